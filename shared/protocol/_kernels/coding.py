"""The wire's byte coding in kernels: varints and their sizes, the control points' delta chain, the corrections,
the range checks that keep values codable, and COBS framing."""

from __future__ import annotations

import math

import numpy as np
from numba import boolean, float64, int64, types

from ropecam.shared.jit import f8_2d, f8_2d_ro, kernel, u1_1d
from ropecam.shared.protocol._kernels._common import _FULL, _INVALID, i8_1d_ro, i8_2d, i8_2d_ro, u1_1d_ro


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


@kernel(boolean(i8_2d_ro, int64))
def ints_within(values, limit):
    """Return True when every entry of `values` (n, 2) lies within +-`limit` (inclusive)."""
    for i in range(values.shape[0]):
        for axis in range(2):
            value = values[i, axis]
            if value > limit or value < -limit:  # not abs(): it wraps at the most negative int64
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
