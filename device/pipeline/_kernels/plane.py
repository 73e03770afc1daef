"""Arc length on the motion plane: material points placed by metres on the plane rather than by pixels.

Lens distortion and a camera not square to the plane make a pixel of the image a different length of rope in
different places; with a plane calibration, eqs. 9-12's uniform stretch is applied to the arc length on the plane.

The calibration travels as one float64 array of `PLANE_PARAMS` values, read by the names of `PLANE_NAMES`
(``params[PLANE.fx]``): fx, skew, cx, fy, cy, the eight OpenCV distortion coefficients k1 k2 p1 p2 k3 k4 k5 k6
(zeros beyond those given), the plane rotation R row-major (r00 ... r22; X_camera = R X_plane + t), and the
camera centre in the plane frame, -R^T t (ox, oy, oz).
"""

from __future__ import annotations

import math
from typing import Final, NamedTuple

import numpy as np
from numba import float64, int32, types

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.device.pipeline._kernels.tracking import _points_at
from ropecam.shared.jit import f4_2d, f8_1d, f8_1d_ro, kernel

f4_3d: Final = types.Array(types.float32, 3, "C")

PLANE_NAMES: Final = (
    "fx", "skew", "cx", "fy", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "r00", "r01", "r02", "r10",
    "r11", "r12", "r20", "r21", "r22", "ox", "oy", "oz",
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


@kernel(float64(f4_2d, f8_1d_ro, f8_1d))
def plane_segment_lengths(poly, params, out_seg):
    """Write the plane length (m) of each segment of `poly` ((n, 2) (row, col) px) into `out_seg[:n - 1]`; return
    the total (NaN when a point misses the plane).

    Neighbouring points are a few pixels apart: each point's undistortion starts from its neighbour's, moved by the
    difference of their distorted coordinates, and needs `WARM_ITERATIONS` steps instead of a cold start's
    `UNDISTORT_ITERATIONS` (the first point gets those)."""
    n = poly.shape[0]
    total = 0.0
    row = np.float64(poly[0, 0])
    col = np.float64(poly[0, 1])
    yd = (row - params[PLANE.cy]) / params[PLANE.fy]
    xd = (col - params[PLANE.cx] - params[PLANE.skew] * yd) / params[PLANE.fx]
    px, py, ux, uy = _to_plane(row, col, params, xd, yd, UNDISTORT_ITERATIONS)
    for j in range(1, n):
        row = np.float64(poly[j, 0])
        col = np.float64(poly[j, 1])
        yd_j = (row - params[PLANE.cy]) / params[PLANE.fy]
        xd_j = (col - params[PLANE.cx] - params[PLANE.skew] * yd_j) / params[PLANE.fx]
        x, y, ux, uy = _to_plane(row, col, params, ux + xd_j - xd, uy + yd_j - yd, WARM_ITERATIONS)
        xd = xd_j
        yd = yd_j
        seg = math.hypot(x - px, y - py)
        out_seg[j - 1] = seg
        total += seg
        px = x
        py = y
    return total


@kernel(int32(f4_2d, f4_2d, types.boolean, f8_1d_ro, f8_1d_ro, f4_3d, f8_1d))
def place_on_plane(begin, end, single, fraction, params, out_points, work_seg):
    """Place the material points of both shapes (fixed end first) at `fraction` of each shape's arc length on the
    plane (uniform stretch on the plane, eqs. 9-12 in metres).

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
