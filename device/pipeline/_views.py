"""Exact argument types for kernel calls.

A Numba dispatcher compiled for explicit signatures finds its machine code on a fast path only when the argument
types match exactly; a mutable array passed for a read-only parameter, or a Python int for an int32, sends every
call through type-conversion resolution (about 100 us each). Stages therefore pass read-only views and NumPy
scalars of the declared width.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["as_ro", "buffer_table", "f32", "i32", "resident_zeros", "ro", "staggered_planes"]


def ro(array: NDArray[Any]) -> NDArray[Any]:
    """Return a read-only view of `array` (no copy)."""
    view = array.view()
    view.flags.writeable = False
    return view


def as_ro(array: NDArray[Any]) -> NDArray[Any]:
    """Return `array` itself when it is read-only already, else a read-only view (`ro`)."""
    return array if not array.flags.writeable else ro(array)


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


def buffer_table(arrays: Mapping[str, NDArray[Any]], spec: Sequence[tuple[str, Any, int]]) -> NDArray[np.int64]:
    """Return the table of `arrays`' addresses and shapes that a kernel taking its buffers as one argument reads
    (`ropecam.device.pipeline._kernels.steady_frame`): row k = (address, size of each dimension, 0 for the
    dimensions it has not) of the buffer named ``spec[k][0]``.

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
