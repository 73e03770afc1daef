"""The device pipeline against cv2.Canny on the same frames, in the same run, on one thread; its allocations.

Reports the median per-frame time of the whole pipeline (``Pipeline.process``: edges in the region of interest,
contour, split, material points), the median of ``cv2.Canny`` on the full frame, their ratio (and the median of the
per-frame paired ratios), how many frames the pipeline processed in its region of interest, and, in further passes
over the same frames (so that the timed pass is not disturbed):

- Numba runtime (NRT) allocations per frame beyond the one MemInfo per array argument that passing a NumPy array
  to a compiled function costs (``NUMBA_NRT_STATS``; the target, and the measured figure today, is 0);
- Python-level allocation per steady frame (a frame made by one ``steady_frame`` call, once the rope's width,
  polarity, fixed end and length have settled), measured with ``tracemalloc`` after the warm-up: the peak of the
  bytes allocated during the frame above what was allocated before it (the frame's result included), the bytes
  still held once the result is dropped, and the source lines that allocate most (target 0 bytes); once with one
  result record reused (``Pipeline.process(..., out=record)``, as the daemon calls it) and once with a new record
  per frame. The first steady frame makes the call's argument table (again whenever the rope width, Lc0 or the
  thresholds change): it is reported apart, not in the median.

With ``--stages`` it also reports the median time per frame of each stage (on a steady frame all of them are one
``steady_frame`` call; "other" is the rest: Python glue, result records), the time of a frame searched without a
region of interest (the first frame of a fresh pipeline, or after ``reset_tracking``) and of a frame whose predicted
region of interest misses (the rope jumped: the band is widened, then the coarse search runs).

    taskset -c 1 python tools/bench.py device [--frames N] [--frameset DIR] [--config TOML] [--method M] [--stages]

Without ``--frameset`` the frames are synthetic 1024x544 rig frames made on the fly (4 ms exposure at 119 FPS, a
420 px rope of 3 px on noise). A scene that needs its own settings (the ``lab`` presets) is measured with the
``[pipeline]`` table ``ropecam-device setup`` wrote for it (``--config``):

    ropecam simulate lab --out LAB && ropecam-device setup LAB --out lab.toml
    taskset -c 1 python tools/bench.py device --frameset LAB --config lab.toml --frames 60 --stages
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NRT_STATS", "1")  # must be set before numba is imported
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import functools
import json
import time
import tracemalloc
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numba.core.runtime import rtsys

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus, PipelineResult
from ropecam_tools.cli import UsageError
from ropecam_tools.frames import Frame, add_frame_arguments, frames_from, source_name

WARM_UP = 3
"""Frames processed before the timed ones (fixed end, width and length estimates, one-time tables)."""


def count_arrays(value: Any) -> int:
    """The NumPy arrays in a kernel argument: 1 for an array, its members' for a named group (`_kernels.groups`)."""
    if isinstance(value, np.ndarray):
        return 1
    return sum(count_arrays(v) for v in value) if isinstance(value, tuple) else 0


class ArrayArgCounter:
    """Count NumPy array arguments passed to the kernels (each costs one NRT MemInfo, not a real allocation; each
    array of a named group too) and the frames made by one `steady_frame` call."""

    def __init__(self) -> None:
        self.count = 0
        self.steady_calls = 0
        self.originals: dict[str, Any] = {}

    def install(self) -> None:
        for name in dir(K):
            fn = getattr(K, name)
            if hasattr(fn, "py_func") and callable(fn):
                self.originals[name] = fn
                setattr(K, name, self._wrap(name, fn))

    def _wrap(self, name: str, fn: Any) -> Any:
        steady = name == "steady_frame"

        def wrapper(*args: Any) -> Any:
            self.count += count_arrays(args)
            self.steady_calls += steady
            return fn(*args)

        return wrapper

    def uninstall(self) -> None:
        for name, fn in self.originals.items():
            setattr(K, name, fn)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    add_frame_arguments(parser, frames=40)
    parser.add_argument(
        "--config",
        metavar="TOML",
        help="the [pipeline] table of this device.toml, with its plane_file and mask (default: the defaults)",
    )
    parser.add_argument("--method", default="blur_split", choices=("blur_split", "paper", "centerline"))
    parser.add_argument("--stages", action="store_true", help="also time each stage, full-frame and ROI-miss frames")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def nrt_report(config: PipelineConfig, frames: list[Frame]) -> tuple[dict[str, Any], list[int]]:
    """NRT allocations per timed frame (a fresh pipeline, the warm-up frames first) and the indices of the timed
    frames made by one `steady_frame` call."""
    height, width = frames[0][0].shape
    pipeline = new_pipeline(config, (width, height))
    for image, t_ns, exposure_us in frames[:WARM_UP]:
        pipeline.process(image, 0, t_ns, exposure_us)
    counter = ArrayArgCounter()
    counter.install()
    steady = []
    try:
        before = rtsys.get_allocation_stats()
        for index, (image, t_ns, exposure_us) in enumerate(frames[WARM_UP:], start=WARM_UP):
            calls = counter.steady_calls
            pipeline.process(image, index, t_ns, exposure_us)
            if counter.steady_calls > calls:
                steady.append(index)
        after = rtsys.get_allocation_stats()
    finally:
        counter.uninstall()
    n = len(frames) - WARM_UP
    nrt = after.alloc - before.alloc
    return {
        "nrt_allocations_per_frame": nrt / n,
        "array_arguments_per_frame": counter.count / n,
        "nrt_extra_allocations_per_frame": (nrt - counter.count) / n,
        "nrt_leaked": (after.alloc - before.alloc) - (after.free - before.free),
    }, steady


