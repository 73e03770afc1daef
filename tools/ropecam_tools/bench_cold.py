"""Where a steady frame's extra time after cv2.Canny goes: the kernel call, its frame check, the Python glue.

`bench.py device` times the pipeline with ``cv2.Canny`` between frames (the acceptance condition): Canny's ~5 MB
evict the pipeline's buffers, code and Python objects from the core's caches, and a frame then takes longer than
one run right after the last (`--stages`, "warm"). This tool gives each frame one of these conditions before it,
in turn (frame i of pass p gets condition ``(i + p) mod 4``; a fresh pipeline per pass, frames before `--settle`
not counted):

- ``canny``: ``cv2.Canny`` on the frame, as `bench.py device`;
- ``canny+planes``: ``cv2.Canny``, then the cache lines of the last band's rows of the four float planes (smoothed,
  gx, gy, magnitude; its spans 3 columns left and 10 right, one read per line) read back: what band-local planes
  could at most save of the cold frame, on the plane side;
- ``memset``: an 8 MiB buffer written instead of ``cv2.Canny`` (`timing.evict`: the caches evicted by plain
  stores; whether the extra time is eviction, or Canny's branch history);
- ``warm``: nothing between the last frame and this one.

For each: median per frame of the whole `Pipeline.process`, of the `steady_frame` call (the kernel with its
dispatch), of `take_frame` (the frame's check), and of the rest (the Python glue, frame by frame). The two wrapped
calls cost ~0.1-0.3 us each (`timing.KernelTimer`), in every condition. Only frames on which `steady_frame` ran
are counted; where it stopped early (after the contour, say) the step-by-step kernels that finish the frame land in
the rest. The pipeline runs with the default `PipelineConfig` (the rig's): time a set that needs its setup's config
(``lab``) with ``bench.py device --config``.

    taskset -c 1 python tools/bench.py cold [--frameset DIR] [--frames N] [--passes P] [--json]
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import json
import time

import cv2
import numpy as np

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam_tools.cli import UsageError, positive_int
from ropecam_tools.frames import add_frame_arguments, frames_from, source_name
from ropecam_tools.timing import KernelTimer, evict

CONDITIONS = ("canny", "canny+planes", "memset", "warm")
"""What runs between the last frame and the timed one (module docstring)."""
_LINE_FLOATS = 16  # float32 per 64-byte cache line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    add_frame_arguments(parser, frames=60)
    parser.add_argument("--passes", type=positive_int, default=24, help="passes over the frames (default: 24)")
    parser.add_argument(
        "--settle", type=positive_int, default=15, help="frames of each pass not counted (default: %(default)s)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def plane_line_index(lo: np.ndarray, hi: np.ndarray, width: int) -> np.ndarray:
    """Flat indices, one per cache line, of the band's rows (spans `lo`/`hi`, empty where ``hi < lo``) grown by 3
    columns left and 10 right, clipped to the image."""
    rows = np.flatnonzero(hi >= lo)
    first = np.maximum(lo[rows].astype(np.int64) - 3, 0)
    last = np.minimum(hi[rows].astype(np.int64) + 10, width - 1)
    counts = (last - first) // _LINE_FLOATS + 1
    starts = np.repeat(rows * width + first - (np.cumsum(counts) - counts) * _LINE_FLOATS, counts)
    return starts + np.arange(int(counts.sum())) * _LINE_FLOATS


def run(args: argparse.Namespace) -> int:
    """Time the conditions frame by frame, print the medians."""
    cv2.setNumThreads(1)
    frames = frames_from(args)
    if len(frames) <= args.settle:
        raise UsageError(f"--frames {args.frames}: {len(frames)} frames, need more than --settle {args.settle}")
    height, width = frames[0][0].shape
    config = PipelineConfig()
    times: dict[str, dict[str, list[float]]] = {
        c: {"total": [], "steady": [], "take": [], "rest": []} for c in CONDITIONS
    }
    with KernelTimer(K, ("steady_frame", "take_frame")) as timer:
        for p in range(args.passes):
            pipeline = Pipeline(config, (width, height))
            e = pipeline.edges
            planes = [plane.reshape(-1) for plane in (e.smooth, e.gx, e.gy, e.mag)]
            record = None
            for index, (image, t_ns, exposure_us) in enumerate(frames):
                condition = CONDITIONS[(index + p) % len(CONDITIONS)]
                if condition.startswith("canny"):
                    cv2.Canny(image, config.canny_low, config.canny_high, L2gradient=True)
                if condition == "canny+planes":
                    lines = plane_line_index(pipeline.locator.lo_ro, pipeline.locator.hi_ro, width)
                    for plane in planes:
                        np.take(plane, lines).sum()
                elif condition == "memset":
                    evict()
                timer.clear()
                t0 = time.perf_counter_ns()
                record = pipeline.process(image, index, t_ns, exposure_us, out=record)
                total = time.perf_counter_ns() - t0
                steady_ns, take_ns = timer.spent.get("steady_frame"), timer.spent.get("take_frame", 0)
                if index < args.settle or steady_ns is None:  # not a steady frame
                    continue
                row = times[condition]
                row["total"].append(total / 1000)
                row["steady"].append(steady_ns / 1000)
                row["take"].append(take_ns / 1000)
                row["rest"].append((total - steady_ns - take_ns) / 1000)
    report = {
        "source": source_name(args),
        "frames": len(frames),
        "passes": args.passes,
        "conditions": {
            c: {"frames": len(times[c]["total"]), **{k: float(np.median(v)) for k, v in times[c].items() if v}}
            for c in CONDITIONS
        },
    }
    if args.json:
        print(json.dumps(report))
        return 0
    print(f"{report['source']}: {len(frames)} frames, {args.passes} passes, steady frames only (median us per frame)")
    print(f"  {'condition':<14} {'frames':>6} {'total':>8} {'steady_frame':>13} {'take_frame':>11} {'Python glue':>12}")
    for c, row in report["conditions"].items():
        if row["frames"]:
            print(
                f"  {c:<14} {row['frames']:>6} {row['total']:>8.1f} {row['steady']:>13.1f} {row['take']:>11.1f} "
                f"{row['rest']:>12.1f}"
            )
    return 0
