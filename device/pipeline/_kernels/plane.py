"""Arc length on the motion plane: material points placed by metres on the plane rather than by pixels.

Lens distortion and a camera not square to the plane make a pixel of the image a different length of rope in
different places; with a plane calibration, eqs. 9-12's uniform stretch is applied to the arc length on the plane.

The calibration travels as one float64 array of `PLANE_PARAMS` values, read by the names of `PLANE_NAMES`
(``params[PLANE.fx]``): fx, skew, cx, fy, cy, the eight OpenCV distortion coefficients k1 k2 p1 p2 k3 k4 k5 k6
(zeros beyond those given), the plane rotation R row-major (r00 ... r22; X_camera = R X_plane + t), and the
camera centre in the plane frame, -R^T t (ox, oy, oz), and the rolling shutter's line time in exposures (``rolling``:
the readout time / (image rows x exposure time); 0 for a global shutter or an unknown exposure).

With a rolling shutter each point of a shape was seen when its own row was exposed (row r ``r / H`` of the
readout after row 0), so a shape is the rope at different instants along its length, and its arc length is not the
rope's: on the simulated `lab-rolling` (7 ms readout, 4 ms exposure) the visible length differs from the rope's by
up to 0.6 %, which placed the material points up to 1.4 mm off along the rope with exact shapes. `place_on_plane`
therefore measures arc length on the rope at one instant (`_deskewed_fractions`): each point is moved back along
its velocity, read from the other shape at the same material fraction, to the instant its shape's middle row was
seen, and the fractions are read again on those moved points (`ROLLING_ITERATIONS` times). The material points are
still placed on the shapes as seen (each at its own row's time, as the result's ``readout_ns`` says).
"""

from __future__ import annotations

import math
from typing import Final, NamedTuple

import numpy as np
from numba import float64, int32, int64, types

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.device.pipeline._kernels.tracking import _points_at
from ropecam.shared.jit import f4_2d, f8_1d, f8_1d_ro, kernel

f4_3d: Final = types.Array(types.float32, 3, "C")

PLANE_NAMES: Final = (
    "fx", "skew", "cx", "fy", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "r00", "r01", "r02", "r10",
    "r11", "r12", "r20", "r21", "r22", "ox", "oy", "oz", "rolling",
)  # fmt: skip
"""The values of the calibration array, in order (see the module's docstring)."""
PLANE: Final = NamedTuple("PlaneSlots", [(name, int) for name in PLANE_NAMES])(*range(len(PLANE_NAMES)))
"""The index of each value of the calibration array (``PLANE.fx``), from `PLANE_NAMES`."""
PLANE_PARAMS: Final = len(PLANE_NAMES)
"""Length of the calibration array."""
UNDISTORT_ITERATIONS: Final = 20
"""Fixed-point iterations of the undistortion from a cold start (OpenCV's method; converged well below 1e-6 px for
lab lenses)."""
WARM_ITERATIONS: Final = 4
"""Iterations from the neighbouring point's solution (a few pixels away: its error shrinks by the distortion's
factor, < 0.2 at the image corners of a lab lens, per step)."""
ROLLING_ITERATIONS: Final = 2
"""Rounds of the rolling shutter's material fractions (each reads the velocity at the other shape's last
fractions; on the simulated `lab-rolling`'s exact shapes: 0.17 mm mean error without, 0.03 mm after two)."""
ROLLING_WORK: Final = 4
"""Work values per point of both shapes the rolling shutter's placement needs (plane x and y, fraction, next
fraction)."""
MAX_BACK_EXPOSURES: Final = 1.0
"""Longest time (exposures) a point is moved back along its velocity (the velocity is the step between the two
shapes over about one exposure: beyond that the shapes' noise is extrapolated, not the motion)."""
MIN_TIME_EXPOSURES: Final = 0.25
"""Smallest time between a point of one shape and the same material of the other, in exposures (a guard: it is
1 + the rows between them x `rolling`, about 1 +- 0.1 on lab footage)."""


