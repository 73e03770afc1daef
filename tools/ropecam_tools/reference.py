"""Another commit's pipeline in the same process: its ``device/`` and ``shared/`` imported as ``ropecam_ref``.

Timing two trees in one process, frame by frame in alternating order, puts the same machine load on both sides of
each paired difference; on a shared machine that is the only comparison that holds.
"""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[2]


def export_ref(ref: str) -> Path:
    """Export `ref`'s device/ and shared/ as the package ``ropecam_ref`` into a cache folder; return the folder.

    Its kernels compile once (~2 min), then load from that folder's Numba cache.

    Raises
    ------
    ValueError
        If git does not know `ref`.
    """
    done = subprocess.run(
        ["git", "rev-parse", "--verify", f"{ref}^{{commit}}"], cwd=REPO, capture_output=True, text=True
    )
    if done.returncode != 0:
        raise ValueError(f"--against: git does not know the commit {ref!r} in {REPO}: {done.stderr.strip()}")
    root = Path(tempfile.gettempdir()) / f"ropecam-bench-ref-{done.stdout.strip()[:12]}"
    package = root / "ropecam_ref"
    if not (package / "__init__.py").exists():
        data = subprocess.run(["git", "archive", ref, "device", "shared"], cwd=REPO, check=True, capture_output=True)
        package.mkdir(parents=True, exist_ok=True)
        with tarfile.open(fileobj=BytesIO(data.stdout)) as archive:
            archive.extractall(package, filter="data")
        pattern = re.compile(r"ropecam\.(device|shared|host)\b")
        for source in package.rglob("*.py"):
            source.write_text(pattern.sub(r"ropecam_ref.\1", source.read_text()))
        (package / "__init__.py").write_text("")
    return root


def pipeline_modules(ref: str | None) -> tuple[ModuleType, type, type]:
    """The kernels package, `PipelineConfig` and `Pipeline` of this tree (`ref` None) or of commit `ref`."""
    prefix = "ropecam"
    if ref is not None:
        root = str(export_ref(ref))
        if root not in sys.path:
            sys.path.insert(0, root)  # the exported tree, a package outside this repository
        print(f"importing {ref} as ropecam_ref (its kernels compile once)...", file=sys.stderr, flush=True)
        prefix = "ropecam_ref"
    kernels = importlib.import_module(f"{prefix}.device.pipeline._kernels")
    if ref is not None:
        _rename_groups(kernels)
    config = importlib.import_module(f"{prefix}.device.pipeline.config").PipelineConfig
    pipeline = importlib.import_module(f"{prefix}.device.pipeline.pipeline").Pipeline
    return kernels, config, pipeline


def _rename_groups(kernels: ModuleType) -> None:
    """Give the exported tree's named argument groups (`_kernels.groups`) names of their own.

    Numba's dispatcher types a named tuple by its class's name and its members (numba/numba#6145): this tree's
    `Motion` and the exported tree's `Motion` would share one type, and the second tree's kernels would refuse their
    own groups ("No matching definition").
    """
    for name in dir(kernels):
        value = getattr(kernels, name)
        if isinstance(value, type) and issubclass(value, tuple) and hasattr(value, "_fields"):
            value.__name__ = f"ropecam_ref_{value.__name__}"
