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

__all__ = ["f32", "i32", "ro"]


def ro(array: NDArray[Any]) -> NDArray[Any]:
    """Return a read-only view of `array` (no copy)."""
    view = array.view()
    view.flags.writeable = False
    return view


def i32(value: int) -> np.int32:
    """Return `value` as an int32 scalar, refusing values that would wrap."""
    if not -(2**31) <= int(value) < 2**31:
        raise ValueError(f"{value} does not fit in int32")
    return np.int32(value)


def f32(value: float) -> np.float32:
    """Return `value` as a float32 scalar."""
    return np.float32(value)
