"""Constants shared by the pipeline kernels: status codes, the neighbour order of the chain code, edge labels; the
cache prefetch hints."""

from __future__ import annotations

import math
from typing import Any, Final

import numba
import numpy as np
from llvmlite import ir
from numba import float64, types
from numba.core import cgutils
from numba.extending import intrinsic

from ropecam.shared.jit import KernelStatus, kernel

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


def _prefetch_intrinsic(write: int) -> Any:
    """Return a Numba intrinsic ``f(array, index)`` hinting the CPU to fetch the cache line of ``array[index]``
    (a 1-D array) for reading (`write` 0) or writing (1); no code runs without JIT."""
    if numba.config.DISABLE_JIT:

        def no_op(array: Any, index: Any) -> None:
            return None

        return no_op

    @intrinsic
    def prefetch(typingctx: Any, array: Any, index: Any) -> Any:
        if not isinstance(array, types.Array) or array.ndim != 1 or not isinstance(index, types.Integer):
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            array_type, index_type = signature.args
            data = context.make_array(array_type)(context, builder, args[0]).data
            pointer = builder.gep(data, [context.cast(builder, args[1], index_type, types.intp)])
            pointer = builder.bitcast(pointer, ir.IntType(8).as_pointer())
            i32 = ir.IntType(32)
            function_type = ir.FunctionType(ir.VoidType(), [pointer.type, i32, i32, i32])
            function = cgutils.get_or_insert_function(builder.module, function_type, "llvm.prefetch.p0")
            builder.call(function, [pointer, i32(write), i32(3), i32(1)])  # locality 3: keep in all levels
            return context.get_dummy_value()

        return types.void(array, index), codegen

    return prefetch


prefetch_read: Final = _prefetch_intrinsic(0)
"""``prefetch_read(array, index)``: start loading the cache line of ``array[index]`` (1-D) into the caches."""
prefetch_write: Final = _prefetch_intrinsic(1)
"""``prefetch_write(array, index)``: the same for a line about to be written."""


@kernel(float64(float64, float64))
def vector_length(d_r, d_c):
    """Return the length of the vector (d_r, d_c): an inline square root (``math.hypot`` is a libm call guarding
    against overflow that coordinates in pixels never reach, ~3x the time)."""
    return math.sqrt(d_r * d_r + d_c * d_c)
