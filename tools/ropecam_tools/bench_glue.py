"""Per-frame Python of the device pipeline: the time of `Pipeline.process` outside kernel calls, and the kernels.

On a shared machine absolute times drift between runs; with ``--against REF`` the pipeline of another commit is
measured in the same process on the same frames, alternately with this tree's, so the two are compared under the
same load. The other commit's ``device/`` and ``shared/`` are exported (``git archive``) into a cache folder and
imported under the package name ``ropecam_ref`` (its kernels compile once, ~2 min, then load from that folder).

Reports medians over frames after the first `--settle` frames (the pipeline's width, fixed end and Lc0 are then
settled): total per frame, time inside kernel calls (every ``_kernels`` function is wrapped with a timer, which
adds ~0.2 us per call to the kernel side), the Python outside them (total minus kernels, frame by frame), and
``cv2.Canny`` on the same frames for the ratio.

    python tools/bench_glue.py [--frameset DIR] [--frames N] [--passes P] [--settle S] [--against REF]
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import importlib
import re
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ropecam.device.capture.frameset import FrameSet

REPO = Path(__file__).resolve().parents[1]


def load_frames(path: str, count: int) -> list[tuple[np.ndarray, int, float]]:
    """The first `count` frames of a frame set (image, t_ns, exposure_us)."""
    frameset = FrameSet(path)
    return [
        (frameset.read(i), frameset.records[i].t_ns, float(frameset.records[i].exposure_us))
        for i in range(min(count, len(frameset)))
    ]


def export_ref(ref: str) -> Path:
    """Export `ref`'s device/ and shared/ as the package ``ropecam_ref`` into a cache folder; return the folder."""
    sha = subprocess.run(["git", "rev-parse", ref], cwd=REPO, check=True, capture_output=True, text=True).stdout
    root = Path(tempfile.gettempdir()) / f"ropecam-bench-ref-{sha.strip()[:12]}"
    package = root / "ropecam_ref"
    if not (package / "__init__.py").exists():
        data = subprocess.run(["git", "archive", ref, "device", "shared"], cwd=REPO, check=True, capture_output=True)
        package.mkdir(parents=True, exist_ok=True)
        with tarfile.open(fileobj=BytesIO(data.stdout)) as archive:
            archive.extractall(package, filter="data")
        pattern = re.compile(r"ropecam\.(device|shared|host)\b")
        for source in package.rglob("*.py"):
            text = source.read_text()
            source.write_text(pattern.sub(r"ropecam_ref.\1", text))
        (package / "__init__.py").write_text("")
    return root


class KernelTimer:
    """Wrap every kernel of a `_kernels` package so that the time spent in them accumulates in `ns`."""

    def __init__(self, kernels: Any) -> None:
        self.ns = 0
        for name in dir(kernels) if kernels is not None else ():
            function = getattr(kernels, name)
            if hasattr(function, "py_func"):
                setattr(kernels, name, self._wrap(function))

    def _wrap(self, function: Any) -> Any:
        def timed(*args: Any) -> Any:
            start = time.perf_counter_ns()
            try:
                return function(*args)
            finally:
                self.ns += time.perf_counter_ns() - start

        return timed


_FIELDS = (
    "frame", "t_ns", "t_end_ns", "status", "method", "order_confidence", "begin", "end", "fixed_end",
    "segmentation_points", "material_arc_m", "material_begin", "material_end", "stretch_begin", "stretch_end",
    "rope_width_px", "full_frame", "message", "extra",
)  # fmt: skip
"""The `FrameResult` fields compared (all but `pipeline_us`)."""


def _same(x: Any, y: Any) -> bool:
    """Equal values, bit for bit: arrays by dtype, shape and content (NaN equal to NaN), enums by name."""
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        if not (isinstance(x, np.ndarray) and isinstance(y, np.ndarray)):
            return False
        return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()
    if hasattr(x, "name") and hasattr(y, "name") and hasattr(x, "value"):
        return bool(x.name == y.name and x.value == y.value)
    if isinstance(x, float) and isinstance(y, float) and x != x and y != y:
        return True
    return type(x) is type(y) and bool(x == y)


