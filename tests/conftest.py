"""Fixtures and markers shared by the whole suite."""

from __future__ import annotations

import dataclasses
import glob
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DIR = REPO_ROOT.parent / "shared"
WITHOUT_JIT = os.environ.get("NUMBA_DISABLE_JIT") == "1"
"""True in tests/test_nojit.py's rerun of the `kernel` tests in plain Python."""


def pytest_configure(config: pytest.Config) -> None:
    """When the whole suite runs (`pytest` without paths, as CI runs it), run tests/warm_caches.py in a background
    process: on an empty Numba cache (a fresh clone) it compiles, on the second core, the device kernels that the
    collection's import of the pipeline reaches last and the protocol's, while the collection compiles the rest on
    the first (the collection's import ~154 -> ~78 s of one core), then the host's kernels (~30 s), which the
    collection reaches only with the host tests; on a filled cache it only loads them (~3 s)."""
    if WITHOUT_JIT or config.args_source != pytest.Config.ArgsSource.TESTPATHS:
        return
    config._ropecam_warm = subprocess.Popen(  # type: ignore[attr-defined]
        [sys.executable, str(Path(__file__).parent / "warm_caches.py")],
        cwd=Path(__file__).parent,  # not the repo root: keep the source folders off sys.path
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


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
    """Stop the background rerun if the session ends before its test waited for it (-x, Ctrl-C), and the
    background compilation if it still runs."""
    rerun = getattr(session.config, "_ropecam_nojit", None)
    if rerun is not None:
        rerun.stop()
    warm = getattr(session.config, "_ropecam_warm", None)
    if warm is not None and warm.poll() is None:
        warm.kill()
        warm.wait()


@pytest.fixture(scope="session", autouse=True)
def synthetic_frames_rendered_once() -> Iterator[None]:
    """`SyntheticRope.render` of a (rope, frame index) without a given generator renders once per session; later
    calls get copies of that frame.

    A frame is a pure function of the rope's parameters and its index (its noise is seeded by `seed + index`), and
    the suite renders the same ropes' frames in many modules (a 12 ms frame of 320x240 costs ~0.25 s of NumPy):
    every test still gets exactly the frame the renderer makes, its arrays its own to modify."""
    from ropecam.device.capture.synthetic import SyntheticRope

    real = SyntheticRope.render
    rendered: dict[tuple[SyntheticRope, int], object] = {}

    def render(self: SyntheticRope, index: int, rng: object = None):  # type: ignore[no-untyped-def]
        if rng is not None:
            return real(self, index, rng)
        frame = rendered.get((self, index))
        if frame is None:
            frame = rendered[(self, index)] = real(self, index)
        return dataclasses.replace(
            frame, image=frame.image.copy(), begin_uv=frame.begin_uv.copy(), end_uv=frame.end_uv.copy()
        )

    SyntheticRope.render = render  # type: ignore[method-assign]
    try:
        yield
    finally:
        SyntheticRope.render = real  # type: ignore[method-assign]


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
