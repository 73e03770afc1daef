"""Numba kernels of the shape codec (the encoder runs on the device's per-frame path): point-to-polyline
distances, least-squares B-spline fit, B-spline sampling, the encoder's fit-and-correct step and byte counts."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float64, int64, types

from ropecam.shared.jit import KernelStatus, f8_1d, f8_1d_ro, f8_2d, f8_2d_ro, kernel, u1_1d

i8_1d: Final = types.Array(types.int64, 1, "C")
i8_1d_ro: Final = types.Array(types.int64, 1, "C", readonly=True)
i8_2d: Final = types.Array(types.int64, 2, "C")
i8_2d_ro: Final = types.Array(types.int64, 2, "C", readonly=True)
u1_1d_ro: Final = types.Array(types.uint8, 1, "C", readonly=True)

_FULL = int(KernelStatus.FULL)
_INVALID = int(KernelStatus.INVALID)
_SINGULAR = int(KernelStatus.SINGULAR)
_NO_CONVERGENCE = int(KernelStatus.NO_CONVERGENCE)


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


@kernel(int64(int64))
def uvarint_bytes(value):
    """Return the length in bytes of `value` (>= 0) written as a LEB128 varint."""
    count = 1
    while value >= 0x80:
        value >>= 7
        count += 1
    return count


@kernel(int64(int64))
def svarint_bytes(value):
    """Return the length in bytes of `value` written as a zigzag LEB128 varint."""
    return uvarint_bytes(value << 1 if value >= 0 else ((-value) << 1) - 1)


@kernel(int64(i8_2d_ro))
def chain_bytes(items):
    """Return the bytes `shapes._write_chain` spends on `items` (m, 2): item 0, the first and second differences."""
    m = items.shape[0]
    if m == 0:
        return 0
    total = svarint_bytes(items[0, 0]) + svarint_bytes(items[0, 1])
    if m > 1:
        total += svarint_bytes(items[1, 0] - items[0, 0]) + svarint_bytes(items[1, 1] - items[0, 1])
    for i in range(2, m):
        total += svarint_bytes(items[i, 0] - 2 * items[i - 1, 0] + items[i - 2, 0])
        total += svarint_bytes(items[i, 1] - 2 * items[i - 1, 1] + items[i - 2, 1])
    return total


@kernel(int64(int64, int64))
def fit_work_size(point_count, control_count):
    """Values of float64 work `fit_spline_with_corrections` needs for n = `point_count` points and m control points."""
    return 4 + control_count * control_count + 5 * point_count + 2 * control_count


@kernel(
    int64(
        f8_2d_ro, f8_1d_ro, int64, int64, float64, int64, i8_1d_ro, i8_1d_ro, f8_2d_ro,
        f8_1d, i8_1d, i8_2d, i8_1d, i8_2d, f8_1d,
    )
)  # fmt: skip
def fit_spline_with_corrections(
    points,
    t,
    shift,
    max_rounds,
    tolerance_px,
    half_window,
    origin_q,
    sample_first,
    sample_basis,
    work,
    work_changed,
    out_control_q,
    out_index,
    out_offset_q,
    out_stats,
):
    """Fit a spline of m = len(`out_control_q`) control points to `points` and find the corrections that bring every
    point within `tolerance_px` of the decoded polyline (the encoder's inner loop, one call per candidate m).

    `work` (float64, at least ``fit_work_size(n, m)`` values) holds, in this order, the fit's basis values (4) and
    normal matrix (m * m), the samples and the decoded polyline (n * 2 each), the distances (n) and the control
    points in pixels (m * 2): one argument instead of six (each array argument costs the call ~0.4 us).
    The control points are fitted (`fit_bspline`), quantised to ``2**-shift`` px into `out_control_q`, turned back
    into pixels exactly as the decoder does and sampled at len(`points`) equally spaced parameters
    (`sample_with_table` with the table of (n, m) from `bspline_sample_table`: `sample_first`, `sample_basis`).
    Then, for up to `max_rounds` rounds: the distance of every point to the decoded polyline (the end points also
    to the decoded end points; after the first round only for the points whose window holds a sample moved in the
    round before: the others' distances cannot have changed; `work_changed`, n + 1 values, counts the moved
    samples); the decoded sample nearest each point farther than `tolerance_px` is moved onto it (an
    offset at the quantum), or, when that sample already carries another point, a free neighbour. Writes the k
    corrections in sample order to ``out_index[:k]`` and ``out_offset_q[:k]``, and to `out_stats`: [0] the largest
    distance, [1] the bytes of the shape's control chain relative to `origin_q` plus its correction list.
    Returns k; KernelStatus.NO_CONVERGENCE when points are still out of tolerance after `max_rounds`; INVALID or
    SINGULAR from the fit.
    """
    n = points.shape[0]
    m = out_control_q.shape[0]
    if (
        n < 2
        or m < 2
        or t.shape[0] != n
        or work.shape[0] < fit_work_size(n, m)
        or out_index.shape[0] < n
        or out_offset_q.shape[0] < n
        or out_stats.shape[0] < 2
        or origin_q.shape[0] != 2
        or work_changed.shape[0] != n + 1
    ):
        return _INVALID
    work_basis = work[0:4]
    work_normal = work[4 : 4 + m * m].reshape((m, m))
    offset = 4 + m * m
    work_samples = work[offset : offset + 2 * n].reshape((n, 2))
    offset += 2 * n
    work_decoded = work[offset : offset + 2 * n].reshape((n, 2))
    offset += 2 * n
    out_distance_px = work[offset : offset + n]
    offset += n
    out_control = work[offset : offset + 2 * m].reshape((m, 2))
    status = fit_bspline(points, t, m, work_basis, work_normal, out_control)
    if status != m:
        return status
    scale = float(1 << shift)
    for a in range(m):
        for axis in range(2):
            out_control_q[a, axis] = int(np.rint(out_control[a, axis] * scale))
            out_control[a, axis] = out_control_q[a, axis] / scale
    if sample_with_table(out_control, sample_first, sample_basis, work_samples) != n:
        return _INVALID
    for i in range(n):
        work_decoded[i, 0] = work_samples[i, 0]
        work_decoded[i, 1] = work_samples[i, 1]
        out_offset_q[i, 0] = 0
        out_offset_q[i, 1] = 0
        out_index[i] = -1  # until the corrections are listed: the point each sample was moved onto
    converged = False
    for round_number in range(max_rounds):
        if round_number == 0:
            distances_to_polyline(points, t, work_decoded, half_window, out_distance_px)
        else:
            # work_changed[j + 1] = 1 for each sample j moved last round; as prefix sums it tells in O(1) per point
            # whether its window [lo, hi + 1] holds one.
            for j in range(n):
                work_changed[j + 1] += work_changed[j]
            for i in range(n):
                lo, hi = _window(t[i], n, half_window)
                if work_changed[hi + 2] - work_changed[lo] > 0:
                    out_distance_px[i] = _distance_in_window(points, t, work_decoded, half_window, i)
        for j in range(n + 1):
            work_changed[j] = 0
        out_distance_px[0] = max(
            out_distance_px[0], math.hypot(points[0, 0] - work_decoded[0, 0], points[0, 1] - work_decoded[0, 1])
        )
        out_distance_px[n - 1] = max(
            out_distance_px[n - 1],
            math.hypot(points[n - 1, 0] - work_decoded[n - 1, 0], points[n - 1, 1] - work_decoded[n - 1, 1]),
        )
        bad = 0
        for i in range(n):
            if out_distance_px[i] > tolerance_px:
                bad += 1
        if bad == 0:
            converged = True
            break
        # Move the decoded sample nearest each failing point onto it (index space ~ arc length on both sides). A
        # sample already moved onto another point keeps it: the next free sample on the point's side, else on the
        # other side, takes this one (two points sharing a sample would undo each other round after round).
        for i in range(n):
            if out_distance_px[i] > tolerance_px:
                position = min(1.0, max(0.0, t[i])) * (n - 1)
                target = min(max(int(np.rint(position)), 0), n - 1)
                if out_index[target] != -1 and out_index[target] != i:
                    near = target + 1 if position >= target else target - 1
                    far = 2 * target - near
                    if 0 <= near < n and (out_index[near] == -1 or out_index[near] == i):
                        target = near
                    elif 0 <= far < n and (out_index[far] == -1 or out_index[far] == i):
                        target = far
                out_index[target] = i
                du = int(np.rint((points[i, 0] - work_samples[target, 0]) * scale))
                dv = int(np.rint((points[i, 1] - work_samples[target, 1]) * scale))
                out_offset_q[target, 0] = du
                out_offset_q[target, 1] = dv
                work_changed[target + 1] = 1
                work_decoded[target, 0] = work_samples[target, 0] + du / scale
                work_decoded[target, 1] = work_samples[target, 1] + dv / scale
    if not converged:
        return _NO_CONVERGENCE
    worst = 0.0
    for i in range(n):
        worst = max(worst, out_distance_px[i])
    size = 0
    count = 0
    previous = -1
    for i in range(n):
        if out_offset_q[i, 0] != 0 or out_offset_q[i, 1] != 0:
            size += uvarint_bytes(i - previous - 1)
            size += svarint_bytes(out_offset_q[i, 0]) + svarint_bytes(out_offset_q[i, 1])
            out_index[count] = i
            out_offset_q[count, 0] = out_offset_q[i, 0]
            out_offset_q[count, 1] = out_offset_q[i, 1]
            count += 1
            previous = i
    size += uvarint_bytes(count)
    size += svarint_bytes(out_control_q[0, 0] - origin_q[0]) + svarint_bytes(out_control_q[0, 1] - origin_q[1])
    if m > 1:
        size += svarint_bytes(out_control_q[1, 0] - out_control_q[0, 0])
        size += svarint_bytes(out_control_q[1, 1] - out_control_q[0, 1])
    for a in range(2, m):
        size += svarint_bytes(out_control_q[a, 0] - 2 * out_control_q[a - 1, 0] + out_control_q[a - 2, 0])
        size += svarint_bytes(out_control_q[a, 1] - 2 * out_control_q[a - 1, 1] + out_control_q[a - 2, 1])
    out_stats[0] = worst
    out_stats[1] = size
    return count


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


@kernel(int64(int64, u1_1d, int64))
def _put_uvarint(value, out_bytes, position):
    """Write `value` (>= 0) as LEB128 at `position`; return the next position, or FULL."""
    while True:
        if position >= out_bytes.shape[0]:
            return _FULL
        if value < 0x80:
            out_bytes[position] = value
            return position + 1
        out_bytes[position] = (value & 0x7F) | 0x80
        value >>= 7
        position += 1


@kernel(int64(int64, u1_1d, int64))
def _put_svarint(value, out_bytes, position):
    """Write `value` as a zigzag LEB128 varint at `position`; return the next position, or FULL."""
    return _put_uvarint(value << 1 if value >= 0 else ((-value) << 1) - 1, out_bytes, position)


@kernel(int64(i8_2d_ro, i8_2d_ro, i8_1d_ro, i8_2d_ro, u1_1d))
def write_spline_body(control_q, reference_q, index, offset_q, out_bytes):
    """Write the part of a spline shape after its control count (see `shapes`): the chain of the items
    ``control_q - reference_q`` (item 0, the first difference, the second differences), the correction count and
    per correction the index gap and the offset (rows of `index` and `offset_q`, in increasing index order).

    `reference_q` has one (u, v) row per control point (a relative shape) or a single row (the origin) subtracted
    from every one. Returns the bytes written into `out_bytes`, FULL when it is too small, INVALID when
    `reference_q` has another number of rows or the corrections disagree in count.
    """
    m = control_q.shape[0]
    k = index.shape[0]
    per_row = reference_q.shape[0] == m
    if (not per_row and reference_q.shape[0] != 1) or offset_q.shape[0] != k:
        return _INVALID
    position = 0
    pu = pv = qu = qv = 0
    for a in range(m):
        r = a if per_row else 0
        u = control_q[a, 0] - reference_q[r, 0]
        v = control_q[a, 1] - reference_q[r, 1]
        if a == 0:
            du, dv = u, v
        elif a == 1:
            du, dv = u - pu, v - pv
        else:
            du, dv = u - 2 * pu + qu, v - 2 * pv + qv
        qu, qv = pu, pv
        pu, pv = u, v
        position = _put_svarint(du, out_bytes, position)
        if position >= 0:
            position = _put_svarint(dv, out_bytes, position)
        if position < 0:
            return position
    position = _put_uvarint(k, out_bytes, position)
    previous = -1
    for c in range(k):
        if position >= 0:
            position = _put_uvarint(index[c] - previous - 1, out_bytes, position)
        if position >= 0:
            position = _put_svarint(offset_q[c, 0], out_bytes, position)
        if position >= 0:
            position = _put_svarint(offset_q[c, 1], out_bytes, position)
        previous = index[c]
    return position


@kernel(types.UniTuple(int64, 2)(u1_1d_ro, int64))
def _get_uvarint(data, position):
    """Read one LEB128 varint of at most 9 bytes at `position`: (value, next position), or (0, FULL) when the data
    ends and (0, INVALID) for a longer varint (the wire's values are far smaller)."""
    value = 0
    for shift in range(0, 63, 7):
        if position >= data.shape[0]:
            return 0, _FULL
        byte = int64(data[position])
        position += 1
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value, position
    return 0, _INVALID


@kernel(types.UniTuple(int64, 2)(u1_1d_ro, int64))
def _get_svarint(data, position):
    """Read one zigzag varint (as `_get_uvarint`): (value, next position) or (0, status)."""
    zigzag, position = _get_uvarint(data, position)
    return (zigzag >> 1) ^ -(zigzag & 1), position


@kernel(int64(u1_1d_ro, int64, int64, i8_2d))
def read_chain(data, position, limit, out_items):
    """Read a chain as `write_spline_body` writes it (2 m zigzag varints from `position`: item 0, the first
    difference, the second differences) and write its m = len(`out_items`) items (u, v), summed up.

    Item 0 must lie within +-`limit`, the first difference within 2 `limit`, second differences within 4 `limit`,
    and every item within +-`limit`. Returns the position after the chain; KernelStatus.FULL when the data ends
    first, INVALID for a varint longer than 9 bytes or a value out of range.
    """
    u = 0
    v = 0
    du = 0
    dv = 0
    for i in range(out_items.shape[0]):
        bound = limit if i == 0 else (2 * limit if i == 1 else 4 * limit)
        a, position = _get_svarint(data, position)
        if position < 0:
            return position
        b, position = _get_svarint(data, position)
        if position < 0:
            return position
        if abs(a) > bound or abs(b) > bound:
            return _INVALID
        if i == 0:
            u, v = a, b
        else:
            if i == 1:
                du, dv = a, b
            else:
                du += a
                dv += b
            u += du
            v += dv
        if abs(u) > limit or abs(v) > limit:
            return _INVALID
        out_items[i, 0] = u
        out_items[i, 1] = v
    return position


@kernel(int64(u1_1d_ro, int64, int64, int64, int64, f8_2d))
def apply_corrections(data, position, count, limit, shift, out_points):
    """Read `count` corrections from `position` (per correction: the index gap as a varint, then du, dv as zigzag
    varints in units of ``2**-shift`` px) and add each offset to its point of `out_points`.

    Returns the position after them; KernelStatus.FULL when the data ends first, INVALID for a malformed varint,
    an offset beyond +-`limit` or an index beyond len(`out_points`).
    """
    n = out_points.shape[0]
    scale = float(1 << shift)
    index = -1
    for _ in range(count):
        gap, position = _get_uvarint(data, position)
        if position < 0:
            return position
        if gap >= n:
            return _INVALID
        index += gap + 1
        if index >= n:
            return _INVALID
        du, position = _get_svarint(data, position)
        if position < 0:
            return position
        dv, position = _get_svarint(data, position)
        if position < 0:
            return position
        if abs(du) > limit or abs(dv) > limit:
            return _INVALID
        out_points[index, 0] += du / scale
        out_points[index, 1] += dv / scale
    return position


@kernel(boolean(f8_2d_ro, float64))
def points_within(points, limit):
    """Return True when every coordinate of `points` (n, 2) is finite and strictly within +-`limit` (one pass: the
    record's check of a polyline costs one call instead of several NumPy reductions)."""
    for i in range(points.shape[0]):
        for axis in range(2):
            value = points[i, axis]
            if not abs(value) < limit:  # also False for nan
                return False
    return True


@kernel(boolean(f8_2d_ro, float64, float64))
def rows_on_wire(points, scale, limit_q):
    """Return True when every row of `points` (n, 2) is either (nan, nan) or a finite (u, v) whose quantisation
    ``rint(x * scale)`` lies strictly within +-`limit_q` (the record's material-point rule, in one pass)."""
    for i in range(points.shape[0]):
        u = points[i, 0]
        v = points[i, 1]
        u_nan = math.isnan(u)
        v_nan = math.isnan(v)
        if u_nan and v_nan:
            continue
        if u_nan or v_nan or math.isinf(u) or math.isinf(v):
            return False
        if not (abs(np.rint(u * scale)) < limit_q and abs(np.rint(v * scale)) < limit_q):
            return False
    return True


@kernel(int64(u1_1d_ro, u1_1d))
def cobs_encode_into(data, out_bytes):
    """Write the COBS encoding of `data` into `out_bytes` (it needs len(data) + len(data) // 254 + 1 bytes) and
    return its length, or FULL when `out_bytes` is too small. The byte-for-byte algorithm of `framing`: blocks of a
    code byte (distance to the next zero, at most 255) and up to 254 non-zero bytes; a block of 254 ends the
    coding when the data ends with it."""
    length = data.shape[0]
    if out_bytes.shape[0] < length + length // 254 + 1:
        return _FULL
    position = 0
    start = 0
    while True:
        limit = min(start + 254, length)
        zero = -1
        for i in range(start, limit):
            if data[i] == 0:
                zero = i
                break
        if zero >= 0:
            out_bytes[position] = zero - start + 1
            position += 1
            for i in range(start, zero):
                out_bytes[position] = data[i]
                position += 1
            start = zero + 1
            continue
        out_bytes[position] = limit - start + 1
        position += 1
        for i in range(start, limit):
            out_bytes[position] = data[i]
            position += 1
        if limit == length:
            break
        start = limit
    return position


@kernel(boolean(i8_2d_ro, int64))
def ints_within(values, limit):
    """Return True when every entry of `values` (n, 2) lies within +-`limit` (inclusive)."""
    for i in range(values.shape[0]):
        for axis in range(2):
            value = values[i, axis]
            if value > limit or value < -limit:  # not abs(): it wraps at the most negative int64
                return False
    return True


@kernel(int64(u1_1d_ro, int64, int64, int64, i8_2d_ro, i8_1d_ro, f8_2d_ro, i8_2d, f8_2d, f8_2d))
def decode_spline(
    data, position, limit, shift, base_q, sample_first, sample_basis, out_control_q, work_control, out_points
):
    """Decode the body of a spline shape after its control count (see `shapes`) in one call: the chain of
    m = len(`out_control_q`) items (`read_chain`), plus `base_q` (one row: the origin; m rows: the reference
    shape's control points) into `out_control_q`, each within +-`limit`; the correction count (<= n); the spline
    sampled at n = len(`out_points`) parameters (`sample_with_table`, its table for (n, m); `work_control` (m, 2)
    receives the control points in pixels) and the corrections added (`apply_corrections`).

    Returns the position after the shape, or a negative KernelStatus for any fault (the caller's step-by-step
    parser then names it).
    """
    m = out_control_q.shape[0]
    n = out_points.shape[0]
    per_row = base_q.shape[0] == m
    if (not per_row and base_q.shape[0] != 1) or work_control.shape[0] != m or m < 2:
        return _INVALID
    position = read_chain(data, position, limit, out_control_q)
    if position < 0:
        return position
    scale = float(1 << shift)
    for a in range(m):
        r = a if per_row else 0
        for axis in range(2):
            value = out_control_q[a, axis] + base_q[r, axis]
            if value > limit or value < -limit:
                return _INVALID
            out_control_q[a, axis] = value
            work_control[a, axis] = value / scale
    count, position = _get_uvarint(data, position)
    if position < 0:
        return position
    if count > n:
        return _INVALID
    if sample_with_table(work_control, sample_first, sample_basis, out_points) != n:
        return _INVALID
    return apply_corrections(data, position, count, limit, shift, out_points)
