"""Run the tools' entry scripts (tools/bench.py, evaluate.py, fuzz.py, soak.py) as a user does: in a subprocess;
or, for a refusal (bad arguments, a bad config), in this process."""

from __future__ import annotations

import os
import runpy
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import cv2
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


@pytest.fixture
def run_tool_here(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> RunTool:
    """``run_tool_here("bench.py", "glue", "--config", "bad.toml")``: the entry script's command run in this process
    (its ``COMMANDS`` table through `ropecam_tools.cli.dispatch`, ``sys.argv[0]`` the script, as `run_tool` runs it),
    its exit code and output returned as `run_tool` returns them. For refusals: a subprocess spends ~3 s loading the
    pipeline's kernels before it refuses. What a tool sets for its whole process (environment variables, OpenCV's
    thread count) is put back after the call."""
    monkeypatch.syspath_prepend(str(TOOLS))

    def run(script: str, *args: str) -> subprocess.CompletedProcess[str]:
        from ropecam_tools.cli import dispatch

        namespace = runpy.run_path(str(TOOLS / script), run_name="entry_script")  # not "__main__": no sys.exit
        monkeypatch.setattr(sys, "argv", [str(TOOLS / script), *args])
        environment, threads = dict(os.environ), cv2.getNumThreads()
        capsys.readouterr()
        try:
            code = dispatch(namespace["__doc__"], namespace["COMMANDS"], list(args))
        except SystemExit as exc:  # argparse's exit, or a message: what the interpreter prints and exits with
            code = exc.code if isinstance(exc.code, int) else 0 if exc.code is None else 1
            if not isinstance(exc.code, int | None):
                print(exc.code, file=sys.stderr)
        finally:
            for name in set(os.environ) - set(environment):
                del os.environ[name]
            os.environ.update(environment)
            cv2.setNumThreads(threads)
        out, err = capsys.readouterr()
        return subprocess.CompletedProcess([script, *args], code, out, err)

    return run
