"""Micro-benchmark the blur split's kernels, step by step, on the contours of a frame set.

A pipeline runs over the frames once and records the arguments of every `split_frame` (the steady frame's
split in one call), `find_segmentation_points`, `split_shapes_packed` and `slope_sweep_median` call (copies:
the gradient planes, the smoothed image, the contour; a recorded `split_frame` reports a full buffer, so the stage
makes the same split with the other three). Each kernel is then re-run on exactly those inputs (one thread) and
the median over calls of the best of ``--repeat`` is printed (also `split_shapes_local` on the unpacked
arguments: the dispatch saving of the packed entry). ``split_shapes_local`` is re-run as its sequence of step
kernels (`side_sweeps`, `offset_by_table_thinned`, `extend_to_band_end`, the lengths, `anchor_start`,
`resample_polyline_of_length`, `smooth_polyline`), each step timed on its own, so that a change to one step can
be measured alone:

    taskset -c 1 python tools/bench_split_kernels.py [--frameset /work/eval/rig] [--frames 40] [--repeat 5] [--cold]

With ``--cold`` the caches are filled with other data before each timed call (before the first step of the
sequence for the steps: the later ones find what the earlier ones loaded, as in the pipeline), as the rest of a
frame's work does between two splits.
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
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline

RECORDED = ("split_frame", "find_segmentation_points", "split_shapes_packed", "slope_sweep_median")
"""The kernels whose calls are recorded (the names `split.py` calls them by). A recorded `split_frame` call then
reports a full buffer, so that the stage makes the same frame's split with the other three (same results)."""


def _copy(value: Any) -> Any:
    """A copy of an array argument keeping its read-only flag (the kernels' signatures tell them apart)."""
    if not isinstance(value, np.ndarray):
        return value
    copied = value.copy()
    copied.flags.writeable = value.flags.writeable
    return copied


def record(frames: list[tuple[np.ndarray, int, float]], config: PipelineConfig) -> dict[str, list[tuple]]:
    """Run a pipeline over `frames`; return the copied argument tuples of each recorded kernel's calls after the
    first three frames."""
    height, width = frames[0][0].shape
    pipeline = Pipeline(config, (width, height))
    pipeline.one_call = False  # the kernels one by one: a steady frame's one call (`steady_frame`) would hide them
    calls: dict[str, list[tuple]] = {name: [] for name in RECORDED}
    originals = {name: getattr(K, name) for name in RECORDED}
    recording = [False]

    def recorder(name: str) -> Any:
        kernel = originals[name]

        def recorded(*args: Any) -> Any:
            if recording[0]:
                calls[name].append(tuple(_copy(a) for a in args))
                if name == "split_frame":
                    return K.FULL
            return kernel(*args)

        return recorded

    for name in RECORDED:
        setattr(K, name, recorder(name))
    try:
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            recording[0] = index >= 3
            pipeline.process(image, index, t_ns, exposure_us)
    finally:
        for name, kernel in originals.items():
            setattr(K, name, kernel)
    return calls


_EVICT = np.zeros(8 << 20, np.uint8)
"""Written before each timed call with ``--cold`` (8 MiB: more than L2, as the rest of a frame's work)."""


def _evict() -> None:
    np.add(_EVICT, 1, out=_EVICT)


def median_us(fn: Any, inputs: list[Any], repeat: int, cold: bool) -> float:
    """Median over `inputs` of the best of `repeat` timed calls ``fn(item)`` (us)."""
    per_item = []
    for item in inputs:
        best = float("inf")
        for _ in range(repeat):
            if cold:
                _evict()
            t0 = time.perf_counter_ns()
            fn(item)
            best = min(best, (time.perf_counter_ns() - t0) / 1000)
        per_item.append(best)
    return float(np.median(per_item)) if per_item else float("nan")


def unpacked(args: tuple) -> tuple:
    """`split_shapes_local`'s argument tuple for a recorded `split_shapes_packed` call (same arrays, as views)."""
    (points, chain, n, i_fix, seg_a, seg_b, mag, inv_contrast, gx, gy, polarity, smooth, fixed_r, fixed_c, params,
     curves, table, lines, sides, work_arc, info) = args  # fmt: skip
    p = params.tolist()
    f4 = np.float32
    return (points, chain, n, i_fix, seg_a, seg_b, mag, inv_contrast, curves[0], curves[1], np.int32(p[0]), gx, gy,
            polarity, f4(p[1]), table, smooth, f4(p[2]), f4(p[3]), f4(p[4]), f4(p[5]), f4(p[6]), p[7], p[8], f4(p[9]),
            f4(p[10]), fixed_r, fixed_c, lines[0], lines[1], lines[2], sides[0], sides[1], sides[2], sides[3],
            work_arc, info, work_arc[:0], np.zeros(0, np.int32))  # fmt: skip


