"""Benchmark the device pipeline against cv2.Canny on the same 1024x544 rig frames, in the same run, on one thread.

Reports the median per-frame time of the whole pipeline (``Pipeline.process``: edges in the region of interest,
contour, split, material points), the median of ``cv2.Canny`` on the full frame, their ratio, how many frames the
pipeline processed in its region of interest, and the Numba (NRT) allocations per frame beyond the one MemInfo per
array argument that passing a NumPy array to a compiled function costs.

    python tools/bench_device.py [--frames N] [--frameset PATH] [--method M] [--json]
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
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    frames = frameset_frames(args.frameset, args.frames + 3) if args.frameset else rig_frames(args.frames + 3)
    height, width = frames[0][0].shape
    config = PipelineConfig(method=args.method)
    pipeline = Pipeline(config, (width, height))
    for image, t_ns, exposure_us in frames[:3]:  # warm-up: fixed end, width and Lc0 estimates, caches
        pipeline.process(image, 0, t_ns, exposure_us)
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
        "roi_frames": pipeline.frames_roi,
        "full_frames": pipeline.frames_full,
        "statuses": statuses,
        "nrt_allocations_per_frame": nrt / n,
        "array_arguments_per_frame": counter.count / n,
        "nrt_extra_allocations_per_frame": (nrt - counter.count) / n,
        "nrt_leaked": (after.alloc - before.alloc) - (after.free - before.free),
    }
    if args.json:
        print(json.dumps(report))
    else:
        print(f"frames {n} of {width}x{height} ({args.method}), statuses {statuses}")
        print(
            f"pipeline median {report['pipeline_median_us']:.0f} us/frame "
            f"({pipeline.frames_roi} ROI frames, {pipeline.frames_full} full frames)"
        )
        print(f"cv2.Canny median {report['canny_median_us']:.0f} us/frame (1 thread)")
        print(f"ratio pipeline / Canny = {report['ratio']:.3f}")
        print(
            f"NRT allocations per frame: {report['nrt_extra_allocations_per_frame']:.2f} beyond the "
            f"{report['array_arguments_per_frame']:.0f} array-argument MemInfos; leaked {report['nrt_leaked']}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
