"""The shape encoder's inner loop: a spline of m control points fitted, quantised and decoded as the decoder does,
and the per-point corrections that bring every point within the tolerance (the device's per-frame path)."""

from __future__ import annotations

import math

import numpy as np
from numba import float64, int64

from ropecam.shared.jit import f8_1d, f8_1d_ro, f8_2d_ro, kernel
from ropecam.shared.protocol._kernels._common import _INVALID, _NO_CONVERGENCE, i8_1d, i8_1d_ro, i8_2d
from ropecam.shared.protocol._kernels.coding import svarint_bytes, uvarint_bytes
from ropecam.shared.protocol._kernels.distance import _distance_in_window, _window, distances_to_polyline
from ropecam.shared.protocol._kernels.spline import fit_bspline, sample_with_table


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