def load_config(args: argparse.Namespace) -> PipelineConfig:
    """The pipeline settings: ``--config``'s [pipeline] table, else the defaults; the method ``--method``."""
    if not args.config:
        return PipelineConfig(method=args.method)
    from ropecam.shared.config import from_mapping, read_toml
    from ropecam.shared.errors import RopecamError

    try:
        table = dict(read_toml(args.config).get("pipeline", {}))
        config = from_mapping(PipelineConfig, table, where=f"{args.config} [pipeline]", method=args.method)
        if config.plane_file is not None:
            _read_plane(config.plane_file)  # read now: its errors named
    except (RopecamError, ValueError) as exc:
        raise UsageError(f"--config {args.config}: {exc}") from exc
    return config


def new_pipeline(config: PipelineConfig, size: tuple[int, int]) -> Pipeline:
    """A pipeline of `config` for frames of `size` (width, height), with the plane calibration of the config's
    ``plane_file`` as `extract` and the daemon use it."""
    plane = None if config.plane_file is None else _read_plane(config.plane_file)
    return Pipeline(config, size, plane=plane)


@functools.cache
def _read_plane(path: str) -> Any:
    from ropecam.shared.plane import read_plane_file

    return read_plane_file(path)


def python_alloc_report(
    config: PipelineConfig, frames: list[Frame], steady: list[int], reuse: bool = True
) -> dict[str, Any]:
    """Python-level allocation (`tracemalloc`) of each timed frame of a fresh pipeline; medians over the frames in
    `steady` (made by one `steady_frame` call), and the lines that allocate most on one steady frame. With `reuse`
    every frame fills one result record (`Pipeline.process`'s `out`), else each gets a new one."""
    height, width = frames[0][0].shape
    pipeline = new_pipeline(config, (width, height))
    record = PipelineResult(0, 0, 0, FrameStatus.BAD_FRAME) if reuse else None
    for image, t_ns, exposure_us in frames[:WARM_UP]:
        pipeline.process(image, 0, t_ns, exposure_us, out=record)
    peak_bytes: dict[int, int] = {}
    held_bytes: dict[int, int] = {}
    sites: list[tuple[str, int, int]] = []
    ignored = (str(Path(__file__).resolve()), tracemalloc.__file__)
    first = steady[0] if steady else len(frames)
    for index in range(WARM_UP, first):  # untraced up to the first steady frame (tracing slows Python down)
        image, t_ns, exposure_us = frames[index]
        pipeline.process(image, index, t_ns, exposure_us, out=record)
    tracemalloc.start()
    try:
        for index in range(first, len(frames)):
            image, t_ns, exposure_us = frames[index]
            snapshot = tracemalloc.take_snapshot() if index == steady[-1] else None
            start = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            result = pipeline.process(image, index, t_ns, exposure_us, out=record)
            peak = tracemalloc.get_traced_memory()[1]
            if snapshot is not None:  # what the last steady frame allocated and still holds (its result included)
                stats = tracemalloc.take_snapshot().compare_to(snapshot, "lineno")
                sites = [
                    (f"{s.traceback[0].filename}:{s.traceback[0].lineno}", s.size_diff, s.count_diff)
                    for s in stats
                    if s.size_diff > 0 and s.traceback[0].filename not in ignored
                ][:8]
            del result
            peak_bytes[index] = peak - start
            held_bytes[index] = tracemalloc.get_traced_memory()[0] - start
    finally:
        tracemalloc.stop()

    # The first steady frame makes the call's argument table (once per rope width, Lc0 and thresholds: a bind,
    # not a steady cost); the last one holds the snapshots: both left out of the figures when others are there.
    measured = steady[1:-1] or steady[:-1] or steady

    def median(values: dict[int, int]) -> float | None:
        return float(np.median([values[i] for i in measured])) if measured else None

    return {
        "steady_frames": len(steady),
        "measured_steady_frames": len(measured),
        "python_alloc_peak_bytes_per_steady_frame": median(peak_bytes),
        "python_alloc_peak_bytes_max": max((peak_bytes[i] for i in measured), default=None),
        "python_alloc_held_bytes_per_steady_frame": median(held_bytes),
        "python_alloc_peak_bytes_first_steady_frame": peak_bytes[steady[0]] if steady else None,
        "python_alloc_sites": [{"line": line, "bytes": size, "blocks": count} for line, size, count in sites],
    }


