"""Buffers reached through a table of raw addresses, and the frame through a one-slot object array.

A kernel called from Python pays, for every NumPy array argument, one NRT MemInfo (48 bytes, allocated through
CPython's raw allocator: what `tracemalloc` sees as the call's Python allocation) besides the array's type
matching. The steady frame's kernels take none: their buffers are the rows of a table (int64, (rows, 4): address,
then the sizes of up to three dimensions; `ropecam.device.pipeline._views.buffer_table` makes it), the table is
passed as its address (a Python int made once), and the frame as the address of a one-slot object array that
holds it during the call (`ropecam.device.pipeline._views.FrameSlot`): the kernel reads the frame's data address,
dimensions and strides from its `PyArrayObject` (NumPy's C ABI: ``data`` at `ARRAY_DATA`, ``nd``, ``dimensions``,
``strides`` after it; `FrameSlot` checks this layout once against NumPy's own answers before any kernel reads it).

Whoever makes a table keeps its arrays alive and unchanged in shape while it is used.
"""

from __future__ import annotations

import ctypes
from typing import Any, Final

import numba
import numpy as np
from numba import carray, types
from numba.extending import intrinsic

ARRAY_DATA: Final = 16
"""Byte offset of ``data`` (the first element's address) in a `PyArrayObject` (after the object header)."""
ARRAY_ND: Final = 24
"""Byte offset of ``nd`` (int) in a `PyArrayObject`."""
ARRAY_DIMENSIONS: Final = 32
"""Byte offset of ``dimensions`` (a pointer to ``nd`` npy_intp) in a `PyArrayObject`."""
ARRAY_STRIDES: Final = 40
"""Byte offset of ``strides`` (a pointer to ``nd`` npy_intp, bytes) in a `PyArrayObject`."""

# ``pointer(address, dtype)``: the int64 `address` as a pointer to `dtype` (a NumPy scalar type, or a record
# dtype such as `BAND_STATE`); `carray` takes the dtype too, which it needs for the untyped pointer without JIT.
if numba.config.DISABLE_JIT:

    def pointer(address: int, dtype: Any) -> Any:
        return ctypes.c_void_p(int(address))

else:

    @intrinsic
    def pointer(typingctx: Any, address: Any, dtype: Any) -> Any:
        if not isinstance(address, types.Integer) or not isinstance(dtype, (types.NumberClass, types.DType)):
            return None
        target = dtype.instance_type if isinstance(dtype, types.NumberClass) else dtype.dtype
        pointer_type = types.CPointer(target)

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            return builder.inttoptr(args[0], context.get_value_type(pointer_type))

        return pointer_type(address, dtype), codegen


@numba.njit(inline="always")
def table_at(address, rows):  # type: ignore[no-untyped-def]
    """The table of `rows` rows (int64, (rows, 4)) at `address`."""
    return carray(pointer(address, np.int64), (rows, 4), np.int64)


@numba.njit(inline="always")
def buffer1(table, row, dtype):  # type: ignore[no-untyped-def]
    """The 1-D buffer of `table`'s `row`."""
    return carray(pointer(table[row, 0], dtype), (table[row, 1],), dtype)


@numba.njit(inline="always")
def buffer2(table, row, dtype):  # type: ignore[no-untyped-def]
    """The 2-D buffer of `table`'s `row`."""
    return carray(pointer(table[row, 0], dtype), (table[row, 1], table[row, 2]), dtype)


@numba.njit(inline="always")
def buffer3(table, row, dtype):  # type: ignore[no-untyped-def]
    """The 3-D buffer of `table`'s `row`."""
    return carray(pointer(table[row, 0], dtype), (table[row, 1], table[row, 2], table[row, 3]), dtype)


@numba.njit(inline="always")
def slot_frame_address(table, row):  # type: ignore[no-untyped-def]
    """The data address of the uint8 frame held by the frame slot of `table`'s `row` (address of the slot, 1,
    height, width), or 0 when the slot is empty or holds no C-contiguous (height, width) array: its `PyArrayObject`
    is read for its dimensions and strides."""
    obj = carray(pointer(table[row, 0], np.int64), (1,), np.int64)[0]
    if obj == 0:
        return 0
    if carray(pointer(obj + ARRAY_ND, np.int32), (1,), np.int32)[0] != 2:
        return 0
    dims = carray(
        pointer(carray(pointer(obj + ARRAY_DIMENSIONS, np.int64), (1,), np.int64)[0], np.int64), (2,), np.int64
    )
    strides = carray(
        pointer(carray(pointer(obj + ARRAY_STRIDES, np.int64), (1,), np.int64)[0], np.int64), (2,), np.int64
    )
    height = table[row, 2]
    width = table[row, 3]
    if dims[0] != height or dims[1] != width or strides[0] != width or strides[1] != 1:
        return 0
    return carray(pointer(obj + ARRAY_DATA, np.int64), (1,), np.int64)[0]


@numba.njit(inline="always")
def slot_frame(table, row, address):  # type: ignore[no-untyped-def]
    """The frame at `address` (`slot_frame_address` of `table`'s `row`) as a (height, width) uint8 array."""
    return carray(pointer(address, np.uint8), (table[row, 2], table[row, 3]), np.uint8)
