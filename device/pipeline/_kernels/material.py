"""Material points of a frame: both shapes' lengths and the points at fixed unstretched arc lengths on each
(uniform stretch, eqs. 9-12 of the paper), in one call per frame."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float64, int32, types

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.shared.jit import f4_2d, f8_1d, f8_1d_ro, kernel

f4_3d: Final = types.Array(types.float32, 3, "C")


@kernel(float64(f4_2d))
def shape_length(poly):
    """Return the length of the polyline `poly` (all its points), eq. (9)."""
    total = 0.0
    for i in range(1, poly.shape[0]):
        total += math.hypot(float(poly[i, 0]) - float(poly[i - 1, 0]), float(poly[i, 1]) - float(poly[i - 1, 1]))
    return total


@kernel(float64(f4_2d, f8_1d))
def _segment_lengths(poly, out_seg):
    """Write the length of each segment of `poly` into `out_seg` and return their sum (as `shape_length`)."""
    total = 0.0
    for i in range(1, poly.shape[0]):
        # The float32 hypot of `shape_length` (libm's hypotf: the double square root of the exact sum of
        # squares, rounded to float32), without its call: 3x faster, the same bits.
        d_r = np.float64(poly[i, 0] - poly[i - 1, 0])
        d_c = np.float64(poly[i, 1] - poly[i - 1, 1])
        seg = np.float64(np.float32(math.sqrt(d_r * d_r + d_c * d_c)))
        out_seg[i - 1] = seg
        total += seg
    return total


@kernel(int32(f4_2d, f8_1d, float64, f8_1d_ro, float64, f4_2d))
def _points_at(poly, seg_px, total, fraction, length0_px, out_points):
    """Write the points of `poly` (segment lengths `seg_px`, length `total`) at arc lengths
    ``fraction * length0_px * total / length0_px`` into `out_points`: arc lengths in increasing order in one walk
    (each search resumes where the last one stopped), others each from the start; beyond the end, the last
    point."""
    n = poly.shape[0]
    m = fraction.shape[0]
    ratio = total / length0_px
    increasing = True
    for k in range(1, m):
        if fraction[k] * length0_px < fraction[k - 1] * length0_px:
            increasing = False
    j0 = 0
    acc0 = 0.0
    for k in range(m):
        target = fraction[k] * length0_px * ratio
        if n == 1 or target <= 0.0:
            out_points[k, 0] = poly[0, 0]
            out_points[k, 1] = poly[0, 1]
            continue
        acc = acc0 if increasing else 0.0
        done = False
        for j in range(j0 if increasing else 0, n - 1):
            seg = seg_px[j]
            if acc + seg > target and seg > 0.0:
                t = (target - acc) / seg
                out_points[k, 0] = poly[j, 0] + t * (poly[j + 1, 0] - poly[j, 0])
                out_points[k, 1] = poly[j, 1] + t * (poly[j + 1, 1] - poly[j, 1])
                done = True
                j0 = j
                acc0 = acc
                break
            acc += seg
        if not done:
            out_points[k, 0] = poly[n - 1, 0]
            out_points[k, 1] = poly[n - 1, 1]
    return m


@kernel(types.Tuple((int32, float64, float64))(f4_2d, f4_2d, boolean, f8_1d_ro, float64, f4_3d, f8_1d, f8_1d))
def track_shapes(begin, end, single, fraction, length0_px, out_points, out_lengths, work_seg):
    """Locate the material points on both shapes of a frame (fixed end first) and their stretch.

    `fraction` holds the points' unstretched arc lengths as fractions of the rope; `length0_px` is the
    unstretched length Lc0 in pixels (<= 0 or not finite: unknown, each shape is taken unstretched). `single`
    says `begin` and `end` are one shape (measured once). A shape of length Lc has its point k at arc length
    ``fraction[k] * Lc0 * Lc / Lc0`` (eqs. 9-12). `work_seg` (at least as long as a shape) holds the segment
    lengths.

    Writes `out_points[0]` (begin) and `out_points[1]` (end), (k, 2) (row, col) each, and `out_lengths` = (Lc
    begin, Lc end). Returns (k or INVALID (an empty shape, buffers too small), stretch Lc/Lc0 of begin, of end).
    """
    m = fraction.shape[0]
    nb = begin.shape[0]
    ne = end.shape[0]
    if nb < 1 or ne < 1 or out_points.shape[0] < 2 or out_points.shape[1] < m or out_lengths.shape[0] < 2:
        return INVALID, math.nan, math.nan
    if work_seg.shape[0] < max(nb, ne):
        return INVALID, math.nan, math.nan
    stretch_begin = math.nan
    stretch_end = math.nan
    for slot in range(2):
        poly = begin if slot == 0 else end
        if slot == 0 or not single:
            lc = _segment_lengths(poly, work_seg)
        length0 = length0_px if length0_px > 0.0 else lc
        out_lengths[slot] = lc
        if length0 > 0.0:
            _points_at(poly, work_seg, lc, fraction, length0, out_points[slot])
            stretch = lc / length0
        else:  # a shape of zero length without a reference: its points all at its start
            for k in range(m):
                out_points[slot, k, 0] = poly[0, 0]
                out_points[slot, k, 1] = poly[0, 1]
            stretch = math.nan
        if slot == 0:
            stretch_begin = stretch
        else:
            stretch_end = stretch
    return m, stretch_begin, stretch_end