@kernel(types.UniTuple(float64, 4)(float64, float64, f8_1d_ro, float64, float64, int32))
def _to_plane(row, col, params, x0, y0, iterations):
    """Map pixel (`row`, `col`) to the plane: `iterations` fixed-point steps of the undistortion from the
    normalised guess (`x0`, `y0`). Returns (x m, y m (NaN when the ray misses the plane in front of the camera),
    the undistorted normalised x, y)."""
    fx = params[PLANE.fx]
    skew = params[PLANE.skew]
    cx = params[PLANE.cx]
    fy = params[PLANE.fy]
    cy = params[PLANE.cy]
    k1 = params[PLANE.k1]
    k2 = params[PLANE.k2]
    p1 = params[PLANE.p1]
    p2 = params[PLANE.p2]
    k3 = params[PLANE.k3]
    k4 = params[PLANE.k4]
    k5 = params[PLANE.k5]
    k6 = params[PLANE.k6]
    yd = (row - cy) / fy
    xd = (col - cx - skew * yd) / fx
    x = x0
    y = y0
    for _ in range(iterations):
        r2 = x * x + y * y
        icdist = (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))) / (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        x = (xd - dx) * icdist
        y = (yd - dy) * icdist
    # The ray (x, y, 1) in the plane frame: R^T ray (R row-major at r00 ... r22).
    rx = params[PLANE.r00] * x + params[PLANE.r10] * y + params[PLANE.r20]
    ry = params[PLANE.r01] * x + params[PLANE.r11] * y + params[PLANE.r21]
    rz = params[PLANE.r02] * x + params[PLANE.r12] * y + params[PLANE.r22]
    if abs(rz) < 1e-12:
        return math.nan, math.nan, x, y
    scale = -params[PLANE.oz] / rz
    if not scale > 0.0:
        return math.nan, math.nan, x, y
    return params[PLANE.ox] + scale * rx, params[PLANE.oy] + scale * ry, x, y


@kernel(types.UniTuple(float64, 2)(float64, float64, f8_1d_ro))
def pixel_to_plane(row, col, params):
    """Return the point (x, y) in metres on the plane seen at pixel (`row`, `col`) (distorted; NaN when its ray
    misses the plane in front of the camera)."""
    yd = (row - params[PLANE.cy]) / params[PLANE.fy]
    xd = (col - params[PLANE.cx] - params[PLANE.skew] * yd) / params[PLANE.fx]
    x, y, _, _ = _to_plane(row, col, params, xd, yd, UNDISTORT_ITERATIONS)
    return x, y


@kernel(types.UniTuple(float64, 6)(f4_2d, int64, f8_1d_ro, float64, float64, float64, float64))
def _point_to_plane(poly, j, params, ux, uy, xd, yd):
    """Map point `j` of `poly` ((n, 2) (row, col) px) to the plane: for j > 0 its undistortion starts from the
    previous point's (`ux`, `uy`, at the normalised distorted `xd`, `yd`) moved by the difference of their
    distorted coordinates (`WARM_ITERATIONS` steps), for j = 0 cold (`UNDISTORT_ITERATIONS`). Returns (x m, y m,
    ux, uy, xd, yd) of point `j`."""
    row = np.float64(poly[j, 0])
    col = np.float64(poly[j, 1])
    yd_j = (row - params[PLANE.cy]) / params[PLANE.fy]
    xd_j = (col - params[PLANE.cx] - params[PLANE.skew] * yd_j) / params[PLANE.fx]
    if j == 0:
        x, y, ux, uy = _to_plane(row, col, params, xd_j, yd_j, UNDISTORT_ITERATIONS)
    else:
        x, y, ux, uy = _to_plane(row, col, params, ux + xd_j - xd, uy + yd_j - yd, WARM_ITERATIONS)
    return x, y, ux, uy, xd_j, yd_j


@kernel(float64(f4_2d, f8_1d_ro, f8_1d))
def plane_segment_lengths(poly, params, out_seg):
    """Write the plane length (m) of each segment of `poly` ((n, 2) (row, col) px) into `out_seg[:n - 1]`; return
    the total (NaN when a point misses the plane).

    Neighbouring points are a few pixels apart: each point's undistortion starts from its neighbour's, moved by the
    difference of their distorted coordinates, and needs `WARM_ITERATIONS` steps instead of a cold start's
    `UNDISTORT_ITERATIONS` (the first point gets those)."""
    n = poly.shape[0]
    total = 0.0
    px, py, ux, uy, xd, yd = _point_to_plane(poly, 0, params, 0.0, 0.0, 0.0, 0.0)
    for j in range(1, n):
        x, y, ux, uy, xd, yd = _point_to_plane(poly, j, params, ux, uy, xd, yd)
        seg = math.hypot(x - px, y - py)
        out_seg[j - 1] = seg
        total += seg
        px = x
        py = y
    return total


@kernel(int32(f4_2d, f8_1d_ro, f8_1d, int64, int64))
def _plane_points(poly, params, work, at_xy, at_fraction):
    """Write the plane points (m) of `poly` ((n, 2) (row, col) px) to ``work[at_xy:]`` (x, y interleaved) and
    their arc lengths as fractions of the total to ``work[at_fraction:]``; return n, or INVALID (a point off the
    plane, a shape of no length). Each undistortion starts from the neighbour's, as `plane_segment_lengths`'."""
    n = poly.shape[0]
    total = 0.0
    ux = uy = xd = yd = 0.0
    for j in range(n):
        x, y, ux, uy, xd, yd = _point_to_plane(poly, j, params, ux, uy, xd, yd)
        if j > 0:
            total += math.hypot(x - work[at_xy + 2 * j - 2], y - work[at_xy + 2 * j - 1])
        if not (math.isfinite(x) and math.isfinite(y)):
            return INVALID
        work[at_xy + 2 * j] = x
        work[at_xy + 2 * j + 1] = y
        work[at_fraction + j] = total
    if not total > 0.0:
        return INVALID
    for j in range(n):
        work[at_fraction + j] /= total
    return n


@kernel(int32(f4_2d, int64, int64, f4_2d, int64, int64, float64, float64, float64, f8_1d, int64))
def _deskewed_fractions(poly, at_xy, at_fraction, other, other_xy, other_fraction, later, rolling, ref_row, work, out):
    """Write to ``work[out:]`` the arc-length fractions of `poly`'s points on the rope as it was when row
    `ref_row` was exposed (`poly`: (n, 2) (row, col) px, its plane points and current fractions in `work` at
    `at_xy`, `at_fraction`; `other` the frame's other shape likewise, seen `later` (+1) or earlier (-1) by one
    exposure). A point of row r was seen ``(r - ref_row) x rolling`` exposures after that instant: it moves back
    by its velocity, the plane step to the other shape's point of the same fraction over the time between them.
    Returns n, or INVALID (a shape of no length)."""
    n = poly.shape[0]
    m = other.shape[0]
    k = 0
    total = 0.0
    last_x = 0.0
    last_y = 0.0
    for j in range(n):
        u = work[at_fraction + j]
        while k < m - 2 and work[other_fraction + k + 1] <= u:
            k += 1
        u0 = work[other_fraction + k]
        u1 = work[other_fraction + k + 1] if m > 1 else u0
        t = (u - u0) / (u1 - u0) if u1 > u0 else 0.0
        t = min(max(t, 0.0), 1.0)
        k1 = k + 1 if m > 1 else k
        ox = work[other_xy + 2 * k] + t * (work[other_xy + 2 * k1] - work[other_xy + 2 * k])
        oy = work[other_xy + 2 * k + 1] + t * (work[other_xy + 2 * k1 + 1] - work[other_xy + 2 * k + 1])
        other_row = np.float64(other[k, 0]) + t * (np.float64(other[k1, 0]) - np.float64(other[k, 0]))
        row = np.float64(poly[j, 0])
        px = work[at_xy + 2 * j]
        py = work[at_xy + 2 * j + 1]
        # Exposures from this point's instant to the other's: one exposure plus the rows between them.
        gap = max(1.0 + later * (other_row - row) * rolling, MIN_TIME_EXPOSURES)
        # Extrapolated at most `MAX_BACK_EXPOSURES` beyond the two sightings: the shapes' noise over one exposure
        # grows with it (the paper camera's 1 ms under a 7 ms readout reaches several exposures).
        ahead = min(max((row - ref_row) * rolling, -MAX_BACK_EXPOSURES), MAX_BACK_EXPOSURES)
        back = ahead * later / gap
        x = px - (ox - px) * back
        y = py - (oy - py) * back
        if j > 0:
            total += math.hypot(x - last_x, y - last_y)
        work[out + j] = total
        last_x = x
        last_y = y
    if not total > 0.0:
        return INVALID
    for j in range(n):
        work[out + j] /= total
    return n


@kernel(int32(f4_2d, f8_1d, int64, f8_1d_ro, f4_2d))
def _points_at_fractions(poly, work, at_fraction, fraction, out_points):
    """Write the points of `poly` at arc-length `fraction` (its points' fractions in ``work[at_fraction:]``,
    non-decreasing, 0 to 1) into `out_points`; beyond the ends, the end points."""
    n = poly.shape[0]
    for k in range(fraction.shape[0]):
        f = fraction[k]
        out_points[k, 0] = poly[n - 1, 0]
        out_points[k, 1] = poly[n - 1, 1]
        if f <= 0.0 or n == 1:
            out_points[k, 0] = poly[0, 0]
            out_points[k, 1] = poly[0, 1]
            continue
        for j in range(n - 1):
            u0 = work[at_fraction + j]
            u1 = work[at_fraction + j + 1]
            if u1 >= f and u1 > u0:
                t = (f - u0) / (u1 - u0)
                out_points[k, 0] = poly[j, 0] + t * (poly[j + 1, 0] - poly[j, 0])
                out_points[k, 1] = poly[j, 1] + t * (poly[j + 1, 1] - poly[j, 1])
                break
    return fraction.shape[0]


@kernel(int32(f4_2d, f4_2d, f8_1d_ro, f8_1d_ro, f4_3d, f8_1d))
def _place_rolling(begin, end, fraction, params, out_points, work):
    """`place_on_plane` of a rolling shutter (``params[PLANE.rolling]`` > 0, two shapes, `work` of at least
    `ROLLING_WORK` x (both shapes' points)): the fractions on the rope at one instant (`_deskewed_fractions`).
    Returns k, or INVALID (a shape off the plane or of no length: nothing written)."""
    nb = begin.shape[0]
    ne = end.shape[0]
    at_b = 0
    at_e = 2 * nb
    frac_b = 2 * (nb + ne)
    frac_e = frac_b + nb
    next_b = frac_e + ne
    next_e = next_b + nb
    if _plane_points(begin, params, work, at_b, frac_b) < 0 or _plane_points(end, params, work, at_e, frac_e) < 0:
        return INVALID
    low = np.float64(begin[0, 0])
    high = low
    for j in range(nb):
        low = min(low, np.float64(begin[j, 0]))
        high = max(high, np.float64(begin[j, 0]))
    for j in range(ne):
        low = min(low, np.float64(end[j, 0]))
        high = max(high, np.float64(end[j, 0]))
    # The instant of the shapes' middle row: the points move back by less than half the readout of their rows.
    ref_row = 0.5 * (low + high)
    rolling = params[PLANE.rolling]
    for _ in range(ROLLING_ITERATIONS):
        if _deskewed_fractions(begin, at_b, frac_b, end, at_e, frac_e, 1.0, rolling, ref_row, work, next_b) < 0:
            return INVALID
        if _deskewed_fractions(end, at_e, frac_e, begin, at_b, frac_b, -1.0, rolling, ref_row, work, next_e) < 0:
            return INVALID
        for j in range(nb + ne):
            work[frac_b + j] = work[next_b + j]
    _points_at_fractions(begin, work, frac_b, fraction, out_points[0])
    _points_at_fractions(end, work, frac_e, fraction, out_points[1])
    return fraction.shape[0]


@kernel(int32(f4_2d, f4_2d, types.boolean, f8_1d_ro, f8_1d_ro, f4_3d, f8_1d))
def place_on_plane(begin, end, single, fraction, params, out_points, work_seg):
    """Place the material points of both shapes (fixed end first) at `fraction` of each shape's arc length on the
    plane (uniform stretch on the plane, eqs. 9-12 in metres).

    With a rolling shutter (``params[PLANE.rolling]`` > 0) and two shapes, the arc length is the rope's at one
    instant (`_place_rolling`; the module's docstring), when `work_seg` holds `ROLLING_WORK` values per point of
    both shapes (otherwise, and when that fails, the shapes' own arc lengths).

    Writes `out_points[0]` (begin) and `out_points[1]` (end), (k, 2) (row, col) each; `work_seg` (at least as
    long as a shape) holds the segment lengths. Returns k, or INVALID (an empty shape, buffers too small, a shape
    off the plane: nothing written to that shape's points).
    """
    m = fraction.shape[0]
    nb = begin.shape[0]
    ne = end.shape[0]
    if nb < 1 or ne < 1 or out_points.shape[0] < 2 or out_points.shape[1] < m or params.shape[0] < PLANE_PARAMS:
        return INVALID
    if work_seg.shape[0] < max(nb, ne):
        return INVALID
    if (
        not single
        and params[PLANE.rolling] > 0.0
        and nb > 1
        and ne > 1
        and work_seg.shape[0] >= ROLLING_WORK * (nb + ne)
        and _place_rolling(begin, end, fraction, params, out_points, work_seg) >= 0
    ):
        return m
    status = m
    for slot in range(2):
        poly = begin if slot == 0 else end
        if slot == 1 and single:
            for k in range(m):
                out_points[1, k, 0] = out_points[0, k, 0]
                out_points[1, k, 1] = out_points[0, k, 1]
            break
        total = plane_segment_lengths(poly, params, work_seg)
        if not total > 0.0 or not math.isfinite(total):
            status = INVALID
            continue
        _points_at(poly, work_seg, total, fraction, total, out_points[slot])
    return status