def run(args: argparse.Namespace) -> int:
    """Time the pipeline and cv2.Canny, count the allocations, print the report."""
    cv2.setNumThreads(1)
    config = load_config(args)
    frames = frames_from(args, args.frames + WARM_UP)
    if len(frames) <= WARM_UP:
        raise UsageError(f"--frameset {args.frameset}: {len(frames)} frames, need more than {WARM_UP}")
    height, width = frames[0][0].shape
    pipeline = new_pipeline(config, (width, height))
    warm_up_us = []
    for image, t_ns, exposure_us in frames[:WARM_UP]:
        warm_up_us.append(pipeline.process(image, 0, t_ns, exposure_us).pipeline_us)
        cv2.Canny(image, config.canny_low, config.canny_high, L2gradient=True)
    ours, canny, statuses = [], [], {}
    for index, (image, t_ns, exposure_us) in enumerate(frames[WARM_UP:], start=WARM_UP):
        t0 = time.perf_counter_ns()
        result = pipeline.process(image, index, t_ns, exposure_us)
        t1 = time.perf_counter_ns()
        cv2.Canny(image, config.canny_low, config.canny_high, L2gradient=True)
        t2 = time.perf_counter_ns()
        ours.append((t1 - t0) / 1000)
        canny.append((t2 - t1) / 1000)
        statuses[result.status.name] = statuses.get(result.status.name, 0) + 1
    nrt, steady = nrt_report(config, frames)
    report = {
        "frames": len(ours),
        "source": source_name(args),
        "config": args.config,
        "image_size": [width, height],
        "method": args.method,
        "pipeline_median_us": float(np.median(ours)),
        "canny_median_us": float(np.median(canny)),
        "ratio": float(np.median(ours) / np.median(canny)),
        # Each frame's pipeline time over the cv2.Canny time measured right after it on the same frame: paired,
        # so a slow minute of a shared machine weighs on both sides of each ratio.
        "paired_ratio_median": float(np.median(np.array(ours) / np.array(canny))),
        "roi_frames": pipeline.frames_roi,
        "coarse_frames": pipeline.frames_coarse,
        "full_frames": pipeline.frames_full,
        "roi_retries": pipeline.roi_retries,
        "first_frame_us": warm_up_us[0],
        "statuses": statuses,
        **nrt,
        **python_alloc_report(config, frames, steady),
        "new_record": python_alloc_report(config, frames, steady, reuse=False),
    }
    if args.stages:
        report.update(stage_report(config, frames, (width, height)))
    if args.json:
        print(json.dumps(report))
        return 0
    print(f"{report['source']}: {len(ours)} frames of {width}x{height} ({args.method}), statuses {statuses}")
    print(
        f"pipeline median {report['pipeline_median_us']:.0f} us/frame "
        f"({pipeline.frames_roi} in the ROI, {pipeline.roi_retries} ROI widenings, {pipeline.frames_coarse} "
        f"coarse searches, {pipeline.frames_full} whole-frame searches, warm-up frames included)"
    )
    print(f"first frame of the process (one-time tables built): {warm_up_us[0]:.0f} us")
    print(f"cv2.Canny median {report['canny_median_us']:.0f} us/frame (1 thread)")
    print(
        f"ratio pipeline / Canny = {report['ratio']:.3f} (median of the per-frame paired ratios "
        f"{report['paired_ratio_median']:.3f})"
    )
    print(
        f"NRT allocations per frame: {report['nrt_extra_allocations_per_frame']:.2f} beyond one MemInfo per array "
        f"argument ({report['array_arguments_per_frame']:.0f} array arguments per frame); leaked {report['nrt_leaked']}"
    )
    print_python_alloc(report)
    if args.stages:
        print_stages(report)
    return 0


