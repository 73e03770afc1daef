"""The layer rules of STYLE.md ("Layers", "Where code goes", "Numba kernels") as tests, on the imports of every
module of the package (parsed with `ast`, lazy imports inside functions included).

- shared imports neither ropecam.device nor ropecam.host, nor OpenCV (cv2) nor mcap;
- device never imports ropecam.host or mcap, and uses OpenCV only in device/capture/;
- host imports from ropecam.device only ropecam.device.pipeline and ropecam.device.capture (offline re-processing);
- device's library (pipeline, capture, senders) never imports its applications (daemon, cli, extract);
- a kernel module (``_kernels.py`` or a module of a ``_kernels/`` package) imports only other kernel modules,
  numpy, numba (with llvmlite, its code generator, for intrinsics), math, typing (``Final``) and ropecam.shared.jit;
- package code never imports the tools (ropecam_tools) and uses absolute imports only.
"""

from __future__ import annotations

import ast
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE_DIRS = ("device", "host", "shared")


def _within(name: str, *prefixes: str) -> bool:
    """True if module `name` is one of `prefixes` or inside one of them."""
    return any(name == prefix or name.startswith(prefix + ".") for prefix in prefixes)


def _is_kernel_module(rel: Path) -> bool:
    return rel.name == "_kernels.py" or "_kernels" in rel.parts[:-1]


@dataclass(frozen=True)
class Rule:
    """One layer rule: the modules it applies to (by path relative to the repository root) and the imports it
    forbids (a reason, or None when allowed)."""

    name: str
    applies: Callable[[Path], bool]
    forbids: Callable[[str], str | None]


def _host_device(name: str) -> str | None:
    if _within(name, "ropecam.device") and not _within(name, "ropecam.device.pipeline", "ropecam.device.capture"):
        return "host may import from ropecam.device only ropecam.device.pipeline and ropecam.device.capture"
    return None


KERNEL_IMPORTS = ("numpy", "numba", "llvmlite", "math", "typing", "__future__", "ropecam.shared.jit")


def _kernel_import(name: str) -> str | None:
    if _within(name, *KERNEL_IMPORTS) or "_kernels" in name.split("."):
        return None
    return f"a kernel module imports only kernel modules and {', '.join(KERNEL_IMPORTS)}"


RULES = (
    Rule(
        "shared imports neither side, OpenCV nor mcap",
        lambda rel: rel.parts[0] == "shared",
        lambda name: (
            "shared never imports device, host, cv2 or mcap"
            if _within(name, "ropecam.device", "ropecam.host", "cv2", "mcap")
            else None
        ),
    ),
    Rule(
        "device never imports host or mcap",
        lambda rel: rel.parts[0] == "device",
        lambda name: "device never imports ropecam.host or mcap" if _within(name, "ropecam.host", "mcap") else None,
    ),
    Rule(
        "OpenCV only in device/capture/ and host/",
        lambda rel: rel.parts[0] == "device" and rel.parts[1] != "capture",
        lambda name: "device uses OpenCV only in device/capture/" if _within(name, "cv2") else None,
    ),
    Rule("host imports only the device's pipeline and capture", lambda rel: rel.parts[0] == "host", _host_device),
    Rule(
        "device's library never imports its applications",
        lambda rel: rel.parts[0] == "device" and rel.parts[1] in ("pipeline", "capture", "senders"),
        lambda name: (
            "a library module never imports an application (daemon, cli, extract)"
            if _within(name, "ropecam.device.daemon", "ropecam.device.cli", "ropecam.device.extract")
            else None
        ),
    ),
    Rule("kernels import only kernels, numpy, numba, math and jit", _is_kernel_module, _kernel_import),
    Rule(
        "package code never imports the tools",
        lambda rel: True,
        lambda name: "package code never imports the tools" if _within(name, "ropecam_tools", "tools") else None,
    ),
)