def local_steps(args: tuple, times: dict[str, float]) -> int:
    """Run `split_shapes_local`'s steps one kernel at a time on its argument tuple `args`, adding each step's
    time (us) to `times`; the slant correction (a few float operations) is left out. Returns the status."""
    (points, chain, n, i_fix, seg_a, seg_b, mag, inv_contrast, ratios, sweeps, half, gx, gy, polarity, step_px,
     table, smooth, width_px, cap_px, skip_px, span_px, blur_px, _slant, _check, out_step_px, smoothing_px,
     fixed_r, fixed_c, work, sweeps_a, sweeps_b, side_a, side_b, out_a, out_b, work_arc, _info,
     _dist, _index) = args  # fmt: skip
    plus, minus = np.int32(1), np.int32(-1)
    clock = time.perf_counter_ns

    def lap(name: str, t0: int) -> int:
        t1 = clock()
        times[name] = times.get(name, 0.0) + (t1 - t0) / 1000
        return t1

    t = clock()
    K.side_sweeps(chain, n, i_fix, seg_a, plus, mag, inv_contrast, ratios, sweeps, half, work, sweeps_a)
    K.side_sweeps(chain, n, i_fix, seg_b, minus, mag, inv_contrast, ratios, sweeps, half, work, sweeps_b)
    t = lap("side_sweeps x2", t)
    sa, sb = sweeps_a.view(), sweeps_b.view()
    sa.flags.writeable = sb.flags.writeable = False
    t = clock()
    keep = K.dense_end_points(skip_px, span_px)
    na = K.offset_by_table_thinned(points, chain, n, i_fix, seg_a, plus, gx, gy, polarity, sa, step_px, table, keep,
                                   keep, side_a)  # fmt: skip
    nb = K.offset_by_table_thinned(points, chain, n, i_fix, seg_b, minus, gx, gy, polarity, sb, step_px, table, keep,
                                   keep, side_b)  # fmt: skip
    t = lap("offset_by_table_thinned x2", t)
    na = K.extend_to_band_end(side_a, na, points, n, smooth, width_px, cap_px, skip_px, span_px, blur_px)
    nb = K.extend_to_band_end(side_b, nb, points, n, smooth, width_px, cap_px, skip_px, span_px, blur_px)
    t = lap("extend_to_band_end x2", t)
    ra, rb = side_a.view(), side_b.view()
    ra.flags.writeable = rb.flags.writeable = False
    K.polyline_length(ra, np.int32(na))
    K.polyline_length(rb, np.int32(nb))
    t = lap("polyline_length x2 (check)", t)
    na = K.anchor_start(side_a, np.int32(na), fixed_r, fixed_c, skip_px, span_px)
    nb = K.anchor_start(side_b, np.int32(nb), fixed_r, fixed_c, skip_px, span_px)
    t = lap("anchor_start x2", t)
    len_a = K.polyline_length(ra, np.int32(na))
    len_b = K.polyline_length(rb, np.int32(nb))
    t = lap("polyline_length x2", t)
    ca = K.resample_polyline_of_length(ra, np.int32(na), len_a, out_step_px, out_a)
    cb = K.resample_polyline_of_length(rb, np.int32(nb), len_b, out_step_px, out_b)
    t = lap("resample x2", t)
    oa, ob = out_a.view(), out_b.view()
    oa.flags.writeable = ob.flags.writeable = False
    if smoothing_px > 0.0:
        K.smooth_polyline(oa, np.int32(ca), smoothing_px, work_arc, side_a)
        K.smooth_polyline(ob, np.int32(cb), smoothing_px, work_arc, side_b)
    lap("smooth_polyline x2", t)
    return 2


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frameset", help="frame set (default: the synthetic rig frames of bench_device)")
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--repeat", type=int, default=5, help="calls per input, the fastest is kept (default 5)")
    parser.add_argument("--cold", action="store_true", help="evict the caches before each timed call")
    args = parser.parse_args(argv)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from bench_device import frameset_frames, rig_frames

    frames = frameset_frames(args.frameset, args.frames + 3) if args.frameset else rig_frames(args.frames + 3)
    calls = record(frames, PipelineConfig())
    calls["split_shapes_local"] = [unpacked(c) for c in calls["split_shapes_packed"]]
    results: dict[str, float] = {}
    for name in (*RECORDED, "split_shapes_local"):
        kernel = getattr(K, name)
        results[name] = median_us(lambda a, k=kernel: k(*a), calls[name], args.repeat, args.cold)
    # The steps: per call, the best of `repeat` sequences for each step (each sequence on fresh copies of the
    # in-place outputs is not needed: every step rewrites its outputs from the recorded inputs).
    per_step: dict[str, list[float]] = {}
    for call in calls["split_shapes_local"]:
        best: dict[str, float] = {}
        for _ in range(args.repeat):
            if args.cold:
                _evict()
            times: dict[str, float] = {}
            local_steps(call, times)
            for key, value in times.items():
                best[key] = min(best.get(key, float("inf")), value)
        for key, value in best.items():
            per_step.setdefault(key, []).append(value)
    n_points = [int(c[2]) for c in calls["split_shapes_local"]]
    print(
        f"{len(calls['split_shapes_local'])} local splits on {frames[0][0].shape[1]}x{frames[0][0].shape[0]}, "
        f"contour points median {np.median(n_points) if n_points else float('nan'):.0f}"
    )
    for name, value in results.items():
        print(f"{name:36s} {value:8.1f} us  ({len(calls[name])} calls)")
    print("split_shapes_local as its steps:")
    for name, values in per_step.items():
        print(f"  {name:34s} {np.median(values):8.1f} us")
    print(f"  {'sum of the step medians':34s} {sum(np.median(v) for v in per_step.values()):8.1f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
