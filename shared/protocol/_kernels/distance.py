"""Distances from points to a polyline near their own parameter (the encoder's bound on its error)."""

from __future__ import annotations

import math

from numba import float64, int64, types

from ropecam.shared.jit import f8_1d, f8_1d_ro, f8_2d_ro, kernel
from ropecam.shared.protocol._kernels._common import _INVALID


@kernel(types.UniTuple(int64, 2)(float64, int64, int64))
def _window(t, m, half_window):
    """First and last segment index compared with a point at relative position `t` on a curve of m points."""
    centre = int(min(1.0, max(0.0, t)) * (m - 1) + 0.5)
    return max(0, centre - half_window), min(m - 2, centre + half_window)


@kernel(float64(f8_2d_ro, f8_1d_ro, f8_2d_ro, int64, int64))
def _distance_in_window(points, t, curve, half_window, i):
    """Distance from point `i` to the segments of `curve` within `half_window` of its relative position."""
    m = curve.shape[0]
    lo, hi = _window(t[i], m, half_window)
    px = points[i, 0]
    py = points[i, 1]
    best = math.inf
    for j in range(lo, hi + 1):
        ax = curve[j, 0]
        ay = curve[j, 1]
        dx = curve[j + 1, 0] - ax
        dy = curve[j + 1, 1] - ay
        qx = px - ax
        qy = py - ay
        length2 = dx * dx + dy * dy
        s = 0.0
        if length2 > 0.0:
            s = min(1.0, max(0.0, (qx * dx + qy * dy) / length2))
        gx = qx - s * dx
        gy = qy - s * dy
        best = min(best, gx * gx + gy * gy)
    return math.sqrt(best)


@kernel(int64(f8_2d_ro, f8_1d_ro, f8_2d_ro, int64, f8_1d))
def distances_to_polyline(points, t, curve, half_window, out_distance_px):
    """Write into `out_distance_px` the distance from each of `points` (n, 2) to the polyline `curve` (m, 2).

    Point i is compared with the segments whose start index lies within `half_window` of ``t[i] * (m - 1)``
    (`t` in [0, 1] is the point's relative position along the rope), so the cost is n * (2 * half_window + 1).
    Returns n, or KernelStatus.INVALID when m < 2, the lengths disagree or `half_window` < 0.
    """
    n = points.shape[0]
    m = curve.shape[0]
    if m < 2 or t.shape[0] != n or out_distance_px.shape[0] < n or half_window < 0:
        return _INVALID
    for i in range(n):
        out_distance_px[i] = _distance_in_window(points, t, curve, half_window, i)
    return n
