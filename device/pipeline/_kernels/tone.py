"""The camera's output curve undone: a frame's codes mapped through a 256-entry table into linear light."""

from __future__ import annotations

from numba import int32

from ropecam.shared.jit import kernel, u1_1d, u1_2d, u1_2d_ro


# The frame read-only or writable (Numba's safe conversion): one signature.
@kernel(int32(u1_2d_ro, u1_1d, u1_2d))
def apply_table(frame, table, out):
    """Write ``table[frame]`` into `out` (both (height, width) uint8; `table` 256 entries). Returns 0, or -1 when
    the shapes differ or the table is short (nothing written)."""
    height, width = frame.shape
    if out.shape[0] != height or out.shape[1] != width or table.shape[0] < 256:
        return -1
    for r in range(height):
        for c in range(width):
            out[r, c] = table[frame[r, c]]
    return 0
