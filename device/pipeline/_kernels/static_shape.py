"""The shape of a rope that did not move (the blur split's static fallback) in one kernel call: its centreline, one
side of its closed contour from rope end to rope end moved half a width into the rope, its tip carried to the band's
end, started at the fixed end, resampled and smoothed."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float32, int32

from ropecam.device.pipeline._kernels._common import NOT_FOUND
from ropecam.device.pipeline._kernels.geometry import turning_angles
from ropecam.device.pipeline._kernels.groups import SPLIT_WIDTH, SPLIT_WORK
from ropecam.device.pipeline._kernels.offsets import find_caps, offset_by_gradient
from ropecam.device.pipeline._kernels.polylines import anchor_start, extend_to_band_end, resample_polyline
from ropecam.device.pipeline._kernels.smoothing import smooth_polyline
from ropecam.shared.jit import f4_2d_ro, i4_2d_ro, kernel

MIN_POINTS: Final = 8
"""Contours with fewer points have no centreline."""
ONE_PASS: Final = 0.7
"""The largest fraction of the contour the walk from the first end to the second takes forward (a side of a
closed outline: about half); more, and the walk goes backward (see `static_shape`)."""


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, f4_2d_ro, f4_2d_ro, f4_2d_ro, float32, SPLIT_WIDTH, boolean, float32, float32,
          SPLIT_WORK)
)  # fmt: skip
def static_shape(points, chain, n, gx, gy, smooth, polarity, width, fixed, fixed_r, fixed_c, buffers):
    """The centreline of the closed contour of `n` subpixel `points` (chain pixels `chain`) of a rope that did not
    move, as the kernels one by one make it:

    1. `turning_angles` at the scale of the rope width (at least 3 points) into ``turn``, and `find_caps` (the two
       rope ends at least ``max(4, n // 8)`` points and two widths + 2 px apart) into ``idx``; with a fixed end
       (`fixed`: at `fixed_r`, `fixed_c`), the end nearer it first;
    2. `offset_by_gradient` from the first end to the second (forward, or backward when forward takes more than
       `ONE_PASS` of the contour), half the width ``width.width_px`` into the rope along
       `polarity` times the gradient (`gx`, `gy`), into side A;
    3. `extend_to_band_end` (the tip carried to where the band ends on `smooth`, with the width's ``cap_px``,
       ``skip_px``, ``span_px``, ``blur_px``), then with a fixed end `anchor_start` at it (axis from ``skip_px``
       over ``span_px``; through the fixed end itself when ``width.through_fixed`` is 1: a given fixed end);
    4. `resample_polyline` at ``width.out_step_px`` into out A, then, with ``width.smoothing_px`` > 0 and 3 points
       or more, `smooth_polyline` back into side A (``scratch[0]`` its arc lengths).

    `width` is the rope width's `SplitWidth`, `buffers` the split's `SplitWork` (side A and out A are ``sides[0]``
    and ``sides[2]``). Writes both ``seg`` rows as the second end's point, ``info[0]`` the point count and
    ``info[4]`` 1 when the shape is in side A (smoothed), 0 when in out A. Returns the point count, NOT_FOUND when
    there is no centreline (fewer than `MIN_POINTS` points, no two ends, fewer than 2 offset points), or
    `resample_polyline`'s status when it failed (< 0).
    """
    if n < MIN_POINTS:
        return NOT_FOUND
    turn = buffers.turn
    idx = buffers.idx
    side_a = buffers.sides[0]
    out_a = buffers.sides[2]
    width64 = width.width64_px
    turning_angles(points, n, np.int32(max(3, int(np.rint(width64)))), turn)
    if find_caps(turn, points, n, np.int32(max(4, n // 8)), np.float32(2.0 * width64 + 2.0), idx) < 0:
        return NOT_FOUND
    e1 = idx[0]
    e2 = idx[1]
    if fixed:
        d1 = math.hypot(points[e1, 0] - fixed_r, points[e1, 1] - fixed_c)
        d2 = math.hypot(points[e2, 0] - fixed_r, points[e2, 1] - fixed_c)
        if d2 < d1:
            e1, e2 = e2, e1
    # One pass from end to end: on a trace that walks its band twice (out and back) the forward way from the
    # first end can pass the second end's other copy and the first end again; then the backward way is one pass.
    direction = np.int32(1)
    if (e2 - e1 + n) % n > ONE_PASS * n:
        direction = np.int32(-1)
    count = offset_by_gradient(
        points, chain, n, e1, e2, direction, gx, gy, polarity, width.width_px, np.float32(0.0), side_a
    )
    if count < 2:
        return NOT_FOUND
    # The cap's edge was moved half a width back along the axis with the gradient: carry the axis on to the band's
    # end instead, as for the split shapes.
    count = extend_to_band_end(
        side_a, count, points, n, smooth, width.width_px, width.cap_px, width.skip_px, width.span_px, width.blur_px,
        np.float32(0.0), np.float32(0.0),
    )  # fmt: skip
    if fixed:
        count = anchor_start(
            side_a, count, fixed_r, fixed_c, width.skip_px, width.span_px, np.int32(1 if width.through_fixed else 0)
        )
    buffers.seg[0, 0] = points[e2, 0]
    buffers.seg[0, 1] = points[e2, 1]
    buffers.seg[1, 0] = points[e2, 0]
    buffers.seg[1, 1] = points[e2, 1]
    count = resample_polyline(side_a, count, width.out_step_px, out_a)
    if count < 0:
        return count
    buffers.info[0] = count
    buffers.info[4] = 0.0
    if width.smoothing_px > 0.0 and count >= 3:
        smooth_polyline(out_a, count, width.smoothing_px, buffers.scratch[0], side_a)
        buffers.info[4] = 1.0
    return count
