"""Exact argument types for kernel calls.

A Numba dispatcher compiled for explicit signatures finds its machine code on a fast path only when the argument
types match exactly; a mutable array passed for a read-only parameter, or a Python int for an int32, sends every
call through type-conversion resolution (about 100 us each). Stages therefore pass read-only views and NumPy
scalars of the declared width.
"""

from __future__ import annotations

import ctypes
import functools
import operator
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline._kernels.tables import ARRAY_DATA, ARRAY_DIMENSIONS, ARRAY_ND, ARRAY_STRIDES

__all__ = [
    "FrameSlot",
    "RecordCells",
    "array_layout_known",
    "as_ro",
    "buffer_table",
    "cell_property",
    "f32",
    "i32",
    "resident_zeros",
    "ro",
    "staggered_planes",
]


def ro(array: NDArray[Any]) -> NDArray[Any]:
    """Return a read-only view of `array` (no copy)."""
    view = array.view()
    view.flags.writeable = False
    return view


def cell_property(cells: str, index: int, doc: str) -> property:
    """Return a property that reads and writes the int cell `index` of the array attribute `cells` (a count or a
    time a kernel keeps there; read on demand as a Python int)."""
    get = operator.attrgetter(cells)

    def read(self: Any) -> int:
        return int(get(self)[index])

    def write(self: Any, value: int) -> None:
        get(self)[index] = value

    return property(read, write, doc=doc)


def as_ro(array: NDArray[Any]) -> NDArray[Any]:
    """Return `array` itself when it is read-only already, else a read-only view (`ro`)."""
    return array if not array.flags.writeable else ro(array)


