"""Layering: the host imports from the device package only the pipeline and the capture sources (used offline)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HOST_MAY_IMPORT = ("ropecam.device.pipeline", "ropecam.device.capture")


def _imports(path: Path) -> list[str]:
    names = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.append(node.module)
    return names


def test_host_imports_only_the_device_pipeline_and_capture() -> None:
    offending = [
        f"{path.relative_to(ROOT)}: {name}"
        for path in sorted((ROOT / "host").rglob("*.py"))
        for name in _imports(path)
        if name.startswith("ropecam.device") and not name.startswith(HOST_MAY_IMPORT)
    ]
    assert not offending, offending
