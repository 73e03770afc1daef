"""The Numba kernel decorator, the kernel status codes and the array type aliases kernels are declared with.

Every kernel is compiled eagerly (explicit signature) at import, cached on disk (`cache=True`), releases the GIL and
uses NumPy's error model (division by zero gives inf/nan, never an exception inside compiled code).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from enum import IntEnum
from pathlib import Path
from typing import Any, Final

import numba
from llvmlite import binding as llvm
from numba import types
from numba.core.compiler import CompilerBase, DefaultPassBuilder

__all__ = [
    "KernelStatus",
    "b1_1d",
    "drop_stale_caches",
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


def drop_stale_caches(package_dir: str | Path) -> bool:
    """Delete the cached kernels of a package of kernel modules when any of its sources (or this module) changed.

    Numba keys a cached kernel on its own file only: a kernel that calls a kernel of another module keeps the
    callee's old code after the callee's file is edited (seen in development: a split kernel ran an old smoothing
    for hours). Call this at the top of the package's ``__init__``, before importing its modules. A stamp of all
    the sources is kept next to the caches (``__pycache__/kernel-sources.sha1``); when it differs, the Numba
    cache files (``*.nbi``, ``*.nbc``) there are deleted and compiled again on import. Unwritable folders (an
    installed copy with Numba's user-wide cache) are left as they are: an installation copies every file anew, and
    Numba then sees new stamps on all of them.

    Returns
    -------
    bool
        True when caches were dropped.
    """
    folder = Path(package_dir)
    digest = hashlib.sha1()
    for source in [*sorted(folder.glob("*.py")), Path(__file__)]:
        try:
            digest.update(source.name.encode() + b"\0" + source.read_bytes())
        except OSError:
            return False
    cache = folder / "__pycache__"
    stamp = cache / "kernel-sources.sha1"
    try:
        if stamp.read_text() == digest.hexdigest():
            return False
    except OSError:
        pass
    try:
        cache.mkdir(exist_ok=True)
        for stale in [*cache.glob("*.nbi"), *cache.glob("*.nbc")]:
            stale.unlink(missing_ok=True)
        stamp.write_text(digest.hexdigest())
    except OSError:
        return False
    return True


def kernel(signature: Any, own_callees: bool = False) -> Callable[[Callable[..., Any]], Any]:
    """Compile a function eagerly with `signature`, cached, GIL-free and with NumPy's error model.

    Parameters
    ----------
    signature
        A Numba signature such as ``int32(u1_2d_ro, uint8, i4_2d)``.
    own_callees
        Run the kernels it calls from its own copies of them (`_OwnCalleesLibrary`), not from their own compiled
        libraries: for a fused kernel called once per frame (``steady_frame``), whose callees' code then lies in
        one place instead of ~50 (docs/speed.md, "the code a steady frame runs"). Same results, more machine code
        (its callees compiled once more, in its object).

    Returns
    -------
    Callable
        A decorator producing the compiled dispatcher (a plain Python function under ``NUMBA_DISABLE_JIT=1``).
    """
    if own_callees:
        return numba.njit(signature, cache=True, nogil=True, error_model="numpy", pipeline_class=_OwnCalleesCompiler)
    return numba.njit(signature, cache=True, nogil=True, error_model="numpy")


def _own_callees_library(codegen: Any, name: str) -> Any:
    """A code library of `codegen`'s kind whose linked-in callees become private to it (`_OwnCalleesLibrary`)."""
    base = type(codegen)._library_class
    cls = _OWN_LIBRARY_CLASSES.get(base)
    if cls is None:

        class _OwnCalleesLibrary(base):  # type: ignore[misc, valid-type]
            """Numba links a callee's module into its caller's as ``linkonce_odr`` (weak) copies; the loader then
            sends every call that LLVM did not inline to the first definition loaded, the callee's own library,
            so a fused kernel's code runs from as many places as it has callees. Made private before the
            module's optimisation, the copies are the ones called (and those left unused are dropped). Private,
            not internal: an internal function keeps its name in the object's symbols, and a library loaded
            later bound its calls to such a copy, which LLVM had compiled for this caller's arguments only (a
            crash, from the on-disk cache); a private one has no symbol."""

            def _optimize_final_module(self) -> None:
                for function in self._final_module.functions:
                    if not function.is_declaration and function.linkage == llvm.Linkage.linkonce_odr:
                        function.linkage = llvm.Linkage.private
                super()._optimize_final_module()

        cls = _OWN_LIBRARY_CLASSES[base] = _OwnCalleesLibrary
    library = cls(codegen, name)
    library.enable_object_caching()
    return library


_OWN_LIBRARY_CLASSES: dict[type, type] = {}


class _OwnCalleesCompiler(CompilerBase):  # type: ignore[misc]
    """Numba's nopython pipeline, lowering into an `_own_callees_library` (`kernel`'s ``own_callees``)."""

    def define_pipelines(self) -> list[Any]:
        state = self.state
        if state.library is None:
            state.library = _own_callees_library(state.targetctx.codegen(), state.func_id.func_qualname)
        return [DefaultPassBuilder.define_nopython_pipeline(state)]


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
