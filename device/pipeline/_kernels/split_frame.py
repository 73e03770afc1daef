"""The blur split of a frame in one kernel call, once the rope's width, polarity and contrast are known:
segmentation points, the smoothed image around the band's corners, the tip sweep, the two shapes."""

from __future__ import annotations

import math
from typing import Any, Final, NamedTuple

import numpy as np
from numba import float32, float64, int32

from ropecam.device.pipeline._kernels._common import INVALID, f4_1d_ro
from ropecam.device.pipeline._kernels.canny_gradient import smooth_box
from ropecam.device.pipeline._kernels.geometry import find_segmentation_points_seg
from ropecam.device.pipeline._kernels.groups import PLANES, SPLIT_WIDTH, SPLIT_WORK
from ropecam.device.pipeline._kernels.offsets import slope_sweep_median
from ropecam.device.pipeline._kernels.split_shapes import split_shapes
from ropecam.shared.jit import f4_2d, f4_2d_ro, f8_1d, f8_1d_ro, i4_1d, i4_1d_ro, i4_2d_ro, kernel, u1_2d_ro

FRAME_STATES: Final = ("fixed_r", "fixed_c", "polarity", "contrast", "last_sweep_px", "n", "decision_contrast")
"""`split_frame`'s `state` (float64), in order: the fixed end and the polarity (float32 values, exactly), the
contrast as measured, the last frame's sweep (px), the contour's point count (a Python int in a float64 array
costs less than an int32 scalar made per frame), the contrast the split/static decision reads the sweep from the
edge slope with (`BandMeasure.decision_contrast`: the contrast times the still rope's slope over the model's)."""
FRAME_STATE: Final = NamedTuple("SplitFrameState", [(name, int) for name in FRAME_STATES])(*range(len(FRAME_STATES)))
"""The index of each value of `split_frame`'s `state` (``FRAME_STATE.contrast``), from `FRAME_STATES`."""
FRAME_INFO: Final = 7
"""Length of `SplitWork.info`: `split_shapes`'s six values, then the sweep (px) of this frame (-1 when no
segmentation points were found)."""
SPLIT_STATIC: Final = 0
"""`split_frame`'s return when the contour is to be taken as one static shape (no segmentation points, or a sweep
below ``static_ratio`` widths)."""
_SLOPE_LOW: Final = np.float32(0.5)
_SLOPE_HIGH: Final = np.float32(0.85)
"""The arc fractions of each side whose edge slope gives the sweep (`BlurSplitter._sweep_from_gradient`)."""
BODY_WINDOWS: Final = np.array([0.1, 0.3, 0.5], dtype=np.float32)
BODY_WINDOWS.setflags(write=False)
"""The arc fractions bounding the stretches of each side whose edge slope gives the body's own sweep (`body_sweep`):
a wave running down a whipping rope sweeps part of the body while the tip turns (the simulated late swing: a
stretch at 20-60 % of the rope swept 3-4 px with the tip 1-2 px), and the band is wide there with its end one rope
wide."""


@kernel(float64(i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, float32, f4_1d_ro, f8_1d_ro, f8_1d_ro, f8_1d))
def body_sweep(chain, n, i_fix, seg_a, seg_b, mag, contrast, windows, ratios, sweeps, work):
    """Return the body's own sweep (px): the largest, over both sides and the stretches between consecutive arc
    fractions of `windows`, of the median local sweep read from the edge slope (`slope_sweep_median` with
    ``to_tip`` 0, not extrapolated to the tip; side a from `i_fix` to `seg_a` forwards, side b to `seg_b`
    backwards; `work` its scratch); nan when no stretch has the samples."""
    best = np.nan
    for side in range(2):
        for w in range(windows.shape[0] - 1):
            median = slope_sweep_median(
                chain, n, i_fix, seg_a if side == 0 else seg_b, np.int32(1 if side == 0 else -1), mag, windows[w],
                windows[w + 1], contrast, ratios, sweeps, np.int32(0), work,
            )  # fmt: skip
            if math.isfinite(median) and not median <= best:
                best = median
    return best


def _signature(frame_type: Any) -> Any:
    """`split_frame`'s signature with the frame of `frame_type`."""
    return int32(
        f4_2d_ro, i4_2d_ro, PLANES, frame_type, f4_1d_ro, i4_1d_ro, i4_1d_ro, i4_1d, i4_1d, f4_2d, SPLIT_WIDTH,
        i4_1d_ro, f8_1d_ro, SPLIT_WORK,
    )  # fmt: skip