class RecordCells:
    """One record of a structured array whose fields are all 8 bytes wide (int64, float64), read and written field
    by field through two memoryviews of its bytes (int64 and float64), at the slots `slot` gives.

    A memoryview's item is a C read that makes a Python int or float (the float from CPython's free list, an int
    within -5..256 cached): no NumPy scalar, no tuple, no argument checks. ``record.item()`` of a steady frame's
    results costs 2-4 us after the frame's kernel has run (its objects and NumPy's code evicted), a memoryview item
    ~0.05-0.2 us.

    Parameters
    ----------
    record
        A C-contiguous structured array of one record (``np.zeros(1, dtype)``), every field int64 or float64;
        the cells read and write it in place (it must outlive them, and never be resized).
    """

    __slots__ = ("floats", "ints", "slots")

    def __init__(self, record: NDArray[np.void]) -> None:
        fields = record.dtype.fields
        if (
            record.shape != (1,)
            or not record.flags.c_contiguous
            or fields is None
            or any(kind.itemsize != 8 or kind.kind not in "if" for kind, *_ in fields.values())
        ):
            raise ValueError(
                f"RecordCells needs one C-contiguous record of 8-byte fields, got {record.shape} of {record.dtype}"
            )
        raw = memoryview(record.view(np.uint8))
        self.ints, self.floats = raw.cast("q"), raw.cast("d")
        """The record's bytes as int64 and as float64 cells."""
        self.slots = {name: offset // 8 for name, (_, offset, *_) in fields.items()}
        """The cell of each field, by name."""

    def slot(self, name: str) -> int:
        """The cell of the field `name`."""
        return self.slots[name]


def i32(value: int) -> np.int32:
    """Return `value` as an int32 scalar, refusing values that would wrap."""
    if not -(2**31) <= int(value) < 2**31:
        raise ValueError(f"{value} does not fit in int32")
    return np.int32(value)


def f32(value: float) -> np.float32:
    """Return `value` as a float32 scalar."""
    return np.float32(value)


def staggered_planes(count: int, shape: tuple[int, int], dtype: Any) -> list[NDArray[Any]]:
    """Return `count` zeroed C-contiguous arrays of `shape` whose start addresses differ modulo 4096 bytes.

    Image-sized buffers allocated one by one all start at the same offset within a 4 KiB page; a loop that reads
    one at index k and writes another at index k then suffers 4K aliasing (the CPU takes the load for a
    dependency on the store and stalls): the Sobel pass over short row spans ran 2x slower. Carving the planes
    out of one block, each shifted by a different multiple of 64 bytes, avoids it.
    """
    dtype = np.dtype(dtype)
    plane_bytes = int(np.prod(shape)) * dtype.itemsize
    step = max(64, (4096 // max(count, 1)) // 64 * 64)
    stride = -(-plane_bytes // 4096) * 4096 + step  # whole pages plus the stagger
    raw = resident_zeros(stride * count + 4096, np.uint8)
    start = (-raw.ctypes.data) % 4096
    return [raw[start + i * stride : start + i * stride + plane_bytes].view(dtype).reshape(shape) for i in range(count)]


def resident_zeros(shape: int | tuple[int, ...], dtype: Any) -> NDArray[Any]:
    """Return a zeroed array whose memory is really mapped (written once now).

    ``np.zeros`` of a large array gets pages the kernel maps on first touch: the first frame, which touches every
    page of every image-sized buffer, then paid some 3000 page faults (tens of ms on a loaded machine).
    """
    array = np.empty(shape, dtype)
    array.fill(0)
    return array


@functools.cache
def array_layout_known() -> bool:
    """Whether this NumPy's `PyArrayObject` has ``data``, ``nd``, ``dimensions`` and ``strides`` where the kernels
    that read a frame from a `FrameSlot` look for them (`ropecam.device.pipeline._kernels.tables`): checked once,
    on a test array, against NumPy's own answers (it is NumPy's C ABI, which compiled extensions rely on)."""
    probe = np.zeros((3, 5), np.uint8)[:, 1:4]
    base = id(probe)

    def word(offset: int) -> int:
        return int(ctypes.c_int64.from_address(base + offset).value)

    dims, strides = word(ARRAY_DIMENSIONS), word(ARRAY_STRIDES)
    return (
        word(ARRAY_DATA) == probe.ctypes.data
        and ctypes.c_int32.from_address(base + ARRAY_ND).value == probe.ndim
        and [ctypes.c_int64.from_address(dims + 8 * k).value for k in range(2)] == list(probe.shape)
        and [ctypes.c_int64.from_address(strides + 8 * k).value for k in range(2)] == list(probe.strides)
    )


class FrameSlot:
    """A one-slot object array that holds a frame while a kernel reads it through a table row (address of the
    slot, 1, height, width; `ropecam.device.pipeline._kernels.tables.slot_frame_address`), so that the frame is no
    array argument: a NumPy array passed to a compiled function costs an NRT MemInfo of 48 bytes, which Numba
    allocates through CPython's raw allocator (Python allocation per call); a store into the slot allocates
    nothing.

    Parameters
    ----------
    height, width
        The frames' size: a kernel refuses a frame of another size or not C-contiguous.
    """

    __slots__ = ("_slot", "height", "width")

    def __init__(self, height: int, width: int) -> None:
        self._slot = np.full(1, None, object)
        self.height, self.width = int(height), int(width)

    def hold(self, frame: NDArray[np.uint8]) -> None:
        """Hold `frame` (a (height, width) C-contiguous uint8 array) for the next kernel call."""
        self._slot[0] = frame

    def release(self) -> None:
        """Let go of the frame (a kernel reading the slot now refuses to run)."""
        self._slot[0] = None

    def row(self) -> tuple[int, int, int, int]:
        """The slot's table row: its address, 1, height, width."""
        return self._slot.ctypes.data, 1, self.height, self.width


def buffer_table(
    arrays: Mapping[str, NDArray[Any] | FrameSlot], spec: Sequence[tuple[str, Any, int]]
) -> NDArray[np.int64]:
    """Return the table of `arrays`' addresses and shapes that a kernel taking its buffers as one argument reads
    (`ropecam.device.pipeline._kernels.steady_frame`): row k = (address, size of each dimension, 0 for the
    dimensions it has not) of the buffer named ``spec[k][0]``; a `FrameSlot` (for an int64 row of one dimension)
    gives its `FrameSlot.row`.

    The table holds raw addresses: the caller keeps `arrays` alive and in place while it uses the table.

    Parameters
    ----------
    arrays
        The buffers by name: exactly the names of `spec`.
    spec
        (name, dtype, dimensions) per row (e.g. `STEADY_BUFFERS`).

    Raises
    ------
    TypeError
        A buffer that is not a C-contiguous NumPy array of its dtype and dimensions, or whose memory is not
        writable (a read-only view of writable memory is taken: the kernel only reads those).
    ValueError
        A name of `spec` missing from `arrays`, or a name of `arrays` that `spec` does not list.
    """
    names = [name for name, _, _ in spec]
    missing, unknown = sorted(set(names) - set(arrays)), sorted(set(arrays) - set(names))
    if missing or unknown:
        raise ValueError(f"buffers missing: {missing or 'none'}; not in the table: {unknown or 'none'}")
    table = np.zeros((len(spec), 4), np.int64)
    for row, (name, dtype, ndim) in enumerate(spec):
        array = arrays[name]
        if isinstance(array, FrameSlot) and np.dtype(dtype) == np.int64 and ndim == 1:
            table[row] = array.row()
            continue
        if not isinstance(array, np.ndarray) or array.dtype != np.dtype(dtype) or array.ndim != ndim:
            got = f"{array.dtype} array of {array.ndim} dimensions" if isinstance(array, np.ndarray) else type(array)
            raise TypeError(f"buffer {name!r} is a {got}, expected a {np.dtype(dtype)} array of {ndim} dimensions")
        owner = array
        while isinstance(owner.base, np.ndarray):
            owner = owner.base
        if not array.flags.c_contiguous or not owner.flags.writeable:
            raise TypeError(f"buffer {name!r} must be C-contiguous in writable memory")
        table[row, 0] = array.ctypes.data
        table[row, 1 : 1 + ndim] = array.shape
    return table
