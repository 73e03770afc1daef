"""Kernel caches of a package are dropped when any of its sources changed (Numba tracks each file alone)."""

from __future__ import annotations

from pathlib import Path

from ropecam.shared.jit import drop_stale_caches


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
