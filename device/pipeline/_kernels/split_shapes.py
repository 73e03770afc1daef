"""The blur split's two shapes from its segmentation points in one call (`split_shapes`): a sequence of calls to
the step kernels of `offsets`, `polylines` and `smoothing`; and `split_width`, the width's group from the arrays
`steady_frame`'s table holds."""

from __future__ import annotations

from typing import Final, NamedTuple

import numpy as np
from numba import float32, int32

from ropecam.device.pipeline._kernels._common import FULL, INVALID, NOT_FOUND, vector_length
from ropecam.device.pipeline._kernels.band_contrast import CONTRAST_STRIDE, contrast_gains
from ropecam.device.pipeline._kernels.groups import (
    PLANES,
    SPLIT_WIDTH,
    SPLIT_WIDTH_SCALARS,
    SPLIT_WORK,
    SplitWidth,
)
from ropecam.device.pipeline._kernels.offsets import (
    dense_end_points,
    offset_by_table_thinned,
    side_sweeps,
    side_sweeps_indexed,
)
from ropecam.device.pipeline._kernels.polylines import (
    anchor_start,
    extend_to_band_end_near,
    polyline_length,
    resample_polyline_of_length,
)
from ropecam.device.pipeline._kernels.smoothing import smooth_polyline
from ropecam.shared.jit import f4_1d, f4_2d_ro, f8_1d, f8_1d_ro, f8_2d, i4_1d_ro, i4_2d_ro, kernel, u1_2d_ro

SPLIT_SCALAR: Final = NamedTuple("SplitWidthSlots", [(name, int) for name in SPLIT_WIDTH_SCALARS])(
    *range(len(SPLIT_WIDTH_SCALARS))
)
"""The index of each scalar of `SplitWidth` in `split_width`'s `scalars` (``SPLIT_SCALAR.half``)."""


