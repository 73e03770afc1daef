"""Rerun every test marked `kernel` with NUMBA_DISABLE_JIT=1: the kernels must mean the same in plain Python.

Compiled code silently wraps integers and skips bounds checks; plain Python does neither, so this run catches
out-of-range indexing and overflow that the compiled run would hide.

The rerun is a child pytest that needs no compiler and only one core for 1-3 minutes. When this test is part of a
larger session, the session's conftest starts it as soon as the tests are collected (`start_rerun`), so that it runs
on the second core beside the compiled tests, and this test only waits for it and reads its verdict.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
TIMEOUT_S = 900
NODE = "test_nojit.py::test_kernel_tests_pass_without_jit"


@dataclass
class Rerun:
    """The plain-Python child pytest and the file its output goes to (a file, not a pipe: nobody reads a pipe
    while the parent runs other tests, and a full pipe would stall the child)."""

    process: subprocess.Popen
    log: Path

    def wait(self) -> tuple[int, str]:
        """Wait for the child; return its exit code and its output."""
        try:
            code = self.process.wait(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.stop()
            code = -1
        output = self.log.read_text(errors="replace")
        self.log.unlink(missing_ok=True)
        return code, output

    def stop(self) -> None:
        """Kill the child if it still runs (the session ended early)."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        self.log.unlink(missing_ok=True)


def start_rerun() -> Rerun:
    """Start the plain-Python rerun of the `kernel` tests in the background."""
    log = Path(tempfile.mkstemp(prefix="ropecam-nojit-", suffix=".log")[1])
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    with log.open("w") as out:
        process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "pytest",
                "-q",
                "-m",
                "kernel",
                "-p",
                "no:cacheprovider",
                "--import-mode=importlib",
                str(REPO_ROOT / "tests"),
            ],
            cwd=REPO_ROOT / "tests",  # not the repo root: keep the source folders off sys.path
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    return Rerun(process, log)


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="already running without JIT")
def test_kernel_tests_pass_without_jit(request: pytest.FixtureRequest) -> None:
    rerun = getattr(request.config, "_ropecam_nojit", None) or start_rerun()
    code, output = rerun.wait()
    tail = "\n".join(output.splitlines()[-40:])
    assert code == 0, f"kernel tests failed without JIT (exit {code}):\n{tail}"
    assert " passed" in output, tail
