"""The centreline of the blurred band: the closed contour cut into its two sides at the fixed end and at the middle
of the band's far end."""

from __future__ import annotations

import math

from numba import float32, int32

from ropecam.device.pipeline._kernels._common import FULL, NOT_FOUND
from ropecam.shared.jit import f4_2d, f4_2d_ro, kernel


@kernel(int32(f4_2d_ro, int32, int32, int32, float32, f4_2d, f4_2d))
def band_sides(points, n, i_fix, i_far, zone_px, out_a, out_b):
    """Cut the closed contour of a blurred band into its two sides, both from the fixed end to the middle of the
    band's far end.

    The band's far end is the tip's track, all of it about as far from the fixed end as the far point; the
    farthest point itself lies anywhere along it (the noise decides). Each side is one edge of the rope at one
    instant plus half of the track, so the sides are equally long: the free end is the point halfway round the
    contour from `i_fix` (equal arc lengths both ways, interpolated between vertices), searched among the points
    of the run around `i_far` that are at least ``R_far - zone_px`` from contour point `i_fix` (R_far: the
    distance of `i_far`); when the halfway point lies outside that run, the run's point nearest to it in arc
    length is the end (a contour with a long appendix on one side still ends at the far end).

    Side A runs forward along the contour from `i_fix`, side B backward; both end at the free end, which is
    written as the last point of both. Writes `out_a` (count returned) and `out_b` (``n + 3 - count`` points);
    returns the count of side A, NOT_FOUND (fewer than 4 points, indices out of range or equal, or the run
    reaches the fixed end) or FULL (a side does not fit its buffer).
    """
    if n < 4 or not (0 <= i_fix < n and 0 <= i_far < n) or i_fix == i_far:
        return NOT_FOUND
    fr = points[i_fix, 0]
    fc = points[i_fix, 1]
    threshold = math.hypot(points[i_far, 0] - fr, points[i_far, 1] - fc) - zone_px
    # The run of far points around i_far, as forward step counts from i_fix: [lo, hi].
    lo = (i_far - i_fix + n) % n
    hi = lo
    while hi + 1 < n:
        i = (i_fix + hi + 1) % n
        if math.hypot(points[i, 0] - fr, points[i, 1] - fc) < threshold:
            break
        hi += 1
    while lo - 1 > 0:
        i = (i_fix + lo - 1) % n
        if math.hypot(points[i, 0] - fr, points[i, 1] - fc) < threshold:
            break
        lo -= 1
    if lo <= 1 or hi >= n - 1:
        return NOT_FOUND  # the far run reaches the fixed end: no band
    # Forward arc length from i_fix to each step; the perimeter closes back to i_fix.
    perimeter = 0.0
    arc_lo = 0.0
    arc_hi = 0.0
    ip = i_fix
    for step in range(1, n + 1):
        i = (i_fix + step) % n
        perimeter += math.hypot(points[i, 0] - points[ip, 0], points[i, 1] - points[ip, 1])
        if step == lo:
            arc_lo = perimeter
        if step == hi:
            arc_hi = perimeter
        ip = i
    half = min(max(0.5 * perimeter, arc_lo), arc_hi)
    # Walk the run to the segment holding the arc `half`: end point between steps k and k + 1.
    k = lo
    arc = arc_lo
    end_r = points[(i_fix + lo) % n, 0]
    end_c = points[(i_fix + lo) % n, 1]
    while k < hi:
        i0 = (i_fix + k) % n
        i1 = (i_fix + k + 1) % n
        seg = math.hypot(points[i1, 0] - points[i0, 0], points[i1, 1] - points[i0, 1])
        if arc + seg >= half:
            t = (half - arc) / seg if seg > 0.0 else 0.0
            end_r = points[i0, 0] + t * (points[i1, 0] - points[i0, 0])
            end_c = points[i0, 1] + t * (points[i1, 1] - points[i0, 1])
            break
        arc += seg
        k += 1
        end_r = points[i1, 0]
        end_c = points[i1, 1]
    if k >= hi:
        k = hi - 1 if hi > lo else lo  # the end is the run's last point: side B keeps at least the end itself
    count_a = k + 2
    count_b = n - k + 1
    if count_a > out_a.shape[0] or count_b > out_b.shape[0]:
        return FULL
    for step in range(k + 1):
        i = (i_fix + step) % n
        out_a[step, 0] = points[i, 0]
        out_a[step, 1] = points[i, 1]
    out_a[k + 1, 0] = end_r
    out_a[k + 1, 1] = end_c
    for step in range(count_b - 1):
        i = (i_fix - step + n) % n
        out_b[step, 0] = points[i, 0]
        out_b[step, 1] = points[i, 1]
    out_b[count_b - 1, 0] = end_r
    out_b[count_b - 1, 1] = end_c
    return count_a
