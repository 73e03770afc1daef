"""Types and status values the shape codec's kernels share."""

from __future__ import annotations

from typing import Final

from numba import types

from ropecam.shared.jit import KernelStatus

i8_1d: Final = types.Array(types.int64, 1, "C")
i8_1d_ro: Final = types.Array(types.int64, 1, "C", readonly=True)
i8_2d: Final = types.Array(types.int64, 2, "C")
i8_2d_ro: Final = types.Array(types.int64, 2, "C", readonly=True)
u1_1d_ro: Final = types.Array(types.uint8, 1, "C", readonly=True)

_FULL = int(KernelStatus.FULL)
_INVALID = int(KernelStatus.INVALID)
_SINGULAR = int(KernelStatus.SINGULAR)
_NO_CONVERGENCE = int(KernelStatus.NO_CONVERGENCE)