# Compiled for a read-only frame only: a writable frame (one a reader made) is taken through Numba's safe
# mutable-to-read-only conversion, at the dispatch cost of an exact match and with no view made per frame; a
# second, writable signature would cost its compilation again on every fresh install.
@kernel(_signature(u1_2d_ro))
def split_frame(
    points, chain, planes, frame, weights, spans_lo, spans_hi, box_lo, box_hi, tmp, width, sweep_index, state,
    buffers,
):  # fmt: skip
    """The blur split of one closed contour (``n = state[FRAME_STATE.n]`` subpixel `points`, chain pixels `chain`),
    as the stage's sequence (`BlurSplitter.split`) makes it once the rope's width, polarity and contrast are known:

    1. `find_segmentation_points` (fixed end ``fixed_r``, ``fixed_c`` of `state`, search zone ``max(search_px,
       1.2 last_sweep_px)``; distances into ``scratch[1]``, angles into ``turn``, indices into ``idx``; as
       `find_segmentation_points_seg` with the segment lengths in ``scratch[2]``);
    2. the smoothed image made this frame's (`smooth_box` on `frame` with the edge stage's `weights` and spans
       `spans_lo`/`spans_hi`, scratch `box_lo`, `box_hi`, `tmp`; writes ``planes.smooth``) over the box around
       the two corners grown by ``grow_px``, which the tip fit reads;
    3. the sweep: the corners' distance, or below 1.5 widths the mean of the two sides' `slope_sweep_median`
       (the ``contrast`` of `state`; scratch ``scratch[2]``) when finite, capped at 1.5 widths;
    4. below ``static_ratio`` widths SPLIT_STATIC unless the body's own sweep (`body_sweep`) reaches them, else
       `split_shapes` with `frame` (the rope's contrast along the band), ``1 / contrast``, `sweep_index` and the
       distances of step 1 (the tip fit's search).

    `planes` are the edge stage's (`Planes`), `width` the rope width's tables and scalars (`SplitWidth`),
    `sweep_index` the ratios' index (`split_shapes`'; or empty), `state` the `FRAME_STATES` (float64),
    `buffers` the split's (`SplitWork`: the names in ``double backquotes`` above are its members). Writes the
    corners to ``seg`` (2, 2) and ``info`` (`FRAME_INFO`): `split_shapes`' values and the sweep. Returns
    `split_shapes`' value (2, NOT_FOUND when the lengths differ, FULL, INVALID), SPLIT_STATIC, or INVALID when an
    array is too small or n out of their range.
    """
    scratch = buffers.scratch
    lines = buffers.lines
    out_seg = buffers.seg
    out_info = buffers.info
    if (
        state.shape[0] < len(FRAME_STATES)
        or out_info.shape[0] < FRAME_INFO
        or scratch.shape[0] < 3
        or lines.shape[0] < 1
        or out_seg.shape[0] < 2
        or out_seg.shape[1] < 2
        or not 0.0 <= state[FRAME_STATE.n] <= min(points.shape[0], chain.shape[0])
    ):
        return INVALID
    idx = buffers.idx
    smooth = planes.smooth
    n = np.int32(state[FRAME_STATE.n])
    width64 = width.width64_px
    fixed_r = np.float32(state[FRAME_STATE.fixed_r])
    fixed_c = np.float32(state[FRAME_STATE.fixed_c])
    search = np.float32(max(width.search_px, 1.2 * state[FRAME_STATE.last_sweep_px]))
    found = find_segmentation_points_seg(
        points, n, width.scale, fixed_r, fixed_c, search, width.min_gap, width.corner_rad, scratch[1], buffers.turn,
        lines[0], scratch[2], idx,
    )  # fmt: skip
    out_info[6] = -1.0
    if found < 0:
        return SPLIT_STATIC
    i_fix = idx[0]
    seg_a = idx[1]
    seg_b = idx[3]
    ar = np.float64(points[seg_a, 0])
    ac = np.float64(points[seg_a, 1])
    br = np.float64(points[seg_b, 0])
    bc = np.float64(points[seg_b, 1])
    # The tip fit reads the smoothed image a few pixels past the band's end next to each corner (see
    # `BlurSplitter.split`): this frame's values must be there.
    grow = width.grow_px
    height = smooth.shape[0]
    cols = smooth.shape[1]
    smooth_box(
        frame, weights, spans_lo, spans_hi, max(0, math.floor(min(ar, br) - grow)),
        min(height - 1, math.ceil(max(ar, br) + grow)), max(0, math.floor(min(ac, bc) - grow)),
        min(cols - 1, math.ceil(max(ac, bc) + grow)), box_lo, box_hi, tmp, smooth,
    )  # fmt: skip
    out_seg[0, 0] = points[seg_a, 0]
    out_seg[0, 1] = points[seg_a, 1]
    out_seg[1, 0] = points[seg_b, 0]
    out_seg[1, 1] = points[seg_b, 1]
    sweep = math.hypot(ar - br, ac - bc)
    contrast = state[FRAME_STATE.contrast]
    decide = np.float32(state[FRAME_STATE.decision_contrast])
    if sweep < 1.5 * width64 and contrast >= 5.0:
        # The corners are a rope width apart whatever the sweep below that: the sweep from the edge slope.
        contrast32 = decide
        total = 0.0
        count = 0
        for side in range(2):
            median = slope_sweep_median(
                chain, n, i_fix, seg_a if side == 0 else seg_b, np.int32(1 if side == 0 else -1), planes.mag,
                _SLOPE_LOW, _SLOPE_HIGH, contrast32, width.ratios, width.sweeps, np.int32(1), scratch[2],
            )  # fmt: skip
            if math.isfinite(median):
                total += median
                count += 1
        if count > 0:
            sweep = min(total if count == 1 else total / 2.0, 1.5 * width64)
    out_info[6] = sweep
    if sweep < width.static_ratio * width64:
        # A whip's tip turns while a wave sweeps the body: the band's end is one rope wide, its body is not.
        if not contrast >= 5.0:
            return SPLIT_STATIC
        body = body_sweep(
            chain, n, i_fix, seg_a, seg_b, planes.mag, decide, BODY_WINDOWS, width.ratios,
            width.sweeps, scratch[2],
        )  # fmt: skip
        if not body >= width.static_ratio * width64:
            return SPLIT_STATIC
    # The tip fit's search takes the distances from the fixed end that step 1 left in ``scratch[1]``.
    return split_shapes(
        points, chain, n, i_fix, seg_a, seg_b, planes, frame, np.float32(1.0 / contrast),
        np.float32(state[FRAME_STATE.polarity]), width, sweep_index, fixed_r, fixed_c, scratch[1], buffers,
    )  # fmt: skip
