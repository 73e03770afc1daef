"""Kernel caches of a package are dropped when any of its sources changed (Numba tracks each file alone); a kernel
can own the kernels it calls (`kernel`'s ``own_callees``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numba import float64, int64

from ropecam.shared.jit import drop_stale_caches, f8_1d, kernel


def _package(root: Path) -> tuple[Path, Path]:
    package = root / "kernels"
    (package / "__pycache__").mkdir(parents=True)
    (package / "a.py").write_text("def f(): return 1\n")
    (package / "b.py").write_text("def g(): return 2\n")
    cached = package / "__pycache__" / "a.f-1.py311.nbi"
    return package, cached


def test_caches_go_when_another_module_of_the_package_changes(tmp_path: Path) -> None:
    package, cached = _package(tmp_path)
    cached.write_bytes(b"index")
    assert drop_stale_caches(package)  # no stamp yet: whatever is cached may be stale
    assert not cached.exists()
    cached.write_bytes(b"index")
    (package / "__pycache__" / "a.f-1.py311.1.nbc").write_bytes(b"code")
    assert not drop_stale_caches(package)  # nothing changed: the caches stay
    assert cached.exists()
    (package / "b.py").write_text("def g(): return 3\n")  # a callee in another file
    assert drop_stale_caches(package)
    assert not cached.exists() and not (package / "__pycache__" / "a.f-1.py311.1.nbc").exists()


def test_python_bytecode_is_left_alone(tmp_path: Path) -> None:
    package, _ = _package(tmp_path)
    bytecode = package / "__pycache__" / "a.cpython-311.pyc"
    bytecode.write_bytes(b"pyc")
    drop_stale_caches(package)
    assert bytecode.exists()


def test_an_unwritable_cache_folder_is_left_as_it_is(tmp_path: Path) -> None:
    package, cached = _package(tmp_path)
    cached.write_bytes(b"index")
    (package / "__pycache__").chmod(0o500)
    try:
        result = drop_stale_caches(package)
    finally:
        (package / "__pycache__").chmod(0o700)
    # As root the folder stays writable; otherwise nothing is deleted and no error is raised.
    assert result or cached.exists()


# `kernel(own_callees=True)`: the callee's code inside the caller's object, and no symbol a later library could bind
# to. The callee is long enough that LLVM keeps it a function (not inlined) in a caller that calls it twice.
@kernel(float64(f8_1d, int64))
def _callee(values, step):
    total = 0.0
    for i in range(0, values.shape[0], step):
        total += math.sin(values[i]) * math.cos(values[i] * 0.5) + math.sqrt(abs(values[i]) + 1.0)
    for i in range(values.shape[0] - 1, -1, -step):
        total -= math.atan2(values[i], total + 3.0) * math.exp(-abs(values[i]))
    for i in range(values.shape[0]):
        values[i] = math.tanh(values[i] + total * 1e-3) if i % step == 0 else math.log1p(abs(values[i]))
    return total


@kernel(float64(f8_1d), own_callees=True)
def _own_caller(values):
    return _callee(values, 1) + _callee(values, 2)


@kernel(float64(f8_1d))
def _plain_caller(values):
    """`_own_caller` as Numba makes it (a function is cached by its name and source: two of them)."""
    return _callee(values, 1) + _callee(values, 2)


@kernel(float64(f8_1d))
def _later_caller(values):
    """A kernel made after `_own_caller`, calling the same callee with another step."""
    return _callee(values, 3)


def _linkages(dispatcher: Any, name: str) -> set[str]:
    """The linkages of the definitions of function `name` in `dispatcher`'s code (the module its library gives
    to link with, fresh or from the cache: its own functions there are weak, the rest as compiled)."""
    module = dispatcher.overloads[dispatcher.signatures[0]].library._get_module_for_linking()
    return {f.linkage.name for f in module.functions if f.name == name and not f.is_declaration}


def test_a_kernel_owning_its_callees_computes_what_the_plain_kernel_does() -> None:
    values = np.linspace(-2.0, 3.0, 101)
    own, plain = values.copy(), values.copy()
    assert _own_caller(own) == _plain_caller(plain)
    assert np.array_equal(own, plain)
    later, reference = values.copy(), values.copy()
    assert _later_caller(later) == _callee(reference, 3)  # its call reaches the callee's own code
    assert np.array_equal(later, reference)


def test_a_kernel_owning_its_callees_exports_no_copy_of_them() -> None:
    name = _callee.overloads[_callee.signatures[0]].fndesc.mangled_name
    assert _linkages(_plain_caller, name) == {"linkonce_odr"}  # Numba's weak copy: bound to the callee's library
    assert _linkages(_own_caller, name) == {"private"}  # its own copy, which no other library can bind to
