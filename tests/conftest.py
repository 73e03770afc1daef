"""Fixtures and markers shared by the whole suite."""

from __future__ import annotations

import glob
import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DIR = REPO_ROOT.parent / "shared"
WITHOUT_JIT = os.environ.get("NUMBA_DISABLE_JIT") == "1"
"""True in tests/test_nojit.py's rerun of the `kernel` tests in plain Python."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip tests marked `hardware` when no camera is attached, and tests marked `jit_only` in the plain-Python
    rerun."""
    camera = bool(glob.glob("/dev/video*"))
    no_camera = pytest.mark.skip(reason="hardware test: no /dev/video* on this machine")
    compiled_only = pytest.mark.skip(reason="jit_only: a pipeline-level check, run with JIT only")
    for item in items:
        if "hardware" in item.keywords and not camera:
            item.add_marker(no_camera)
        if "jit_only" in item.keywords and WITHOUT_JIT:
            item.add_marker(compiled_only)


def pytest_collection_finish(session: pytest.Session) -> None:
    """Start tests/test_nojit.py's plain-Python rerun of the kernel tests in the background when that test is
    selected, so that it runs on a second core beside the compiled tests instead of after them."""
    if WITHOUT_JIT or session.config.option.collectonly:
        return
    if any(item.nodeid.endswith("test_nojit.py::test_kernel_tests_pass_without_jit") for item in session.items):
        from .test_nojit import start_rerun

        session.config._ropecam_nojit = start_rerun()


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Stop the background rerun if the session ends before its test waited for it (-x, Ctrl-C)."""
    rerun = getattr(session.config, "_ropecam_nojit", None)
    if rerun is not None:
        rerun.stop()


@pytest.fixture(scope="session")
def jit_enabled() -> bool:
    """False in the plain-Python rerun (tests/test_nojit.py): a test may then use a smaller input that still
    reaches every branch of its kernels (plain Python is 100-1000x slower)."""
    return not WITHOUT_JIT


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The `../shared` folder handed to the developers (reference data, real images)."""
    if not SHARED_DIR.is_dir():
        pytest.fail(f"{SHARED_DIR} is missing: the suite reads reference data from ../shared beside the repo")
    return SHARED_DIR


@pytest.fixture(scope="session")
def ancf_reference_dir(shared_dir: Path) -> Path:
    """Exudyn's reference trajectories of the paper's rope."""
    return shared_dir / "reference" / "ancf"


@pytest.fixture(scope="session")
def rig_frames(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Twelve frames of the simulated rig (1024x544, 4 ms, from 200 ms into the swing, where the rope swings fast),
    rendered once per session for every test that runs the live or offline path on them: read them, never write."""
    from ropecam.host.cli import main as host_main

    out = tmp_path_factory.mktemp("rig_frames") / "rig"
    assert host_main(["simulate", "rig", "--out", str(out), "--frames", "12", "--first-exposure-ms", "200", "-q"]) == 0
    return out
