"""Numba kernels of the shape codec (the encoder runs on the device's per-frame path): point-to-polyline
distances, least-squares B-spline fit and B-spline sampling."""

from __future__ import annotations

import math

from numba import float64, int64

from ropecam.shared.jit import KernelStatus, f8_1d, f8_1d_ro, f8_2d, f8_2d_ro, kernel

_INVALID = int(KernelStatus.INVALID)
_SINGULAR = int(KernelStatus.SINGULAR)


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
        centre = int(min(1.0, max(0.0, t[i])) * (m - 1) + 0.5)
        lo = max(0, centre - half_window)
        hi = min(m - 2, centre + half_window)
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
        out_distance_px[i] = math.sqrt(best)
    return n


@kernel(float64(int64, int64, int64))
def _knot(index, control_count, degree):
    """Knot `index` of the clamped uniform knot vector of `control_count` control points."""
    if index <= degree:
        return 0.0
    if index >= control_count:
        return 1.0
    return (index - degree) / (control_count - degree)


@kernel(int64(float64, int64, int64, f8_1d))
def _basis_at(t, control_count, degree, out_values):
    """Write the degree + 1 non-zero basis values at `t` into `out_values`; return the first control index."""
    segments = control_count - degree
    span = degree + min(int(t * segments), segments - 1)
    out_values[0] = 1.0
    left1 = left2 = left3 = 0.0
    right1 = right2 = right3 = 0.0
    for j in range(1, degree + 1):
        left = t - _knot(span + 1 - j, control_count, degree)
        right = _knot(span + j, control_count, degree) - t
        if j == 1:
            left1, right1 = left, right
        elif j == 2:
            left2, right2 = left, right
        else:
            left3, right3 = left, right
        saved = 0.0
        for r in range(j):
            # right[r + 1] and left[j - r], unrolled for degree <= 3
            rr = right1 if r + 1 == 1 else (right2 if r + 1 == 2 else right3)
            jr = j - r
            ll = left1 if jr == 1 else (left2 if jr == 2 else left3)
            temp = out_values[r] / (rr + ll)
            out_values[r] = saved + rr * temp
            saved = ll * temp
        out_values[j] = saved
    return span - degree


@kernel(int64(f8_2d_ro, f8_1d_ro, int64, f8_1d, f8_2d, f8_2d))
def fit_bspline(points, t, control_count, work_basis, work_normal, out_control):
    """Least-squares fit of a clamped uniform B-spline (degree min(3, m - 1)) through `points` at parameters `t`.

    Writes the m = `control_count` control points into ``out_control[:m]`` (rows (u, v)), using `work_basis`
    (>= 4 values) and ``work_normal[:m, :m]`` for the normal equations (solved by Cholesky). Returns m,
    KernelStatus.INVALID for inconsistent sizes (m < 2, buffers too small) or KernelStatus.SINGULAR when the
    points do not determine the control points (too few, or a span without points).
    """
    n = points.shape[0]
    m = control_count
    if (
        m < 2
        or t.shape[0] != n
        or work_basis.shape[0] < 4
        or work_normal.shape[0] < m
        or work_normal.shape[1] < m
        or out_control.shape[0] < m
    ):
        return _INVALID
    degree = min(3, m - 1)
    for a in range(m):
        out_control[a, 0] = 0.0
        out_control[a, 1] = 0.0
        for b in range(m):
            work_normal[a, b] = 0.0
    values = work_basis
    for i in range(n):
        first = _basis_at(min(1.0, max(0.0, t[i])), m, degree, values)
        for a in range(degree + 1):
            va = values[a]
            out_control[first + a, 0] += va * points[i, 0]
            out_control[first + a, 1] += va * points[i, 1]
            for b in range(degree + 1):
                work_normal[first + a, first + b] += va * values[b]
    # Cholesky A = L L^T in the lower triangle, then forward and back substitution for both columns.
    scale = 0.0
    for a in range(m):
        scale = max(scale, work_normal[a, a])
    for j in range(m):
        diagonal = work_normal[j, j]
        for k in range(j):
            diagonal -= work_normal[j, k] * work_normal[j, k]
        if diagonal <= 1e-12 * scale:
            return _SINGULAR
        diagonal = math.sqrt(diagonal)
        work_normal[j, j] = diagonal
        for i in range(j + 1, m):
            value = work_normal[i, j]
            for k in range(j):
                value -= work_normal[i, k] * work_normal[j, k]
            work_normal[i, j] = value / diagonal
    for column in range(2):
        for i in range(m):
            value = out_control[i, column]
            for k in range(i):
                value -= work_normal[i, k] * out_control[k, column]
            out_control[i, column] = value / work_normal[i, i]
        for i in range(m - 1, -1, -1):
            value = out_control[i, column]
            for k in range(i + 1, m):
                value -= work_normal[k, i] * out_control[k, column]
            out_control[i, column] = value / work_normal[i, i]
    return m


@kernel(int64(f8_2d_ro, f8_1d, f8_2d))
def sample_bspline(control, work_basis, out_points):
    """Evaluate the clamped uniform B-spline with `control` (m, 2) at len(out_points) equally spaced parameters.

    Writes `out_points` (n, 2) using `work_basis` (>= 4 values); returns n, or KernelStatus.INVALID when m < 2,
    n < 2 or `work_basis` is too short.
    """
    m = control.shape[0]
    n = out_points.shape[0]
    if m < 2 or n < 2 or work_basis.shape[0] < 4:
        return _INVALID
    degree = min(3, m - 1)
    values = work_basis
    for i in range(n):
        first = _basis_at(i / (n - 1), m, degree, values)
        u = 0.0
        v = 0.0
        for a in range(degree + 1):
            u += values[a] * control[first + a, 0]
            v += values[a] * control[first + a, 1]
        out_points[i, 0] = u
        out_points[i, 1] = v
    return n
