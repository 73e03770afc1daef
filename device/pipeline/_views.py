"""Exact argument types for kernel calls.

A Numba dispatcher compiled for explicit signatures finds its machine code on a fast path only when the argument
types match exactly; a mutable array passed for a read-only parameter, or a Python int for an int32, sends every
call through type-conversion resolution (about 100 us each). Stages therefore pass read-only views and NumPy
scalars of the declared width.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["as_ro", "f32", "i32", "resident_zeros", "ro", "staggered_planes"]


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