@kernel(SPLIT_WIDTH(f8_1d, f8_2d, f4_1d))
def split_width(scalars, curves, offsets):
    """Return the `SplitWidth` of the edge model's ``curves = [ratios, sweeps]``, its `offsets` and `scalars`
    (float64, the `SPLIT_WIDTH_SCALARS` in order, each converted back to the type `SplitWidth` has: the values
    `WidthTables` writes are exact). Reads ``scalars[:len(SPLIT_WIDTH_SCALARS)]`` and ``curves[:2]``: the caller
    checks their sizes."""
    s = scalars
    return SplitWidth(
        curves[0], curves[1], offsets, np.int32(s[SPLIT_SCALAR.half]), np.float32(s[SPLIT_SCALAR.step_px]),
        np.float32(s[SPLIT_SCALAR.width_px]), np.float32(s[SPLIT_SCALAR.cap_px]), np.float32(s[SPLIT_SCALAR.skip_px]),
        np.float32(s[SPLIT_SCALAR.span_px]), np.float32(s[SPLIT_SCALAR.blur_px]), s[SPLIT_SCALAR.slant_gain_px],
        s[SPLIT_SCALAR.width64_px], np.float32(s[SPLIT_SCALAR.out_step_px]), np.float32(s[SPLIT_SCALAR.smoothing_px]),
        np.int32(s[SPLIT_SCALAR.scale]), np.int32(s[SPLIT_SCALAR.min_gap]), s[SPLIT_SCALAR.search_px],
        np.float32(s[SPLIT_SCALAR.corner_rad]), s[SPLIT_SCALAR.grow_px], s[SPLIT_SCALAR.static_ratio],
        s[SPLIT_SCALAR.rope_px], s[SPLIT_SCALAR.through_fixed],
    )  # fmt: skip


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, PLANES, u1_2d_ro, float32, float32, SPLIT_WIDTH, i4_1d_ro,
          float32, float32, f8_1d_ro, SPLIT_WORK)
)  # fmt: skip
def split_shapes(
    points, chain, n, i_fix, seg_a, seg_b, planes, frame, inv_contrast, polarity, width, sweep_index, fixed_r,
    fixed_c, fixed_dist, buffers,
):  # fmt: skip
    """The blur split's shapes from its segmentation points, with local sweeps, in one call (the stage's
    sequence of kernels, without a Python step between them): per side (A forward from `i_fix` to `seg_a`, B
    backward to `seg_b`) `side_sweeps` with the frame's contrast (``1 / inv_contrast``), then, when `frame` (the
    frame the planes were made from) is not empty and ``width.rope_px`` > 0, `contrast_gains` (the rope's contrast
    across the band at each point where the sweep is below a few widths, read every `CONTRAST_STRIDE`-th point
    first; into ``scratch[2]``) and, when they spread along the side by `MIN_SPREAD` or more where it sweeps
    little, `side_sweeps` again with them;
    `offset_by_table`, `extend_to_band_end` (the segmentation points' gap bounding a wide sweep's tip);
    then the slant correction of
    the two tips (`BlurSplitter._correct_slant`: float32 updates as NumPy makes them), the two lengths, the
    length check (``|La - Lb| > max(3 width64_px, 0.1 max(La, Lb))`` rejects the split), and per side
    `anchor_start` at the fixed end (`fixed_r`, `fixed_c`; axis from `skip_px` over `span_px`; through the fixed
    end itself when ``width.through_fixed`` is 1),
    `resample_polyline_of_length` into out A / out B, then `smooth_polyline` into side A / side B when
    `smoothing_px` > 0 and the shape has 3 points or more. The planes are `planes`' (`Planes`, read only), the
    width's tables and scalars `width`'s (`SplitWidth`), the buffers `buffers`' (`SplitWork`: ``lines`` = [work,
    sweeps of side A, of side B], ``sides`` = [side A, side B, out A, out B], ``scratch[0]`` the arc lengths,
    ``scratch[2]`` the contrast gains, ``info``). `fixed_dist` holds the distances of the `points` from
    (`fixed_r`, `fixed_c`) (`find_segmentation_points`' `out_dist`) for the tip fit's search
    (`extend_to_band_end_near`: the same results with fewer points checked), or is shorter than `n` (every point
    checked). `sweep_index` is the
    ratios' index for `side_sweeps_indexed` (the same sweeps, found faster), or empty (`side_sweeps`).

    Writes ``info[:6] = [count_a, count_b, length_a, length_b, smoothed_a, smoothed_b]`` (a smoothed shape is in
    ``sides[0 or 1, :count]``, else in ``sides[2 or 3, :count]``). Returns 2, NOT_FOUND when the lengths differ
    (the lengths written), or FULL / INVALID when a step did (the caller redoes the steps one by one for its
    message); INVALID when a buffer of `buffers` is too small to hold them.
    """
    if buffers.lines.shape[0] < 3 or buffers.sides.shape[0] < 4 or buffers.scratch.shape[0] < 3:
        return INVALID
    mag = planes.mag
    gx = planes.gx
    gy = planes.gy
    smooth = planes.smooth
    ratios = width.ratios
    sweeps = width.sweeps
    table = width.offsets
    half = width.half
    step_px = width.step_px
    width_px = width.width_px
    cap_px = width.cap_px
    skip_px = width.skip_px
    span_px = width.span_px
    blur_px = width.blur_px
    slant_gain_px = width.slant_gain_px
    width_check_px = width.width64_px
    out_step_px = width.out_step_px
    smoothing_px = width.smoothing_px
    work = buffers.lines[0]
    out_sweeps_a = buffers.lines[1]
    out_sweeps_b = buffers.lines[2]
    out_side_a = buffers.sides[0]
    out_side_b = buffers.sides[1]
    out_a = buffers.sides[2]
    out_b = buffers.sides[3]
    work_arc = buffers.scratch[0]
    out_info = buffers.info
    if out_info.shape[0] < 6:
        return INVALID
    plus = np.int32(1)
    minus = np.int32(-1)
    gains = buffers.scratch[2]
    none = gains[:0]
    contrast = np.float32(1.0 / inv_contrast)
    # The rope's own contrast is read with a frame and a rope width (none under a strong lens blur: `WidthTables`).
    local = frame.shape[0] > 1 and frame.shape[1] > 1 and width.rope_px > 0.0
    stride = np.int32(CONTRAST_STRIDE)
    for side in range(2):
        seg = seg_a if side == 0 else seg_b
        direction = plus if side == 0 else minus
        out_sweeps = out_sweeps_a if side == 0 else out_sweeps_b
        for rounds in range(2 if local else 1):
            factors = gains if rounds == 1 else none
            if sweep_index.shape[0] >= 2:
                count = side_sweeps_indexed(chain, n, i_fix, seg, direction, mag, inv_contrast, factors, ratios,
                                            sweeps, sweep_index, half, work, out_sweeps)  # fmt: skip
            else:
                count = side_sweeps(chain, n, i_fix, seg, direction, mag, inv_contrast, factors, ratios, sweeps, half,
                                    work, out_sweeps)  # fmt: skip
            if count < 0:
                return FULL
            # The rope's own contrast where the sweep read with the frame's is below a few widths (there the
            # offset depends on it): `side_sweeps` again with the ratio of the two, when it varies along the side
            # more than an even rope's readings do (else 0: the sweeps read with the frame's contrast stand).
            if rounds == 0 and local:
                applied = contrast_gains(
                    points, chain, n, i_fix, seg, direction, frame, gx, gy, polarity, out_sweeps, width_px,
                    float(contrast) * float(np.float32(width.rope_px)), stride, work, gains,
                )  # fmt: skip
                if applied < 0:
                    return FULL
                if applied == 0:
                    break
    keep = dense_end_points(skip_px, span_px)
    na = offset_by_table_thinned(points, chain, n, i_fix, seg_a, plus, gx, gy, polarity, out_sweeps_a, step_px,
                                 table, keep, keep, out_side_a)  # fmt: skip
    nb = offset_by_table_thinned(points, chain, n, i_fix, seg_b, minus, gx, gy, polarity, out_sweeps_b, step_px,
                                 table, keep, keep, out_side_b)  # fmt: skip
    if na < 0 or nb < 0:
        return FULL
    gap_r = points[seg_b, 0] - points[seg_a, 0]
    gap_c = points[seg_b, 1] - points[seg_a, 1]
    na = extend_to_band_end_near(out_side_a, na, points, n, smooth, width_px, cap_px, skip_px, span_px, blur_px,
                                 gap_r, gap_c, fixed_dist, fixed_r, fixed_c)  # fmt: skip
    nb = extend_to_band_end_near(out_side_b, nb, points, n, smooth, width_px, cap_px, skip_px, span_px, blur_px,
                                 gap_r, gap_c, fixed_dist, fixed_r, fixed_c)  # fmt: skip
    if na >= 3 and nb >= 3:
        a1r = float(out_side_a[na - 1, 0])
        a1c = float(out_side_a[na - 1, 1])
        a3r = float(out_side_a[na - 3, 0])
        a3c = float(out_side_a[na - 3, 1])
        b1r = float(out_side_b[nb - 1, 0])
        b1c = float(out_side_b[nb - 1, 1])
        b3r = float(out_side_b[nb - 3, 0])
        b3c = float(out_side_b[nb - 3, 1])
        u_r = a1r - a3r + b1r - b3r
        u_c = a1c - a3c + b1c - b3c
        norm = vector_length(u_r, u_c)
        if norm > 0.0 and slant_gain_px > 0:
            u_r = u_r / norm
            u_c = u_c / norm
            d_r = b1r - a1r
            d_c = b1c - a1c
            along = d_r * u_r + d_c * u_c
            across = abs(d_r * u_c - d_c * u_r)
            if not across - 2.0 * slant_gain_px < 1.0:
                shift = min(max(along / (across - 2.0 * slant_gain_px), -1.5), 1.5) * slant_gain_px
                out_side_a[na - 1, 0] = out_side_a[na - 1, 0] - np.float32(shift * u_r)
                out_side_a[na - 1, 1] = out_side_a[na - 1, 1] - np.float32(shift * u_c)
                out_side_b[nb - 1, 0] = out_side_b[nb - 1, 0] + np.float32(shift * u_r)
                out_side_b[nb - 1, 1] = out_side_b[nb - 1, 1] + np.float32(shift * u_c)
    len_a = polyline_length(out_side_a, na)
    len_b = polyline_length(out_side_b, nb)
    out_info[2] = len_a
    out_info[3] = len_b
    if abs(len_a - len_b) > max(3.0 * width_check_px, 0.1 * max(len_a, len_b)):
        return NOT_FOUND
    through = np.int32(width.through_fixed)
    na = anchor_start(out_side_a, na, fixed_r, fixed_c, skip_px, span_px, through)
    nb = anchor_start(out_side_b, nb, fixed_r, fixed_c, skip_px, span_px, through)
    len_a = polyline_length(out_side_a, na)
    len_b = polyline_length(out_side_b, nb)
    out_info[2] = len_a
    out_info[3] = len_b
    for side in range(2):
        poly = out_side_a if side == 0 else out_side_b
        out = out_a if side == 0 else out_b
        count = resample_polyline_of_length(poly, na if side == 0 else nb, len_a if side == 0 else len_b,
                                            out_step_px, out)  # fmt: skip
        if count < 0:
            return FULL
        out_info[side] = count
        out_info[4 + side] = 0.0
        if smoothing_px > 0.0 and count >= 3:
            if smooth_polyline(out, count, smoothing_px, work_arc, poly) < 0:
                return INVALID
            out_info[4 + side] = 1.0
    return 2
