"""Clamped B-splines of the shape codec: knots, basis functions, the least-squares fit, sampling (direct and by
a table made once per (n, m)) and the points' relative positions along the polyline."""

from __future__ import annotations

import math

from numba import float64, int64, types

from ropecam.shared.jit import f8_1d, f8_1d_ro, f8_2d, f8_2d_ro, kernel
from ropecam.shared.protocol._kernels._common import _INVALID, _SINGULAR, i8_1d, i8_1d_ro


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


@kernel(types.UniTuple(float64, 4)(float64, float64, float64, float64, float64, float64, float64))
def _cubic_basis(t, k0, k1, k2, k3, k4, k5):
    """The four non-zero cubic basis values at `t` in the span [k2, k3) (knots k0..k5 around it): `_basis_at`
    for degree 3 unrolled, the same operations in the same order (bit-identical; tested)."""
    left1 = t - k2
    right1 = k3 - t
    temp = 1.0 / (right1 + left1)
    n0 = 0.0 + right1 * temp
    n1 = left1 * temp
    left2 = t - k1
    right2 = k4 - t
    temp = n0 / (right1 + left2)
    n0 = 0.0 + right1 * temp
    saved = left2 * temp
    temp = n1 / (right2 + left1)
    n1 = saved + right2 * temp
    n2 = left1 * temp
    left3 = t - k0
    right3 = k5 - t
    temp = n0 / (right1 + left3)
    n0 = 0.0 + right1 * temp
    saved = left3 * temp
    temp = n1 / (right2 + left2)
    n1 = saved + right2 * temp
    saved = left2 * temp
    temp = n2 / (right3 + left1)
    n2 = saved + right3 * temp
    return n0, n1, n2, left1 * temp


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
    knots_span = -1
    k0 = k1 = k2 = k3 = k4 = k5 = 0.0
    for i in range(n):
        ti = min(1.0, max(0.0, t[i]))
        if degree == 3:
            # The cubic case (every spline the encoder fits) unrolled, with the six knots around the span kept
            # while consecutive points stay in it: the operations of `_basis_at`, in its order (bit-identical).
            segments = m - 3
            span = 3 + min(int(ti * segments), segments - 1)
            if span != knots_span:
                knots_span = span
                k0 = _knot(span - 2, m, 3)
                k1 = _knot(span - 1, m, 3)
                k2 = _knot(span, m, 3)
                k3 = _knot(span + 1, m, 3)
                k4 = _knot(span + 2, m, 3)
                k5 = _knot(span + 3, m, 3)
            n0, n1, n2, n3 = _cubic_basis(ti, k0, k1, k2, k3, k4, k5)
            values[0] = n0
            values[1] = n1
            values[2] = n2
            values[3] = n3
            first = span - 3
        else:
            first = _basis_at(ti, m, degree, values)
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


@kernel(int64(int64, i8_1d, f8_2d))
def bspline_sample_table(control_count, out_first, out_basis):
    """Write the basis of a clamped uniform B-spline of `control_count` control points at n = len(`out_first`)
    equally spaced parameters: per sample the first control index (`out_first`) and the degree + 1 non-zero basis
    values (``out_basis[i, :degree + 1]``). The table depends only on (n, m): `sample_with_table` then evaluates
    any spline of that size with the very arithmetic of `sample_bspline`. Returns n, or INVALID (m < 2, n < 2,
    `out_basis` too small)."""
    n = out_first.shape[0]
    m = control_count
    if m < 2 or n < 2 or out_basis.shape[0] != n or out_basis.shape[1] < 4:
        return _INVALID
    degree = min(3, m - 1)
    for i in range(n):
        out_first[i] = _basis_at(i / (n - 1), m, degree, out_basis[i])
    return n


@kernel(int64(f8_2d_ro, i8_1d_ro, f8_2d_ro, f8_2d))
def sample_with_table(control, first, basis, out_points):
    """`sample_bspline` with the basis from `bspline_sample_table` (same results, bit for bit).

    Returns n = len(`out_points`), or INVALID when the table's size differs from n or it indexes beyond `control`
    (the caller pairs each table with its m: a smaller m can pass unnoticed only while its indices stay in range).
    """
    m = control.shape[0]
    n = out_points.shape[0]
    if m < 2 or n < 2 or first.shape[0] != n or basis.shape[0] != n or basis.shape[1] < 4:
        return _INVALID
    degree = min(3, m - 1)
    for i in range(n):
        f = first[i]
        if f < 0 or f + degree >= m:
            return _INVALID
        u = 0.0
        v = 0.0
        for a in range(degree + 1):
            u += basis[i, a] * control[f + a, 0]
            v += basis[i, a] * control[f + a, 1]
        out_points[i, 0] = u
        out_points[i, 1] = v
    return n


@kernel(int64(f8_2d_ro, f8_1d))
def relative_positions(points, out_t):
    """Write the normalised arc length of each of `points` (n, 2) into `out_t` (0 at the first, 1 at the last point;
    equally spaced when the polyline has no length). Returns n, or INVALID when `out_t` is too short."""
    n = points.shape[0]
    if out_t.shape[0] < n:
        return _INVALID
    total = 0.0
    if n > 0:
        out_t[0] = 0.0
    for i in range(1, n):
        total += math.hypot(points[i, 0] - points[i - 1, 0], points[i, 1] - points[i - 1, 1])
        out_t[i] = total
    for i in range(n):
        out_t[i] = out_t[i] / total if total > 0.0 else (i / (n - 1) if n > 1 else 0.0)
    return n
