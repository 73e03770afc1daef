"""The Numba kernel decorator, the kernel status codes and the array type aliases kernels are declared with.

Every kernel is compiled eagerly (explicit signature) at import, cached on disk (`cache=True`), releases the GIL and
uses NumPy's error model (division by zero gives inf/nan, never an exception inside compiled code).
"""

from __future__ import annotations

from collections.abc import Callable
from enum import IntEnum
from typing import Any, Final

import numba
from numba import types

__all__ = [
    "KernelStatus",
    "b1_1d",
    "f4_1d",
    "f4_2d",
    "f4_2d_ro",
    "f8_1d",
    "f8_1d_ro",
    "f8_2d",
    "f8_2d_ro",
    "f8_3d",
    "i4_1d",
    "i4_1d_ro",
    "i4_2d",
    "i4_2d_ro",
    "kernel",
    "u1_1d",
    "u1_2d",
    "u1_2d_ro",
]


class KernelStatus(IntEnum):
    """Negative return codes of kernels; a non-negative return is a count of items written."""

    FULL = -1
    """An output buffer was too small; what was written is valid but incomplete."""
    INVALID = -2
    """An input violated the kernel's contract (checked cheaply inside the kernel)."""
    NOT_FOUND = -3
    """The thing searched for (rope, contour, segmentation point) is not in the input."""
    NO_CONVERGENCE = -4
    """An iterative solve did not converge within its iteration limit."""
    SINGULAR = -5
    """A linear system was singular."""


def kernel(signature: Any) -> Callable[[Callable[..., Any]], Any]:
    """Compile a function eagerly with `signature`, cached, GIL-free and with NumPy's error model.

    Parameters
    ----------
    signature
        A Numba signature such as ``int32(u1_2d_ro, uint8, i4_2d)``.

    Returns
    -------
    Callable
        A decorator producing the compiled dispatcher (a plain Python function under ``NUMBA_DISABLE_JIT=1``).
    """
    return numba.njit(signature, cache=True, nogil=True, error_model="numpy")


def _array(dtype: Any, ndim: int, readonly: bool = False) -> types.Array:
    return types.Array(dtype, ndim, "C", readonly=readonly)


u1_1d: Final = _array(types.uint8, 1)
u1_2d: Final = _array(types.uint8, 2)
u1_2d_ro: Final = _array(types.uint8, 2, readonly=True)
b1_1d: Final = _array(types.boolean, 1)
i4_1d: Final = _array(types.int32, 1)
i4_1d_ro: Final = _array(types.int32, 1, readonly=True)
i4_2d: Final = _array(types.int32, 2)
i4_2d_ro: Final = _array(types.int32, 2, readonly=True)
f4_1d: Final = _array(types.float32, 1)
f4_2d: Final = _array(types.float32, 2)
f4_2d_ro: Final = _array(types.float32, 2, readonly=True)
f8_1d: Final = _array(types.float64, 1)
f8_1d_ro: Final = _array(types.float64, 1, readonly=True)
f8_2d: Final = _array(types.float64, 2)
f8_2d_ro: Final = _array(types.float64, 2, readonly=True)
f8_3d: Final = _array(types.float64, 3)