def compare(a: Any, b: Any, pipeline_a: Any, pipeline_b: Any) -> list[str]:
    """The fields of two `FrameResult`s that differ, and the pipelines' ROI spans (`lo`, `hi`) if they differ."""
    out = [
        f"{name}: {getattr(a, name)!r} != {getattr(b, name)!r}"
        for name in _FIELDS
        if not _same(getattr(a, name), getattr(b, name))
    ]
    for name in ("lo", "hi"):
        if not _same(getattr(pipeline_a, name), getattr(pipeline_b, name)):
            out.append(f"ROI span {name} differs")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frameset", default="/work/eval/rig", help="frame set folder (default: %(default)s)")
    parser.add_argument("--frames", type=int, default=60, help="frames per pass (default: %(default)s)")
    parser.add_argument("--passes", type=int, default=3, help="passes over the frames (default: %(default)s)")
    parser.add_argument("--settle", type=int, default=16, help="frames left out at the start of each pass")
    parser.add_argument("--against", metavar="REF", help="also measure this git commit, alternately (same frames)")
    parser.add_argument(
        "--plain", action="store_true", help="no kernel timers: whole-pipeline times only (no ~0.3 us per kernel call)"
    )
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    frames = load_frames(args.frameset, args.frames)
    if len(frames) <= args.settle:
        parser.error(f"{args.frameset} has {len(frames)} frames, need more than --settle {args.settle}")
    height, width = frames[0][0].shape
    variants: dict[str, tuple[Any, Any, KernelTimer]] = {}
    for label, prefix in [("this tree", "ropecam")] + ([(f"{args.against}", "ropecam_ref")] if args.against else []):
        if prefix == "ropecam_ref":
            sys.path.insert(0, str(export_ref(args.against)))
            print(f"importing {args.against} as ropecam_ref (its kernels compile once)...", flush=True)
        kernels = importlib.import_module(f"{prefix}.device.pipeline._kernels")
        config = importlib.import_module(f"{prefix}.device.pipeline.config").PipelineConfig
        pipeline = importlib.import_module(f"{prefix}.device.pipeline.pipeline").Pipeline
        variants[label] = (pipeline, config, KernelTimer(kernels) if not args.plain else KernelTimer(None))
    rows: dict[str, list[tuple[float, float]]] = {label: [] for label in variants}
    differences: list[str] = []
    canny: list[float] = []
    for pass_index in range(args.passes + 1):  # the first pass warms up (compilation, tables, caches)
        pipelines = {label: make(config(), (width, height)) for label, (make, config, _) in variants.items()}
        labels = list(pipelines)
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            order = labels if (index + pass_index) % 2 == 0 else labels[::-1]
            results = {}
            for label in order:
                timer = variants[label][2]
                timer.ns = 0
                start = time.perf_counter_ns()
                results[label] = pipelines[label].process(image, index, t_ns, exposure_us)
                total = time.perf_counter_ns() - start
                if pass_index > 0 and index >= args.settle:
                    rows[label].append((total / 1000.0, (total - timer.ns) / 1000.0))
            if pass_index == 0 and len(labels) == 2:
                a, b = labels
                differences.extend(
                    f"frame {index}: {d}" for d in compare(results[a], results[b], pipelines[a], pipelines[b])
                )
            start = time.perf_counter_ns()
            cv2.Canny(image, 20, 50, L2gradient=True)
            canny.append((time.perf_counter_ns() - start) / 1000.0)
    canny_us = float(np.median(canny))
    print(f"{args.frameset}: {len(rows[labels[0]])} frames per variant, cv2.Canny median {canny_us:.0f} us")
    for label, values in rows.items():
        data = np.array(values)
        total, python = float(np.median(data[:, 0])), float(np.median(data[:, 1]))
        print(
            f"  {label:>12}: pipeline {total:.0f} us ({total / canny_us:.3f} x Canny), kernels "
            f"{float(np.median(data[:, 0] - data[:, 1])):.0f} us, Python outside kernel calls {python:.1f} us"
        )
    if args.against:
        print(
            f"  outputs (every FrameResult field but pipeline_us, the ROI spans after each frame; first pass, "
            f"{len(frames)} frames): {'identical' if not differences else f'{len(differences)} DIFFERENCES'}"
        )
        for line in differences[:20]:
            print(f"    {line}")
        mine, theirs = np.array(rows[labels[0]]), np.array(rows[labels[1]])
        # Each frame is the same work in every pass: its fastest pass is the least disturbed by other processes.
        per_pass = len(frames) - args.settle
        best_mine = mine[:, 0].reshape(args.passes, per_pass).min(axis=0)
        best_theirs = theirs[:, 0].reshape(args.passes, per_pass).min(axis=0)
        print(
            f"  fastest pass per frame, median over frames: this tree {float(np.median(best_mine)):.1f} us, "
            f"{args.against} {float(np.median(best_theirs)):.1f} us, median paired difference "
            f"{float(np.median(best_theirs - best_mine)):.1f} us"
        )
        saved = np.median(theirs - mine, axis=0)
        print(
            f"  median paired difference ({args.against} - this tree): pipeline {saved[0]:.1f} us, "
            f"Python {saved[1]:.1f} us"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
