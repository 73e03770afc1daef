"""The edge kernel (`detect_edges`) of this tree against another commit's, on the bands of a real pipeline run.

A pipeline of this tree runs once over the frames and records the frame and row spans of every edge-stage call;
both kernels (the other commit exported as ``ropecam_ref``, as `bench_glue.py` does) then run on exactly those
bands, with the same buffers (so that only the code differs, not where the planes lie), ``cv2.Canny`` on the
whole frame before each call (as `bench_device.py`: it evicts L2 as a frame's other work does).

Each timed call is the first on its band: the variants take turns over the bands (pass p gives band i to variant
``(i + p) % 3``). Timing a second variant on a band just processed by another favours it: the first call fetches
the band's new plane lines from memory, the next ones find them in L3 (an identical kernel measured 9 us faster,
0.90, when always run second). The third variant is the reference again: its ratio is the noise floor.

    taskset -c 1 python tools/bench_edges_ab.py [--frameset /work/eval/rig] [--against main] [--passes 5]

Prints, per variant, the median over bands of the fastest call, the median of the per-band ratios and differences
against the reference; first checks that both kernels give the same edge count, edge list and edge map inside
the spans on every band.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import importlib
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_device import frameset_frames
from bench_glue import export_ref
from bench_roi_kernels import record

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.edges import EdgeDetector


def _inside(lo: np.ndarray, hi: np.ndarray, width: int) -> np.ndarray:
    """Boolean mask of the pixels inside the row spans."""
    cols = np.arange(width)
    return (cols[None, :] >= lo[:, None]) & (cols[None, :] <= hi[:, None])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frameset", default="/work/eval/rig", help="frame set folder (default: %(default)s)")
    parser.add_argument("--frames", type=int, default=60, help="frames of the pipeline run (default: %(default)s)")
    parser.add_argument("--passes", type=int, default=5, help="timed calls per band and variant")
    parser.add_argument("--against", default="main", metavar="REF", help="the other commit (default: %(default)s)")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    frames = frameset_frames(args.frameset, args.frames)
    calls, _ = record(frames, PipelineConfig())
    if not calls:
        parser.error(f"no edge-stage calls recorded on {args.frameset}")
    sys.path.insert(0, str(export_ref(args.against)))
    print(f"importing {args.against} as ropecam_ref (its kernels compile once)...", flush=True)
    ref = importlib.import_module("ropecam_ref.device.pipeline._kernels")
    height, width = calls[0][0].shape
    config = PipelineConfig()
    other = EdgeDetector(height, width, config.smooth_sigma_px, config.canny_low, config.canny_high)

    def run(kernels: Any, e: EdgeDetector, call: tuple[np.ndarray, np.ndarray, np.ndarray]) -> int:
        frame, lo, hi = call
        return int(
            kernels.detect_edges(
                frame, e.weights_ro, lo, hi, e.low, e.high, e.work_spans, e.tmp, e.smooth, e.gx, e.gy, e.mag,
                e.edges, e.stack,
            )
        )  # fmt: skip

    shared = EdgeDetector(height, width, config.smooth_sigma_px, config.canny_low, config.canny_high)
    for call in calls:  # the same outputs, band by band
        count, count_ref = run(K, shared, call), run(ref, other, call)
        inside = _inside(call[1], call[2], width)
        same = count == count_ref and np.array_equal(shared.stack[:count], other.stack[:count])
        if not same or not np.array_equal(shared.edges[inside], other.edges[inside]):
            print("outputs differ between the two kernels")
            return 1
    variants = {"this tree": K, args.against: ref, f"{args.against} (again)": ref}
    names = list(variants)
    best = {name: np.full(len(calls), np.inf) for name in names}
    for p in range(args.passes * len(names)):
        for i, call in enumerate(calls):
            name = names[(i + p) % len(names)]
            cv2.Canny(call[0], 20, 50, L2gradient=True)
            t0 = time.perf_counter_ns()
            run(variants[name], shared, call)
            best[name][i] = min(best[name][i], (time.perf_counter_ns() - t0) / 1000)
    rows = [int(np.count_nonzero(hi >= lo)) for _, lo, hi in calls]
    print(f"{args.frameset}: {len(calls)} bands (median {int(np.median(rows))} rows), outputs identical")
    base = best[args.against]
    for name in names:
        ratio = float(np.median(best[name] / base))
        diff = float(np.median(best[name] - base))
        print(
            f"  {name:>24}: detect_edges {np.median(best[name]):7.1f} us, ratio {ratio:.3f}, difference {diff:+.1f} us"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