KNOWN_EXCEPTIONS = {
    ("device/pipeline/_kernels/__init__.py", "pathlib.Path"): "the cache-invalidation helper STYLE.md asks for "
    "(`drop_stale_caches(Path(__file__).parent)`) runs before the kernel modules are imported",
    ("device/pipeline/_kernels/tracking.py", "sys"): "`sys.float_info.max` for a constant; np.finfo(np.float64).max "
    "would do (left to the pipeline refactoring of #17)",
    ("device/pipeline/_kernels/tables.py", "ctypes"): "the raw-address buffer tables of `steady_frame` and "
    "`sample_slice` (point 2 of #17 keeps the table and makes it safe), without JIT",
}
"""Imports that break a rule today, each with why; `test_known_exceptions_are_still_needed` drops stale ones."""


def imported_names(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every import in `path`; ``from a import b`` gives ``a.b``; a relative import gives
    ``.``-prefixed names."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = "." * node.level + (node.module or "")
            names += [
                (node.lineno, f"{module}.{alias.name}" if module != "." * node.level else module + alias.name)
                for alias in node.names
            ]
    return names


def violations(root: Path, known: dict[tuple[str, str], str] | None = None) -> list[str]:
    """Every import under `root`'s package folders that breaks a rule, as ``file:line: import NAME: reason``,
    except the `known` (file, import) pairs."""
    known = KNOWN_EXCEPTIONS if known is None else known
    found = []
    for top in PACKAGE_DIRS:
        for path in sorted((root / top).rglob("*.py")):
            rel = path.relative_to(root)
            for line, name in imported_names(path):
                if (rel.as_posix(), name) in known:
                    continue
                if name.startswith("."):
                    found.append(f"{rel}:{line}: import {name}: absolute imports only (ropecam.…)")
                    continue
                for rule in RULES:
                    reason = rule.forbids(name) if rule.applies(rel) else None
                    if reason:
                        found.append(f"{rel}:{line}: import {name}: {reason}")
    return found


def test_the_package_keeps_every_layer_rule() -> None:
    found = violations(ROOT)
    assert not found, "layer rules of STYLE.md broken:\n" + "\n".join(found)


def test_known_exceptions_are_still_needed() -> None:
    stale = [
        f"{file}: import {name}"
        for (file, name) in KNOWN_EXCEPTIONS
        if not (ROOT / file).is_file() or name not in {n for _, n in imported_names(ROOT / file)}
    ]
    assert not stale, f"no longer imported, drop from KNOWN_EXCEPTIONS: {stale}"


BAD_MODULES = [
    ("shared/protocol/x.py", "from ropecam.device.pipeline import Pipeline", "shared never imports"),
    ("shared/x.py", "import cv2", "shared never imports"),
    ("shared/x.py", "def f():\n    import mcap.reader", "shared never imports"),
    ("device/pipeline/x.py", "from ropecam.host.sim import presets", "device never imports ropecam.host"),
    ("device/daemon/x.py", "import mcap", "device never imports ropecam.host or mcap"),
    ("device/pipeline/edges.py", "import cv2", "OpenCV only in device/capture/"),
    ("host/x.py", "from ropecam.device.daemon import runner", "host may import from ropecam.device only"),
    ("host/x.py", "from ropecam.device import senders", "host may import from ropecam.device only"),
    ("device/capture/x.py", "from ropecam.device.daemon.runner import Runner", "never imports an application"),
    ("device/pipeline/_kernels/x.py", "from ropecam.device.pipeline.edges import EdgeDetector", "a kernel module"),
    ("host/model/_kernels.py", "import os", "a kernel module"),
    ("shared/protocol/_kernels/x.py", "from ropecam.shared.errors import ProtocolError", "a kernel module"),
    ("host/x.py", "from ropecam_tools.frames import rig_frames", "never imports the tools"),
    ("host/x.py", "from . import receiver", "absolute imports only"),
]
GOOD_MODULES = [
    ("host/x.py", "from ropecam.device.pipeline.pipeline import Pipeline\nfrom ropecam.device import capture"),
    ("device/capture/x.py", "import cv2"),
    ("host/calibration/x.py", "import cv2\nimport mcap"),
    (
        "device/pipeline/_kernels/x.py",
        "import math\nfrom typing import Final\nimport numpy as np\nfrom numba import "
        "njit\nfrom ropecam.shared.jit import kernel\nfrom ropecam.device.pipeline._kernels._common import FULL",
    ),
]


@pytest.mark.parametrize(("file", "source", "message"), BAD_MODULES)
def test_the_checker_names_the_file_and_the_import_it_refuses(
    tmp_path: Path, file: str, source: str, message: str
) -> None:
    (tmp_path / file).parent.mkdir(parents=True)
    (tmp_path / file).write_text(source + "\n")
    found = violations(tmp_path, known={})
    assert len(found) == 1 and found[0].startswith(f"{file}:") and message in found[0], found
    assert source.split()[-1].split(".")[0] in found[0]  # the import is named


@pytest.mark.parametrize(("file", "source"), GOOD_MODULES)
def test_the_checker_accepts_what_the_rules_allow(tmp_path: Path, file: str, source: str) -> None:
    (tmp_path / file).parent.mkdir(parents=True)
    (tmp_path / file).write_text(source + "\n")
    assert violations(tmp_path, known={}) == []


MAX_KERNEL_ARGUMENTS = 16
"""Issue 17 ("no kernel with more than 16 arguments"): related arrays travel as the named groups of
`ropecam.device.pipeline._kernels.groups`, made once by the workspace, not as long positional lists."""


def kernel_arities(root: Path, folder: str = "device/pipeline/_kernels") -> list[tuple[int, str]]:
    """Return (argument count, ``file:name``) of every function decorated with ``kernel(...)`` in the modules
    under `root` / `folder`, the largest first."""
    found = []
    for path in sorted((root / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.FunctionDef):
                continue
            for decorator in node.decorator_list:
                target = decorator.func if isinstance(decorator, ast.Call) else decorator
                if getattr(target, "id", getattr(target, "attr", None)) == "kernel":
                    found.append((len(node.args.args), f"{path.relative_to(root)}:{node.name}"))
    return sorted(found, reverse=True)


def test_no_pipeline_kernel_takes_more_than_16_arguments() -> None:
    arities = kernel_arities(ROOT)
    assert len(arities) > 100  # the checker sees the kernels
    too_many = [f"{name}: {count}" for count, name in arities if count > MAX_KERNEL_ARGUMENTS]
    assert not too_many, f"kernels with more than {MAX_KERNEL_ARGUMENTS} arguments (use a named group): {too_many}"


def test_the_arity_checker_counts_decorated_kernels_only(tmp_path: Path) -> None:
    folder = tmp_path / "device/pipeline/_kernels"
    folder.mkdir(parents=True)
    names = ", ".join(f"a{i}" for i in range(17))
    (folder / "x.py").write_text(
        f"@kernel(sig)\ndef wide({names}):\n    pass\n\n\n@njit\ndef helper({names}):\n    pass\n\n\n"
        "@jit.kernel([sig])\ndef narrow(a, b):\n    pass\n"
    )
    assert kernel_arities(tmp_path) == [
        (17, "device/pipeline/_kernels/x.py:wide"),
        (2, "device/pipeline/_kernels/x.py:narrow"),
    ]


MAX_PIPELINE_MODULE_LINES = 600
"""Issue 17: no module of device/pipeline over 600 lines (STYLE.md: aim under 400, split before 800)."""
MAX_PIPELINE_PY_LINES = 350
"""Issue 17: `Pipeline` keeps the frame's sequence only (`pipeline.py` under 350 lines)."""


def test_no_pipeline_module_is_over_600_lines() -> None:
    sizes = {
        str(path.relative_to(ROOT)): len(path.read_text().splitlines())
        for path in sorted((ROOT / "device/pipeline").rglob("*.py"))
    }
    assert len(sizes) > 40  # the test sees the modules
    too_long = [f"{name}: {count}" for name, count in sizes.items() if count > MAX_PIPELINE_MODULE_LINES]
    assert not too_long, f"modules over {MAX_PIPELINE_MODULE_LINES} lines (split them by job): {too_long}"
    assert sizes["device/pipeline/pipeline.py"] < MAX_PIPELINE_PY_LINES
