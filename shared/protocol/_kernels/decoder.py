"""The shape decoder's one-call path: a spline body parsed, sampled and corrected in one kernel."""

from __future__ import annotations

from numba import int64

from ropecam.shared.jit import f8_2d, f8_2d_ro, kernel
from ropecam.shared.protocol._kernels._common import _INVALID, i8_1d_ro, i8_2d, i8_2d_ro, u1_1d_ro
from ropecam.shared.protocol._kernels.coding import _get_uvarint, apply_corrections, read_chain
from ropecam.shared.protocol._kernels.spline import sample_with_table


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