def print_python_alloc(report: dict[str, Any]) -> None:
    """Print the `python_alloc_report` part of `report`."""
    if not report["steady_frames"]:
        print("Python allocation per steady frame: no steady frame (give more --frames: steady from about frame 16)")
        return
    for how, part in (
        ("one result record reused (out=)", report),
        ("a new result record per frame", report["new_record"]),
    ):
        print(
            f"Python allocation per steady frame, {how} (tracemalloc, {part['measured_steady_frames']} of "
            f"{part['steady_frames']} steady frames): peak {part['python_alloc_peak_bytes_per_steady_frame']:.0f} "
            f"bytes above the frame's start (median; max {part['python_alloc_peak_bytes_max']}), "
            f"{part['python_alloc_held_bytes_per_steady_frame']:.0f} bytes held once the result is dropped; target 0 "
            f"(the first steady frame, which makes the call's argument table: "
            f"{part['python_alloc_peak_bytes_first_steady_frame']} bytes)"
        )
        for site in part["python_alloc_sites"]:
            print(f"  {site['bytes']:7d} bytes in {site['blocks']:3d} blocks  {site['line']}")


_STAGES = (
    ("edges+contour", "tracer", "detect_and_trace"),  # one kernel call (the pipeline's; `bench.py bands` replays it)
    ("edges", "edges", "detect"),  # called on their own by other paths only
    ("contour", "tracer", "trace"),
    ("roi_contacts", "tracer", "roi_contacts"),
    ("border_contacts", "tracer", "border_contacts"),
    ("split", "splitter", "split"),
    ("fixed_end", "traits", "find_fixed_end"),
    ("material_points", "tracker", "track_shapes"),
    ("lengths", "tracker", "length"),
)


def _timed_stages(pipeline: Pipeline, totals: dict[str, float]) -> None:
    """Wrap the stage methods of `pipeline` so that their time (us) accumulates in `totals`."""
    for label, owner, name in _STAGES:
        target = pipeline if owner is None else getattr(pipeline, owner)
        method = getattr(target, name)

        def timed(*a: Any, _method: Any = method, _label: str = label, **k: Any) -> Any:
            t0 = time.perf_counter_ns()
            try:
                return _method(*a, **k)
            finally:
                totals[_label] = totals.get(_label, 0.0) + (time.perf_counter_ns() - t0) / 1000

        setattr(target, name, timed)
    for label, name in _KERNEL_STAGES:
        kernel = getattr(K, name)

        def timed_kernel(*a: Any, _kernel: Any = kernel, _label: str = label) -> Any:
            t0 = time.perf_counter_ns()
            try:
                return _kernel(*a)
            finally:
                totals[_label] = totals.get(_label, 0.0) + (time.perf_counter_ns() - t0) / 1000

        setattr(K, name, timed_kernel)


_KERNEL_STAGES = (("steady frame", "steady_frame"), ("band", "band_stage"), ("order+material", "track_frame"))
"""Stages that are one kernel call made by the pipeline itself (timed by wrapping the kernel, dispatch included).
A steady frame (the rope's width, polarity, fixed end and Lc0 settled) is one `steady_frame` call: its band, edges,
contour, split, order and material points are all in "steady frame"; the other stages show the frames before."""


_SETTLE_FRAMES = 16
"""Frames after which the pipeline has stopped measuring its slow state (width, polarity, fixed end, Lc0)."""


