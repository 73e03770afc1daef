"""Constants shared by the pipeline kernels: status codes, the neighbour order of the chain code, edge labels."""

from __future__ import annotations

from typing import Final

import numpy as np
from numba import types

from ropecam.shared.jit import KernelStatus

f4_1d_ro: Final = types.Array(types.float32, 1, "C", readonly=True)

FULL: Final = int(KernelStatus.FULL)
INVALID: Final = int(KernelStatus.INVALID)
NOT_FOUND: Final = int(KernelStatus.NOT_FOUND)

# Clockwise neighbour order on screen (rows point down), starting east: E, SE, S, SW, W, NW, N, NE.
DIR_ROW: Final = np.array([0, 1, 1, 1, 0, -1, -1, -1], dtype=np.int32)
DIR_COL: Final = np.array([1, 1, 0, -1, -1, -1, 0, 1], dtype=np.int32)

TAN_22_5: Final = np.float32(0.41421356237309503)
ZERO: Final = np.float32(0.0)
TWO: Final = np.float32(2.0)
EDGE_NONE: Final = 0
EDGE_WEAK: Final = 1
EDGE_STRONG: Final = 2
