"""The blur split's two shapes from its segmentation points in one call (`split_shapes_local`), and the same with
its arguments packed in fewer arrays (`split_shapes_packed`, `split_shapes_packed_near`): a sequence of calls to
the step kernels of `offsets`, `polylines` and `smoothing`."""

from __future__ import annotations

from typing import Final

import numpy as np
from numba import float32, float64, int32, types

from ropecam.device.pipeline._kernels._common import FULL, INVALID, NOT_FOUND, f4_1d_ro, vector_length
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
from ropecam.shared.jit import f4_1d, f4_2d, f4_2d_ro, f8_1d, f8_1d_ro, f8_2d_ro, i4_1d_ro, i4_2d_ro, kernel

f4_3d: Final = types.Array(types.float32, 3, "C")

SPLIT_PARAMS: Final = 11
"""Length of `split_shapes_packed`'s `params`: `split_shapes_local`'s scalars that depend only on the rope width,
in its order (`half`, `step_px`, `width_px`, `cap_px`, `skip_px`, `span_px`, `blur_px`, `slant_gain_px`,
`width_check_px`, `out_step_px`, `smoothing_px`), each exactly representable in float64."""


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, float32, f8_1d_ro, f8_1d_ro, int32, f4_2d_ro,
          f4_2d_ro, float32, float32, f4_1d_ro, f4_2d_ro, float32, float32, float32, float32, float32, float64,
          float64, float32, float32, float32, float32, f4_1d, f4_1d, f4_1d, f4_2d, f4_2d, f4_2d, f4_2d, f8_1d,
          f8_1d, f8_1d_ro, i4_1d_ro)
)  # fmt: skip
def split_shapes_local(
    points, chain, n, i_fix, seg_a, seg_b, mag, inv_contrast, ratios, sweeps, half, gx, gy, polarity, step_px, table,
    smooth, width_px, cap_px, skip_px, span_px, blur_px, slant_gain_px, width_check_px, out_step_px, smoothing_px,
    fixed_r, fixed_c, work, out_sweeps_a, out_sweeps_b, out_side_a, out_side_b, out_a, out_b, work_arc, out_info,
    fixed_dist, sweep_index,
):  # fmt: skip
    """The blur split's shapes from its segmentation points, with local sweeps, in one call (the stage's
    sequence of kernels, without a Python step between them): per side (A forward from `i_fix` to `seg_a`, B
    backward to `seg_b`) `side_sweeps`, `offset_by_table`, `extend_to_band_end`; then the slant correction of
    the two tips (`BlurSplitter._correct_slant`: float32 updates as NumPy makes them), the two lengths, the
    length check (``|La - Lb| > max(3 width_check_px, 0.1 max(La, Lb))`` rejects the split), and per side
    `anchor_start` at the fixed end (`fixed_r`, `fixed_c`; axis from `skip_px` over `span_px`),
    `resample_polyline_of_length` into `out_a`/`out_b`, then `smooth_polyline` into `out_side_a`/`out_side_b`
    when `smoothing_px` > 0 and the shape has 3 points or more. `fixed_dist` holds the distances of the `points`
    from (`fixed_r`, `fixed_c`) (`find_segmentation_points`' `out_dist`) for the tip fit's search
    (`extend_to_band_end_near`: the same results with fewer points checked), or is shorter than `n` (every
    point checked). `sweep_index` is the `ratios`' index for `side_sweeps_indexed` (the same sweeps, found
    faster), or empty (`side_sweeps`).

    Writes ``out_info = [count_a, count_b, length_a, length_b, smoothed_a, smoothed_b]`` (a smoothed shape is in
    ``out_side_*[:count]``, else in ``out_*[:count]``). Returns 2, NOT_FOUND when the lengths differ (the lengths
    written), or FULL / INVALID when a step did (the caller redoes the steps one by one for its message).
    """
    if out_info.shape[0] < 6:
        return INVALID
    plus = np.int32(1)
    minus = np.int32(-1)
    if sweep_index.shape[0] >= 2:
        if (
            side_sweeps_indexed(chain, n, i_fix, seg_a, plus, mag, inv_contrast, ratios, sweeps, sweep_index, half,
                                work, out_sweeps_a) < 0
            or side_sweeps_indexed(chain, n, i_fix, seg_b, minus, mag, inv_contrast, ratios, sweeps, sweep_index,
                                   half, work, out_sweeps_b) < 0
        ):  # fmt: skip
            return FULL
    else:
        if side_sweeps(chain, n, i_fix, seg_a, plus, mag, inv_contrast, ratios, sweeps, half, work, out_sweeps_a) < 0:
            return FULL
        if side_sweeps(chain, n, i_fix, seg_b, minus, mag, inv_contrast, ratios, sweeps, half, work, out_sweeps_b) < 0:
            return FULL
    keep = dense_end_points(skip_px, span_px)
    na = offset_by_table_thinned(points, chain, n, i_fix, seg_a, plus, gx, gy, polarity, out_sweeps_a, step_px,
                                 table, keep, keep, out_side_a)  # fmt: skip
    nb = offset_by_table_thinned(points, chain, n, i_fix, seg_b, minus, gx, gy, polarity, out_sweeps_b, step_px,
                                 table, keep, keep, out_side_b)  # fmt: skip
    if na < 0 or nb < 0:
        return FULL
    na = extend_to_band_end_near(out_side_a, na, points, n, smooth, width_px, cap_px, skip_px, span_px, blur_px,
                                 fixed_dist, fixed_r, fixed_c)  # fmt: skip
    nb = extend_to_band_end_near(out_side_b, nb, points, n, smooth, width_px, cap_px, skip_px, span_px, blur_px,
                                 fixed_dist, fixed_r, fixed_c)  # fmt: skip
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
    na = anchor_start(out_side_a, na, fixed_r, fixed_c, skip_px, span_px)
    nb = anchor_start(out_side_b, nb, fixed_r, fixed_c, skip_px, span_px)
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


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, float32, f4_2d_ro, f4_2d_ro, float32, f4_2d_ro,
          float32, float32, f8_1d_ro, f8_2d_ro, f4_1d_ro, f4_2d, f4_3d, f8_1d, f8_1d, f8_1d_ro, i4_1d_ro)
)  # fmt: skip
def split_shapes_packed_near(
    points, chain, n, i_fix, seg_a, seg_b, mag, inv_contrast, gx, gy, polarity, smooth, fixed_r, fixed_c, params,
    curves, table, lines, sides, work_arc, out_info, fixed_dist, sweep_index,
):  # fmt: skip
    """`split_shapes_packed` with the points' distances from the fixed end (`split_shapes_local`'s `fixed_dist`)
    and the ratios' index (its `sweep_index`): the same results, the tip fit's search over fewer points and the
    sweep table's intervals found without a walk."""
    if params.shape[0] < SPLIT_PARAMS or curves.shape[0] < 2 or lines.shape[0] < 3 or sides.shape[0] < 4:
        return INVALID
    return split_shapes_local(
        points, chain, n, i_fix, seg_a, seg_b, mag, inv_contrast, curves[0], curves[1], np.int32(params[0]), gx, gy,
        polarity, np.float32(params[1]), table, smooth, np.float32(params[2]), np.float32(params[3]),
        np.float32(params[4]), np.float32(params[5]), np.float32(params[6]), params[7], params[8],
        np.float32(params[9]), np.float32(params[10]), fixed_r, fixed_c, lines[0], lines[1], lines[2], sides[0],
        sides[1], sides[2], sides[3], work_arc, out_info, fixed_dist, sweep_index,
    )  # fmt: skip


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, float32, f4_2d_ro, f4_2d_ro, float32, f4_2d_ro,
          float32, float32, f8_1d_ro, f8_2d_ro, f4_1d_ro, f4_2d, f4_3d, f8_1d, f8_1d)
)  # fmt: skip
def split_shapes_packed(
    points, chain, n, i_fix, seg_a, seg_b, mag, inv_contrast, gx, gy, polarity, smooth, fixed_r, fixed_c, params,
    curves, table, lines, sides, work_arc, out_info,
):  # fmt: skip
    """`split_shapes_local` with its arguments bound in fewer arrays (a dispatch costs ~0.1 us per argument): the
    width's scalars in `params` (`SPLIT_PARAMS` values, converted back to the types `split_shapes_local` takes),
    ``curves = [ratios, sweeps]``, ``lines = [work, out_sweeps_a, out_sweeps_b]`` and ``sides = [out_side_a,
    out_side_b, out_a, out_b]``; every contour point is checked by the tip fit (no `fixed_dist`), the sweep table
    walked (no `sweep_index`). Same results
    and returns; INVALID when an array is too small to hold them."""
    return split_shapes_packed_near(
        points, chain, n, i_fix, seg_a, seg_b, mag, inv_contrast, gx, gy, polarity, smooth, fixed_r, fixed_c, params,
        curves, table, lines, sides, work_arc, out_info, work_arc[:0], chain.reshape(chain.size)[:0],
    )  # fmt: skip
