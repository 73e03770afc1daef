"""Micro-benchmark the kernels of the edge and contour stages on the real regions of interest of a frame set.

A pipeline runs over the frames once and records, for every call of the edge stage, the frame and the row spans
it got, and for every band built, the arguments of `band_stage`. Each kernel is then re-run on exactly
those inputs (one thread) and its median time per call is printed, with the size of the spans (rows, pixels), so
that a change to one pass can be measured on its own:

    taskset -c 1 python tools/bench_roi_kernels.py [--frameset /work/eval/rig] [--frames 40] [--repeat 5] \\
        [--cold] [--passes]

Kernels timed: ``detect_edges`` (the whole edge stage), ``keep_largest_listed``, ``trace_contour``,
``refine_subpixel``, ``count_roi_contacts``, ``trace_closed``, ``trace_rope`` (what `ContourTracer.trace` calls:
all of them in one kernel) and ``band_stage`` (the band); "contour stage" is the sum of the first three. With
``--passes``, each pass of `detect_edges` is also timed on its own (the same kernel calls in the same order, from
Python: each includes its ~1 us dispatch; with ``--cold`` the caches are evicted once before the first pass, as in
the pipeline, where the passes warm each other's data).
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import sys
import time
from typing import Any

import numpy as np

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import ro
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline


def record(frames: list[tuple[np.ndarray, int, float]], config: PipelineConfig) -> tuple[list[Any], list[Any]]:
    """Run a pipeline over `frames`; return the (frame, lo, hi) of each edge-stage call after the first three
    frames and the argument tuples of each `band_stage` call (the band: its measured error, the prediction and
    `spans_around_chain`)."""
    height, width = frames[0][0].shape
    pipeline = Pipeline(config, (width, height))
    pipeline.one_call = False  # the kernels one by one: a steady frame's one call (`steady_frame`) would hide them
    calls: list[Any] = []
    bands: list[Any] = []
    detect = pipeline.tracer.detect_and_trace  # the edge and contour stages in one call
    band = K.band_stage
    recording = [False]

    def recorded_detect(detector: Any, frame: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> int:
        if recording[0]:
            calls.append((frame, lo.copy(), hi.copy()))
        return detect(detector, frame, lo, hi)

    def recorded_band(*args: Any) -> Any:
        if recording[0]:
            copied = tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args)
            bands.append(tuple(ro(a) if k == 0 else a for k, a in enumerate(copied)))  # the contour: read-only
        return band(*args)

    pipeline.tracer.detect_and_trace = recorded_detect  # type: ignore[method-assign]
    K.band_stage = recorded_band
    try:
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            recording[0] = index >= 3
            pipeline.process(image, index, t_ns, exposure_us)
    finally:
        K.band_stage = band
    return calls, bands


_EVICT = np.zeros(8 << 20, np.uint8)
"""Written before each timed call with ``--cold`` (8 MiB: more than L2, as the rest of a frame's work)."""


def median_us(fn: Any, inputs: list[Any], repeat: int, cold: bool = False) -> float:
    """Median over `inputs` of the best of `repeat` timed calls ``fn(item)`` (us); with `cold`, the caches are
    filled with other data before each call."""
    per_item = []
    for item in inputs:
        best = float("inf")
        for _ in range(repeat):
            if cold:
                np.add(_EVICT, 1, out=_EVICT)
            t0 = time.perf_counter_ns()
            fn(item)
            best = min(best, (time.perf_counter_ns() - t0) / 1000)
        per_item.append(best)
    return float(np.median(per_item))


def edge_passes(e: Any, frame: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> list[tuple[str, float]]:
    """Run the passes of `detect_edges` one kernel call at a time (the same calls, in the same order) and return
    each pass's time (us), including its dispatch (~1 us)."""
    height, width = frame.shape
    rows = np.flatnonzero(np.minimum(hi, width - 1) >= np.maximum(lo, 0))
    r_first, r_last = int(rows[0]), int(rows[-1])
    radius = e.weights.shape[0] // 2
    sob_lo, sob_hi, gau_lo, gau_hi = e.work_spans
    sob_begin, sob_end = max(r_first - 1, 0), min(r_last + 1, height - 1)
    gau_begin, gau_end = max(r_first - 2, 0), min(r_last + 2, height - 1)
    times: list[tuple[str, float]] = []
    t0 = time.perf_counter_ns()
    K.grow_spans_once(lo, hi, r_first, r_last, width, gau_lo, gau_hi)
    K.grow_spans_inplace(sob_begin, sob_end, 1, width, gau_lo, gau_hi)
    hor_begin, hor_end = gau_begin, gau_end
    sob_lo[hor_begin : hor_end + 1] = gau_lo[hor_begin : hor_end + 1]
    sob_hi[hor_begin : hor_end + 1] = gau_hi[hor_begin : hor_end + 1]
    for _ in range(radius):
        K.grow_spans_inplace(hor_begin, hor_end, 0, width, sob_lo, sob_hi)
        hor_begin, hor_end = max(hor_begin - 1, 0), min(hor_end + 1, height - 1)
    t1 = time.perf_counter_ns()
    times.append(("  spans (grow_spans_*)", (t1 - t0) / 1000))
    args = (frame, e.weights_ro, sob_lo, sob_hi, gau_lo, gau_hi, gau_begin, gau_end, e.tmp, e.smooth)
    if not K.smooth_ring(*args):
        K.smooth_rows(frame, e.weights_ro, sob_lo, sob_hi, hor_begin, hor_end, e.tmp)
        K.smooth_columns(e.tmp, e.weights_ro, gau_lo, gau_hi, gau_begin, gau_end, e.smooth)
    t2 = time.perf_counter_ns()
    times.append(("  smoothing (smooth_ring)", (t2 - t1) / 1000))
    K.grow_spans_once(lo, hi, r_first, r_last, width, sob_lo, sob_hi)
    t3 = time.perf_counter_ns()
    planes = (e.gx, e.gy, e.mag, e.edges, e.stack)
    top = K.sobel_suppress(e.smooth, lo, hi, sob_lo, sob_hi, r_first, r_last, e.low, e.high, *planes)
    if top < 0:
        K.sobel_rows(e.smooth, sob_lo, sob_hi, sob_begin, sob_end, e.gx, e.gy, e.mag)
        top = K.suppress_rows(
            e.mag, e.gx, e.gy, lo, hi, sob_lo, sob_hi, r_first, r_last, e.low, e.high, e.edges, e.stack
        )
    t4 = time.perf_counter_ns()
    times.append(("  Sobel, NMS, seeds (sobel_suppress)", (t4 - t3) / 1000))
    K.grow_edges(lo, hi, top, e.edges, e.stack)
    t5 = time.perf_counter_ns()
    times.append(("  hysteresis (grow_edges)", (t5 - t4) / 1000))
    K.finish_edges(lo, hi, r_first, r_last, e.edges)
    t6 = time.perf_counter_ns()
    times.append(("  relabelling (finish_edges)", (t6 - t5) / 1000))
    return times


def pass_times(e: Any, inputs: list[Any], repeat: int, cold: bool) -> dict[str, float]:
    """Median over `inputs` of the best of `repeat` runs of each pass of `edge_passes` (us)."""
    per_pass: dict[str, list[float]] = {}
    for frame, lo, hi in inputs:
        best: dict[str, float] = {}
        for _ in range(repeat):
            if cold:
                np.add(_EVICT, 1, out=_EVICT)
            for name, value in edge_passes(e, frame, lo, hi):
                best[name] = min(best.get(name, float("inf")), value)
        for name, value in best.items():
            per_pass.setdefault(name, []).append(value)
    return {name: float(np.median(values)) for name, values in per_pass.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frameset", help="frame set (default: the synthetic rig frames of bench_device)")
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--repeat", type=int, default=5, help="calls per input, the fastest is kept (default 5)")
    parser.add_argument("--cold", action="store_true", help="evict the caches before each timed call")
    parser.add_argument(
        "--passes", action="store_true", help="also time each pass of detect_edges on its own (in order, one eviction)"
    )
    args = parser.parse_args(argv)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from bench_device import frameset_frames, rig_frames

    frames = frameset_frames(args.frameset, args.frames + 3) if args.frameset else rig_frames(args.frames + 3)
    config = PipelineConfig()
    calls, bands = record(frames, config)
    height, width = frames[0][0].shape
    pipeline = Pipeline(config, (width, height))
    e = pipeline.edges
    t = pipeline.tracer
    rows = [int(np.count_nonzero(hi >= lo)) for _, lo, hi in calls]
    pixels = [int(np.sum(np.maximum(hi - lo + 1, 0))) for _, lo, hi in calls]
    inputs = [(ro(frame), ro(lo), ro(hi)) for frame, lo, hi in calls]

    def edges(item: Any) -> int:
        frame, lo, hi = item
        args = (e.work_spans, e.tmp, e.smooth, e.gx, e.gy, e.mag, e.edges, e.stack)
        return int(K.detect_edges(frame, e.weights_ro, lo, hi, e.low, e.high, *args))

    results: dict[str, float] = {"edges (detect_edges)": median_us(edges, inputs, args.repeat, args.cold)}
    if args.passes:
        results.update(pass_times(e, inputs, args.repeat, args.cold))
    # The contour kernels need the edge map of their own call: detect once per input, then time each kernel.
    component, trace, refine, contacts, closed, fused = [], [], [], [], [], []
    for item in inputs:
        _, lo, hi = item
        count = edges(item)
        edge_map = e.edges.copy()
        stack = e.stack_ro
        best = [float("inf")] * 4
        for _ in range(args.repeat):
            e.edges[:] = edge_map
            if args.cold:
                np.add(_EVICT, 1, out=_EVICT)
            t0 = time.perf_counter_ns()
            K.keep_largest_listed(
                e.edges,
                lo,
                hi,
                stack,
                np.int32(count),
                np.int32(config.min_contour_px),
                True,
                t.labels,
                t.stack,
                t.start,
            )
            t1 = time.perf_counter_ns()
            n = K.trace_contour(e.edges_ro, lo, hi, t.start[0], t.start[1], t.chain, t.codes)
            t2 = time.perf_counter_ns()
            K.refine_subpixel(e.mag_ro, e.gx_ro, e.gy_ro, t.chain_ro, n, t.points)
            t3 = time.perf_counter_ns()
            K.count_roi_contacts(t.chain_ro, np.int32(n), lo, hi, np.int32(width))
            t4 = time.perf_counter_ns()
            for k, (a, b) in enumerate(((t0, t1), (t1, t2), (t2, t3), (t3, t4))):
                best[k] = min(best[k], (b - a) / 1000)
        for k, bucket in enumerate((component, trace, refine, contacts)):
            bucket.append(best[k])
        best_closed = best_fused = float("inf")
        for _ in range(args.repeat):
            e.edges[:] = edge_map
            K.keep_largest_listed(e.edges, lo, hi, stack, np.int32(count), np.int32(config.min_contour_px), True,
                                  t.labels, t.stack, t.start)  # fmt: skip
            if args.cold:
                np.add(_EVICT, 1, out=_EVICT)
            t0 = time.perf_counter_ns()
            K.trace_closed(e.edges.reshape(-1), width, t.start[0], t.start[1], t.chain, t.codes)
            best_closed = min(best_closed, (time.perf_counter_ns() - t0) / 1000)
            e.edges[:] = edge_map
            if args.cold:
                np.add(_EVICT, 1, out=_EVICT)
            t0 = time.perf_counter_ns()
            K.trace_rope(
                e.edges,
                lo,
                hi,
                stack,
                np.int32(count),
                np.int32(config.min_contour_px),
                True,
                e.mag_ro,
                e.gx_ro,
                e.gy_ro,
                t.labels,
                t.stack,
                t.start,
                t.chain,
                t.codes,
                t.points,
                t.counts,
            )
            best_fused = min(best_fused, (time.perf_counter_ns() - t0) / 1000)
        closed.append(best_closed)
        fused.append(best_fused)
    results["component (keep_largest_listed)"] = float(np.median(component))
    results["trace (trace_contour)"] = float(np.median(trace))
    results["subpixel (refine_subpixel)"] = float(np.median(refine))
    results["contour stage (sum of the three)"] = float(np.median(np.add(np.add(component, trace), refine)))
    results["roi contacts (count_roi_contacts)"] = float(np.median(contacts))
    results["trace without span tests (trace_closed)"] = float(np.median(closed))
    results["all of them (trace_rope)"] = float(np.median(fused))
    # Each replay updates its copies of the measured error's state as the pipeline's call did (the same work).
    results["band (band_stage)"] = median_us(lambda a: K.band_stage(*a), bands, args.repeat, args.cold)
    print(
        f"{len(calls)} edge-stage calls on {width}x{height}: rows median {np.median(rows):.0f}, "
        f"pixels median {np.median(pixels):.0f}; {len(bands)} bands built"
    )
    for name, value in results.items():
        extra = f"  ({1000 * value / np.median(pixels):.1f} ns/px)" if name.startswith("edges") else ""
        print(f"{name:36s} {value:8.1f} us{extra}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
