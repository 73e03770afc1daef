"""Rerun every test marked `kernel` with NUMBA_DISABLE_JIT=1: the kernels must mean the same in plain Python.

Compiled code silently wraps integers and skips bounds checks; plain Python does neither, so this run catches
out-of-range indexing and overflow that the compiled run would hide.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="already running without JIT")
def test_kernel_tests_pass_without_jit() -> None:
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    result = subprocess.run(
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
        capture_output=True,
        text=True,
        timeout=900,
    )
    tail = "\n".join(result.stdout.splitlines()[-30:])
    assert result.returncode == 0, f"kernel tests failed without JIT:\n{tail}\n{result.stderr[-3000:]}"
    assert " passed" in result.stdout, tail
