"""The camera's output curve undone: a frame's codes mapped through a 256-entry table into linear light."""

from __future__ import annotations

from typing import Final

import numba
import numpy as np
from numba import boolean, int32, int64, types

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.device.pipeline._kernels.tables import buffer1, buffer2, slot_frame, slot_frame_address, table_at
from ropecam.shared.jit import kernel, u1_1d, u1_2d, u1_2d_ro


@numba.njit(inline="always")
def _map(frame, table, out):  # type: ignore[no-untyped-def]
    for r in range(frame.shape[0]):
        for c in range(frame.shape[1]):
            out[r, c] = table[frame[r, c]]


# The frame read-only or writable (Numba's safe conversion): one signature.
@kernel(int32(u1_2d_ro, u1_1d, u1_2d))
def apply_table(frame, table, out):
    """Write ``table[frame]`` into `out` (both (height, width) uint8; `table` 256 entries). Returns 0, or -1 when
    the shapes differ or the table is short (nothing written)."""
    height, width = frame.shape
    if out.shape[0] != height or out.shape[1] != width or table.shape[0] < 256:
        return -1
    _map(frame, table, out)
    return 0


GAIN_BITS: Final = 12
"""Fixed-point bits of `flatten_frame`'s gain (4096 = 1)."""

_u2_2d_ro = types.Array(types.uint16, 2, "C", readonly=True)


@kernel(int32(u1_2d_ro, u1_1d, _u2_2d_ro, u1_2d, u1_2d))
def flatten_frame(frame, table, gain, linear, out):
    """Write ``table[frame]`` into `linear` (as `apply_table`), then ``min(255, linear * gain / 2**GAIN_BITS)``
    (rounded) into `out`: a static background's texture divided out (`ropecam.device.pipeline.background`). All
    (height, width) C-contiguous, `table` 256 entries. Returns 0, or -1 when the shapes differ (nothing written).
    Two passes: the second (no table lookup) is vectorised; one fused pass cost more (docs/speed.md, dark15)."""
    height, width = frame.shape
    for a in (gain.shape, linear.shape, out.shape):
        if a[0] != height or a[1] != width:
            return -1
    if table.shape[0] < 256:
        return -1
    # Flat, not `_map`'s rows and columns: two 2-D passes measured 714 us against 427 for two flat ones (dark15).
    f, g, lin, o = frame.ravel(), gain.ravel(), linear.ravel(), out.ravel()
    for i in range(f.size):
        lin[i] = table[f[i]]
    for i in range(f.size):
        v = (np.uint32(lin[i]) * np.uint32(g[i]) + np.uint32(2048)) >> np.uint32(GAIN_BITS)
        o[i] = min(v, np.uint32(255))
    return 0


TONE_BUFFERS: Final = (("frame_slot", np.int64, 1), ("table", np.uint8, 1), ("out", np.uint8, 2))
"""The rows of `take_frame`'s table: (name, dtype, dimensions), the frame slot's row its address, 1, height, width
(`ropecam.device.pipeline._kernels.tables`)."""
_TONE_FRAME, _TONE_TABLE, _TONE_OUT = range(len(TONE_BUFFERS))
FRAME_AS_GIVEN: Final = 0
"""`take_frame`: the frame is C-contiguous and of the slot's size; nothing to map."""
FRAME_MAPPED: Final = 1
"""`take_frame`: the frame, C-contiguous and of the slot's size, was mapped through ``table`` into ``out``."""


@kernel(int64(int64, boolean))
def take_frame(table_address, mapped):
    """Take the frame the slot of the table at `table_address` (`TONE_BUFFERS`) holds: FRAME_AS_GIVEN when it is a
    C-contiguous (height, width) array of the slot's size, FRAME_MAPPED when it is and `mapped` asked for
    ``table[frame]`` in ``out``, INVALID (-2) when it is not (nothing written). No array argument: no Python
    allocation per call, where an array argument costs a MemInfo."""
    table = table_at(table_address, len(TONE_BUFFERS))
    address = slot_frame_address(table, _TONE_FRAME)
    if address == 0:
        return INVALID
    if not mapped:
        return FRAME_AS_GIVEN
    frame = slot_frame(table, _TONE_FRAME, address)
    out = buffer2(table, _TONE_OUT, np.uint8)
    lookup = buffer1(table, _TONE_TABLE, np.uint8)
    if out.shape[0] != frame.shape[0] or out.shape[1] != frame.shape[1] or lookup.shape[0] < 256:
        return INVALID
    _map(frame, lookup, out)
    return FRAME_MAPPED
