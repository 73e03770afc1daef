"""Run the tools' entry scripts (tools/bench.py, evaluate.py, fuzz.py, soak.py) as a user does: in a subprocess."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parents[2] / "tools"

RunTool = Callable[..., subprocess.CompletedProcess[str]]


@pytest.fixture(scope="session")
def tools_dir() -> Path:
    """The repository's tools/ folder."""
    return TOOLS


@pytest.fixture(scope="session")
def run_tool() -> RunTool:
    """``run_tool("bench.py", "device", "--frames", "3")``: the finished process (text output, not checked)."""

    def run(script: str, *args: str, timeout_s: float = 600) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, str(TOOLS / script), *args], capture_output=True, text=True, timeout=timeout_s, check=False
        )

    return run
