"""The entry scripts' command tables: every subcommand names a module of tools/ropecam_tools with a one-line help,
``add_arguments`` and ``run``, and ``--help`` lists them all without importing them (fast)."""

from __future__ import annotations

import ast
from collections.abc import Callable
from pathlib import Path
from subprocess import CompletedProcess

import pytest

SCRIPTS = ("bench.py", "evaluate.py", "fuzz.py", "soak.py")

RunTool = Callable[..., CompletedProcess[str]]
"""The `run_tool` fixture (tests/tools/conftest.py)."""


def _commands(script: Path) -> dict[str, str]:
    """The script's ``COMMANDS`` table, read from its source."""
    for node in ast.parse(script.read_text()).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "COMMANDS" for t in node.targets):
            return ast.literal_eval(node.value)
    raise AssertionError(f"{script}: no COMMANDS table")


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_subcommand_module_has_a_summary_add_arguments_and_run(tools_dir: Path, script: str) -> None:
    commands = _commands(tools_dir / script)
    assert commands, script
    for name, module in commands.items():
        path = tools_dir / "ropecam_tools" / f"{module}.py"
        assert path.is_file(), f"{script} {name}: no module {path}"
        tree = ast.parse(path.read_text())
        doc = ast.get_docstring(tree)
        assert doc and doc.splitlines()[0].strip(), f"{path}: no one-line summary"
        functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
        assert {"add_arguments", "run"} <= functions, f"{path}: lacks add_arguments or run"


def test_each_tool_module_serves_one_subcommand_or_is_shared(tools_dir: Path) -> None:
    served = {module for script in SCRIPTS for module in _commands(tools_dir / script).values()}
    shared = {"__init__", "cli", "frames", "reference", "timing", "truth_metrics"}
    on_disk = {path.stem for path in (tools_dir / "ropecam_tools").glob("*.py")}
    unreached = {m for m in on_disk - served - shared if not m.startswith("matrix")}  # matrix*: #18's helpers
    assert not unreached, f"modules no entry script reaches (a shared helper? add it to `shared`): {sorted(unreached)}"
    assert {p.name for p in tools_dir.glob("*.py")} == set(SCRIPTS), "tools/ holds the entry scripts only"


@pytest.mark.parametrize("script", SCRIPTS)
def test_help_lists_every_subcommand(run_tool: RunTool, tools_dir: Path, script: str) -> None:
    done = run_tool(script, "--help", timeout_s=60)
    assert done.returncode == 0, done.stderr
    for name in _commands(tools_dir / script):
        assert f"\n    {name}" in done.stdout, (name, done.stdout)


def test_an_unknown_subcommand_is_refused(run_tool: RunTool) -> None:
    done = run_tool("bench.py", "no-such-command", timeout_s=60)
    assert done.returncode == 2 and "invalid choice: 'no-such-command'" in done.stderr
