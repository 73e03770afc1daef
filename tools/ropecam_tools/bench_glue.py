"""Per-frame Python of the device pipeline: the time of `Pipeline.process` outside kernel calls, and the kernels.

On a shared machine absolute times drift between runs; with ``--against REF`` the pipeline of another commit is
measured in the same process on the same frames, alternately with this tree's, so the two are compared under the
same load. The other commit's ``device/`` and ``shared/`` are exported (``git archive``) into a cache folder and
imported under the package name ``ropecam_ref`` (its kernels compile once, ~2 min, then load from that folder).

Reports medians over frames after the first `--settle` frames (the pipeline's width, fixed end and Lc0 are then
settled): total per frame, time inside kernel calls (every ``_kernels`` function is wrapped with a timer, which
adds ~0.2 us per call to the kernel side), the Python outside them (total minus kernels, frame by frame), and
``cv2.Canny`` on the same frames for the ratio.

    python tools/bench.py glue [--frameset DIR] [--frames N] [--passes P] [--settle S] [--against REF] [--warm-up]
        [--config TOML]

A scene that needs its own settings (the ``lab`` presets: gamma, plane, static mask) is compared with the
``[pipeline]`` table ``ropecam-device setup`` wrote for it (``--config``), read by each tree's own modules.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import importlib
import time
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from ropecam_tools.cli import UsageError, positive_int
from ropecam_tools.frames import add_frame_arguments, frames_from, source_name
from ropecam_tools.reference import pipeline_modules
from ropecam_tools.timing import KernelTimer

_FIELDS = (
    "frame", "t_ns", "t_end_ns", "status", "method", "order_confidence", "begin", "end", "fixed_end",
    "segmentation_points", "material_arc_m", "material_begin", "material_end", "stretch_begin", "stretch_end",
    "rope_width_px", "full_frame", "message", "extra",
)  # fmt: skip
"""The `PipelineResult` fields compared (all but `pipeline_us`)."""


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
    """The fields of two `PipelineResult`s that differ, and the pipelines' ROI spans (`lo`, `hi`) if they differ."""
    out = [
        f"{name}: {getattr(a, name)!r} != {getattr(b, name)!r}"
        for name in _FIELDS
        if not _same(getattr(a, name), getattr(b, name))
    ]
    for name in ("lo", "hi"):
        if not _same(getattr(pipeline_a, name), getattr(pipeline_b, name)):
            out.append(f"ROI span {name} differs")
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    add_frame_arguments(parser, frames=60)
    parser.add_argument("--passes", type=positive_int, default=3, help="passes over the frames (default: %(default)s)")
    parser.add_argument("--settle", type=int, default=16, help="frames left out at the start of each pass")
    parser.add_argument("--against", metavar="REF", help="also measure this git commit, alternately (same frames)")
    parser.add_argument(
        "--warm-up", action="store_true", help="warm every pipeline up first (`Pipeline.warm_up`), as the daemon does"
    )
    parser.add_argument(
        "--config",
        metavar="TOML",
        help="the [pipeline] table of this device.toml, with its plane_file, and [capture] readout_us, for both trees "
        "(default: the defaults)",
    )
    parser.add_argument(
        "--plain", action="store_true", help="no kernel timers: whole-pipeline times only (no ~0.3 us per kernel call)"
    )


