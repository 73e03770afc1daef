"""tests/warm_caches.py (the background compilation on a fresh clone, started by tests/conftest.py) names kernel
modules that exist: a renamed module would stop it silently (its output is not read) and the suite would only be
slower."""

from __future__ import annotations

import importlib.util
from pathlib import Path

TESTS = Path(__file__).resolve().parent
KERNELS_DIR = TESTS.parent / "device" / "pipeline" / "_kernels"


def test_the_background_compilation_names_existing_kernel_modules() -> None:
    spec = importlib.util.spec_from_file_location("warm_caches", TESTS / "warm_caches.py")
    assert spec is not None and spec.loader is not None
    warm = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(warm)  # defines names only (main() runs under __main__)
    assert warm.KERNELS == "ropecam.device.pipeline._kernels"
    missing = [name for name in warm.DEVICE_LAST if not (KERNELS_DIR / f"{name}.py").is_file()]
    assert not missing, f"tests/warm_caches.py DEVICE_LAST names no module in {KERNELS_DIR}: {missing}"
    for module in warm.LATER:
        assert importlib.util.find_spec(module) is not None, module
