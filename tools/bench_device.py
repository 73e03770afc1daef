"""Benchmark the device pipeline against cv2.Canny on the same 1024x544 rig frames, in the same run, on one thread.

Reports the median per-frame time of the whole pipeline (``Pipeline.process``: edges in the region of interest,
contour, split, material points), the median of ``cv2.Canny`` on the full frame, their ratio, how many frames the
pipeline processed in its region of interest, and the Numba (NRT) allocations per frame beyond the one MemInfo per
array argument that passing a NumPy array to a compiled function costs.

With ``--stages`` it also reports (in further passes over the same frames, so the main figures are not disturbed):
the median time per frame of each stage (edges, contour, split, ordering, material points, ROI building, or on a
steady frame all of them in one `steady_frame` call; "other" is the rest: Python glue, result records), the time
of a frame searched without a region of interest (the first frame of a fresh pipeline, or after
``reset_tracking``: coarse search, then the band around the rope) and of a frame whose predicted region of
interest misses (the rope jumped: the band is widened, then the coarse search runs), each as a median over several
frames.

    python tools/bench_device.py [--frames N] [--frameset PATH] [--method M] [--stages] [--json]
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NRT_STATS", "1")  # must be set before numba is imported
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import json
import sys
import time
from typing import Any

import cv2
import numpy as np
from numba.core.runtime import rtsys

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline


def rig_frames(count: int) -> list[tuple[np.ndarray, int, float]]:
    """Synthetic 1024x544 frames of the rig: 4 ms exposure at 119 FPS, a 420 px rope of 3 px."""
    rope = SyntheticRope(
        width=1024, height=544, fixed_uv=(512.3, 40.6), length_px=420.0, diameter_px=3.0, amplitude_rad=0.5,
        period_s=1.4, fps=119.0, exposure_us=4000, noise_dn=2.0,
    )  # fmt: skip
    return [(f.image, f.t_ns, float(f.exposure_us)) for f in rope.frames(count, start=5)]


def frameset_frames(path: str, count: int) -> list[tuple[np.ndarray, int, float]]:
    """The first `count` frames of a frame set."""
    from ropecam.device.capture.frameset import FrameSet

    frameset = FrameSet(path)
    out = []
    for position in range(min(count, len(frameset))):
        record = frameset.records[position]
        out.append((frameset.read(position), record.t_ns, float(record.exposure_us)))
    return out


class ArrayArgCounter:
    """Count NumPy array arguments passed to the kernels (each costs one NRT MemInfo, not a real allocation)."""

    def __init__(self) -> None:
        self.count = 0
        self.originals: dict[str, Any] = {}

    def install(self) -> None:
        for name in dir(K):
            fn = getattr(K, name)
            if hasattr(fn, "py_func") and callable(fn):
                self.originals[name] = fn
                setattr(K, name, self._wrap(fn))

    def _wrap(self, fn: Any) -> Any:
        def wrapper(*args: Any) -> Any:
            self.count += sum(isinstance(a, np.ndarray) for a in args)
            return fn(*args)

        return wrapper

    def uninstall(self) -> None:
        for name, fn in self.originals.items():
            setattr(K, name, fn)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=40, help="frames to time (default 40)")
    parser.add_argument("--frameset", help="time these frames instead of the synthetic rig frames")
    parser.add_argument("--method", default="blur_split", choices=("blur_split", "paper", "centerline"))
    parser.add_argument("--stages", action="store_true", help="also time each stage, full-frame and ROI-miss frames")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    frames = frameset_frames(args.frameset, args.frames + 3) if args.frameset else rig_frames(args.frames + 3)
    height, width = frames[0][0].shape
    config = PipelineConfig(method=args.method)
    pipeline = Pipeline(config, (width, height))
    warm_up_us = []
    for image, t_ns, exposure_us in frames[:3]:  # warm-up: fixed end, width and Lc0 estimates, caches
        warm_up_us.append(pipeline.process(image, 0, t_ns, exposure_us).pipeline_us)
        cv2.Canny(image, config.canny_low, config.canny_high, L2gradient=True)
    ours, canny, statuses = [], [], {}
    timed = frames[3:]
    for index, (image, t_ns, exposure_us) in enumerate(timed, start=3):
        t0 = time.perf_counter_ns()
        result = pipeline.process(image, index, t_ns, exposure_us)
        t1 = time.perf_counter_ns()
        cv2.Canny(image, config.canny_low, config.canny_high, L2gradient=True)
        t2 = time.perf_counter_ns()
        ours.append((t1 - t0) / 1000)
        canny.append((t2 - t1) / 1000)
        statuses[result.status.name] = statuses.get(result.status.name, 0) + 1
    # Allocations in a second pass over the same frames (the argument counter's wrappers cost time).
    allocation_pipeline = Pipeline(config, (width, height))
    for image, t_ns, exposure_us in frames[:3]:
        allocation_pipeline.process(image, 0, t_ns, exposure_us)
    counter = ArrayArgCounter()
    counter.install()
    before = rtsys.get_allocation_stats()
    for index, (image, t_ns, exposure_us) in enumerate(timed, start=3):
        allocation_pipeline.process(image, index, t_ns, exposure_us)
    after = rtsys.get_allocation_stats()
    counter.uninstall()
    n = len(ours)
    nrt = after.alloc - before.alloc
    report = {
        "frames": n,
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
        "nrt_allocations_per_frame": nrt / n,
        "array_arguments_per_frame": counter.count / n,
        "nrt_extra_allocations_per_frame": (nrt - counter.count) / n,
        "nrt_leaked": (after.alloc - before.alloc) - (after.free - before.free),
    }
    if args.stages:
        report.update(stage_report(config, frames, (width, height)))
    if args.json:
        print(json.dumps(report))
    else:
        print(f"frames {n} of {width}x{height} ({args.method}), statuses {statuses}")
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
            f"NRT allocations per frame: {report['nrt_extra_allocations_per_frame']:.2f} beyond the "
            f"{report['array_arguments_per_frame']:.0f} array-argument MemInfos; leaked {report['nrt_leaked']}"
        )
        if args.stages:
            print_stages(report)
    return 0


_STAGES = (
    ("edges+contour", "tracer", "detect_and_trace"),  # one kernel call (the pipeline's; bench_roi_kernels splits it)
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
    pipeline = Pipeline(config, size)
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
    pipeline = Pipeline(config, size)
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
        pipeline = Pipeline(config, size)
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
    first = Pipeline(config, size)
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


if __name__ == "__main__":
    sys.exit(main())