def pipeline_factory(prefix: str, config_class: type, make: type, toml: str | None) -> Callable[[tuple[int, int]], Any]:
    """A function making a pipeline of tree `prefix` (``ropecam`` or ``ropecam_ref``) for a frame size: its
    `PipelineConfig` `config_class` and `Pipeline` `make`, with the [pipeline] table of `toml` and its plane read by
    that tree's own modules (None: the defaults)."""
    if toml is None:
        return lambda size: make(config_class(), size)
    settings = importlib.import_module(f"{prefix}.shared.config")
    errors = (OSError, ValueError, importlib.import_module(f"{prefix}.shared.errors").RopecamError)
    try:
        document = settings.read_toml(toml)
        config = settings.from_mapping(config_class, dict(document.get("pipeline", {})), where=f"{toml} [pipeline]")
        plane = None
        if config.plane_file is not None:
            plane = importlib.import_module(f"{prefix}.shared.plane").read_plane_file(config.plane_file)
        readout_us = document.get("capture", {}).get("readout_us", 0)  # a rolling shutter's placement on the plane
        if not isinstance(readout_us, int) or readout_us < 0:
            raise ValueError(f"[capture] readout_us must be an integer >= 0 (microseconds), got {readout_us!r}")
    except AttributeError as exc:  # a tree older than the config reader
        raise UsageError(f"--config {toml}: the tree {prefix} cannot read a device.toml ({exc})") from exc
    except errors as exc:
        raise UsageError(f"--config {toml}: {exc}") from exc
    return lambda size: make(config, size, readout_us=readout_us, plane=plane)


def run(args: argparse.Namespace) -> int:
    """Time the pipeline(s) frame by frame; print the medians, the paired differences and the output check."""
    cv2.setNumThreads(1)
    frames = frames_from(args)
    if len(frames) <= args.settle:
        raise UsageError(f"{source_name(args)} gives {len(frames)} frames, need more than --settle {args.settle}")
    height, width = frames[0][0].shape
    variants: dict[str, tuple[Callable[[tuple[int, int]], Any], KernelTimer | None]] = {}
    for label, ref in [("this tree", None)] + ([(args.against, args.against)] if args.against else []):
        try:
            kernels, config, pipeline = pipeline_modules(ref)
        except ValueError as exc:
            raise UsageError(str(exc)) from exc
        factory = pipeline_factory("ropecam" if ref is None else "ropecam_ref", config, pipeline, args.config)
        variants[label] = (factory, None if args.plain else KernelTimer(kernels))
    rows: dict[str, list[tuple[float, float]]] = {label: [] for label in variants}
    differences: list[str] = []
    canny: list[float] = []
    for pass_index in range(args.passes + 1):  # the first pass warms up (compilation, tables, caches)
        pipelines = {label: make((width, height)) for label, (make, _) in variants.items()}
        for pipeline in pipelines.values() if args.warm_up else ():
            pipeline.warm_up()
        labels = list(pipelines)
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            order = labels if (index + pass_index) % 2 == 0 else labels[::-1]
            results = {}
            for label in order:
                timer = variants[label][1]
                if timer is not None:
                    timer.clear()
                start = time.perf_counter_ns()
                results[label] = pipelines[label].process(image, index, t_ns, exposure_us)
                total = time.perf_counter_ns() - start
                if pass_index > 0 and index >= args.settle:
                    in_kernels = timer.total_ns if timer is not None else 0
                    rows[label].append((total / 1000.0, (total - in_kernels) / 1000.0))
            if pass_index == 0 and len(labels) == 2:
                a, b = labels
                differences.extend(
                    f"frame {index}: {d}" for d in compare(results[a], results[b], pipelines[a], pipelines[b])
                )
            start = time.perf_counter_ns()
            cv2.Canny(image, 20, 50, L2gradient=True)
            canny.append((time.perf_counter_ns() - start) / 1000.0)
    canny_us = float(np.median(canny))
    print(f"{source_name(args)}: {len(rows[labels[0]])} frames per variant, cv2.Canny median {canny_us:.0f} us")
    for label, values in rows.items():
        data = np.array(values)
        total, python = float(np.median(data[:, 0])), float(np.median(data[:, 1]))
        print(
            f"  {label:>12}: pipeline {total:.0f} us ({total / canny_us:.3f} x Canny), kernels "
            f"{float(np.median(data[:, 0] - data[:, 1])):.0f} us, Python outside kernel calls {python:.1f} us"
        )
    if args.against:
        print(
            f"  outputs (every PipelineResult field but pipeline_us, the ROI spans after each frame; first pass, "
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
    return 1 if differences else 0
