"""Material points of a frame: both shapes' lengths and the points at fixed unstretched arc lengths on each
(uniform stretch, eqs. 9-12 of the paper), in one call per frame."""

from __future__ import annotations

import math
from typing import Final

from numba import float64, int32, types

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


@kernel(int32(f4_2d, float64, f8_1d_ro, float64, f4_2d))
def _points_at(poly, total, fraction, length0_px, out_points):
    """Write the points of `poly` (length `total`) at arc lengths ``fraction * length0_px * total / length0_px``
    into `out_points`: the arc lengths in increasing order in one walk (each search resumes where the last one
    stopped), others each from the start; beyond the end, the last point."""
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
            seg = math.hypot(float(poly[j + 1, 0]) - float(poly[j, 0]), float(poly[j + 1, 1]) - float(poly[j, 1]))
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


@kernel(int32(f4_2d, f4_2d, int32, f8_1d_ro, float64, f4_3d, f8_1d))
def track_shapes(begin, end, single, fraction, length0_px, out_points, out_info):
    """Locate the material points on both shapes of a frame (fixed end first) and their stretch.

    `fraction` holds the points' unstretched arc lengths as fractions of the rope; `length0_px` is the
    unstretched length Lc0 in pixels (<= 0 or not finite: unknown, each shape is taken unstretched). `single`
    says `begin` and `end` are one shape (its length is measured once). A shape of length Lc has its point k at
    arc length ``fraction[k] * Lc0 * Lc / Lc0``.

    Writes `out_points[0]` (begin) and `out_points[1]` (end), (k, 2) (row, col) each, and `out_info` = (Lc begin,
    Lc end, stretch Lc/Lc0 begin, stretch end). Returns k, or INVALID (an empty shape, buffers too small).
    """
    m = fraction.shape[0]
    if begin.shape[0] < 1 or end.shape[0] < 1 or out_points.shape[0] < 2 or out_points.shape[1] < m:
        return INVALID
    if out_info.shape[0] < 4:
        return INVALID
    length_begin = shape_length(begin)
    length_end = length_begin if single else shape_length(end)
    for slot in range(2):
        poly = begin if slot == 0 else end
        lc = length_begin if slot == 0 else length_end
        length0 = length0_px if length0_px > 0.0 else lc
        out_info[slot] = lc
        if length0 > 0.0:
            _points_at(poly, lc, fraction, length0, out_points[slot])
            out_info[2 + slot] = lc / length0
        else:  # a shape of zero length without a reference: its points all at its start
            for k in range(m):
                out_points[slot, k, 0] = poly[0, 0]
                out_points[slot, k, 1] = poly[0, 1]
            out_info[2 + slot] = math.nan
    return m