def stage_report(
    config: PipelineConfig, frames: list[tuple[np.ndarray, int, float]], size: tuple[int, int]
) -> dict[str, Any]:
    """Median per-frame time of each stage; times of frames searched without a band and of frames whose band
    misses (both after the first `_SETTLE_FRAMES` frames, when the pipeline measures only what changes)."""
    pipeline = new_pipeline(config, size)
    for index, (image, t_ns, exposure_us) in enumerate(frames[:3]):
        pipeline.process(image, index, t_ns, exposure_us)
    per_frame: list[dict[str, float]] = []
    totals: dict[str, float] = {}
    originals = {name: getattr(K, name) for _, name in _KERNEL_STAGES}
    _timed_stages(pipeline, totals)
    try:
        for index, (image, t_ns, exposure_us) in enumerate(frames[3:], start=3):
            totals.clear()
            t0 = time.perf_counter_ns()
            pipeline.process(image, index, t_ns, exposure_us)
            total = (time.perf_counter_ns() - t0) / 1000
            row = dict(totals)
            row["other"] = total - sum(totals.values())
            row["total"] = total
            per_frame.append(row)
    finally:
        for name, kernel in originals.items():
            setattr(K, name, kernel)
    labels = [label for label, _, _ in _STAGES] + [label for label, _ in _KERNEL_STAGES] + ["other", "total"]
    stages = {label: float(np.median([row.get(label, 0.0) for row in per_frame])) for label in labels}
    # A frame searched without an ROI: the pipeline knows the rope (width, fixed end) but not where it is.
    searched, searched_paths = [], []
    pipeline = new_pipeline(config, size)
    settled = min(_SETTLE_FRAMES, len(frames) // 2)  # width, polarity and fixed end are measured until then
    for index, (image, t_ns, exposure_us) in enumerate(frames):
        if index >= settled:
            pipeline.reset_tracking()
            before = (pipeline.frames_coarse, pipeline.frames_full)
        result = pipeline.process(image, index, t_ns, exposure_us)
        if index >= settled:
            searched.append(result.pipeline_us)
            searched_paths.append("coarse" if pipeline.frames_coarse > before[0] else "full")
    # A frame whose ROI misses: the rope jumped (a frame 12 periods later arrives one period after the last).
    missed, missed_paths = [], []
    period_ns = int(np.median(np.diff([t for _, t, _ in frames]))) if len(frames) > 1 else 8_400_000
    for start in range(settled, len(frames) - 12, 3):  # none with fewer than settled + 13 frames
        pipeline = new_pipeline(config, size)
        for index in range(start):
            image, t_ns, exposure_us = frames[index]
            pipeline.process(image, index, t_ns, exposure_us)
        image, _, exposure_us = frames[start + 12]
        last_t_ns = frames[start - 1][1]
        before = (pipeline.frames_roi, pipeline.frames_coarse, pipeline.roi_retries)
        result = pipeline.process(image, start + 12, last_t_ns + period_ns, exposure_us)
        missed.append(result.pipeline_us)
        if pipeline.frames_roi > before[0]:
            missed_paths.append(f"roi+{pipeline.roi_retries - before[2]}")
        else:
            missed_paths.append("coarse" if pipeline.frames_coarse > before[1] else "full")
    first = new_pipeline(config, size)
    image, t_ns, exposure_us = frames[0]
    first_us = first.process(image, 0, t_ns, exposure_us).pipeline_us
    return {
        "stages_median_us": stages,
        "searched_frame_median_us": float(np.median(searched)),
        "searched_frame_max_us": float(np.max(searched)),
        "searched_paths": {p: searched_paths.count(p) for p in sorted(set(searched_paths))},
        "roi_miss_frame_median_us": float(np.median(missed)) if missed else None,
        "roi_miss_frame_max_us": float(np.max(missed)) if missed else None,
        "roi_miss_paths": {p: missed_paths.count(p) for p in sorted(set(missed_paths))},
        "first_frame_fresh_pipeline_us": first_us,
    }


def print_stages(report: dict[str, Any]) -> None:
    """Print the `stage_report` part of `report`."""
    stages = report["stages_median_us"]
    shown = {k: v for k, v in stages.items() if v >= 0.5}  # a stage of the first frames only has a median of 0
    print("stages (median us/frame): " + ", ".join(f"{k} {v:.0f}" for k, v in shown.items()))
    print(
        f"frame searched without ROI: median {report['searched_frame_median_us']:.0f} us, "
        f"max {report['searched_frame_max_us']:.0f} us ({report['searched_paths']})"
    )
    if report["roi_miss_frame_median_us"] is not None:
        print(
            f"frame whose ROI misses (rope jumped 12 frames): median {report['roi_miss_frame_median_us']:.0f} us, "
            f"max {report['roi_miss_frame_max_us']:.0f} us ({report['roi_miss_paths']})"
        )
    print(f"first frame of a fresh pipeline (one-time tables cached): {report['first_frame_fresh_pipeline_us']:.0f} us")
