"""The edge and contour stages on the recorded bands of a frame set: sizes, times, and an A/B against another commit.

A pipeline runs over the frames once and records every edge-stage call (frame, row spans; as
`bench_roi_kernels.py`). Each recorded band is then replayed through the stages as the pipeline calls them,
`EdgeDetector.detect` followed at once by `ContourTracer.trace` (component, chain, subpixel points, contacts),
with the caches evicted before the detection (the pipeline runs ``cv2.Canny`` on the whole frame between frames
in `bench_device.py`, and the split between a frame's trace and the next detection):

    taskset -c 1 python tools/bench_trace.py [--frameset DIR] [--frames 40] [--repeat 5] \\
        [--against REF] [--sizes] [--parts]

- ``--sizes``: per band, the rows and pixels of the spans, the edge pixels, their components, the kept
  component's pixels and the chain's length (medians and ranges).
- ``--parts``: the kernels `trace_rope` runs on a band, one call each right after a detection (caches evicted
  before it): ``first_listed`` + ``trace_closed``, ``keep_traced``, ``refine_inner``, and ``trace_rope`` whole
  (each with its ~1-2 us dispatch).
- ``--against REF``: the same replay with REF's ``device/`` (exported as ``ropecam_ref``, see `bench_glue.py`),
  the two trees alternately band by band; prints both medians, the median of the per-band paired ratios
  (this tree / REF) and checks that the outputs are bit-identical (edge pixels as a set, edge map, contour
  chain, codes, subpixel points, component size, contacts, border pixels).
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import importlib
import sys
import time
from typing import Any

import numpy as np

_EVICT = np.zeros(8 << 20, np.uint8)


def outputs(pipeline: Any, lo: np.ndarray, hi: np.ndarray, n: int) -> dict[str, Any]:
    """What the edge and contour stages leave for the rest of the pipeline, for comparison."""
    e, t = pipeline.edges, pipeline.tracer
    rows = np.flatnonzero(hi >= lo)
    edge_map = np.concatenate([e.edges[r, lo[r] : hi[r] + 1] for r in rows]) if rows.size else np.zeros(0)
    return {
        "edge pixels": np.sort(e.stack[: e.count]),
        "edge map": edge_map,
        "n": n,
        "chain": t.chain[:n].copy(),
        "codes": t.codes[:n].copy(),
        "points": t.points[:n].copy(),
        "counts": (t.component_px, t.contacts, t.on_border),
    }


def replay(pipeline: Any, frame: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[float, float, int]:
    """Evict the caches, detect and trace one band; return (detect us, trace us, contour points)."""
    np.add(_EVICT, 1, out=_EVICT)
    t0 = time.perf_counter_ns()
    pipeline.edges.detect(frame, lo, hi)
    t1 = time.perf_counter_ns()
    e = pipeline.edges
    n = pipeline.tracer.trace(e.edges, lo, hi, e.mag_ro, e.gx_ro, e.gy_ro, e.stack_ro, e.count)  # as the pipeline
    t2 = time.perf_counter_ns()
    return (t1 - t0) / 1000, (t2 - t1) / 1000, n


def sizes(pipeline: Any, inputs: list[Any]) -> None:
    """Print the band, edge and contour sizes."""
    e, t = pipeline.edges, pipeline.tracer
    table: dict[str, list[float]] = {}
    for frame, lo, hi in inputs:
        n = replay(pipeline, frame, lo, hi)[2]
        flat = e.stack[: e.count]
        mask = np.zeros(e.shape, bool)
        mask.flat[flat] = True
        components = _count_components(mask)
        values = {
            "rows": int(np.count_nonzero(hi >= lo)),
            "band px": int(np.sum(np.maximum(hi - lo + 1, 0))),
            "edge px": e.count,
            "components": components,
            "kept component px": t.component_px,
            "other edge px": e.count - t.component_px,
            "chain points": n,
            "chain / kept px": n / max(t.component_px, 1),
        }
        for key, value in values.items():
            table.setdefault(key, []).append(value)
    for key, values in table.items():
        a = np.array(values, float)
        print(f"  {key:20s} median {np.median(a):9.2f}   min {a.min():9.2f}   max {a.max():9.2f}")


def _count_components(mask: np.ndarray) -> int:
    """8-connected components of `mask` (slow, obvious)."""
    seen = np.zeros_like(mask)
    count = 0
    height, width = mask.shape
    for r0, c0 in zip(*np.nonzero(mask), strict=True):
        if seen[r0, c0]:
            continue
        count += 1
        todo = [(r0, c0)]
        seen[r0, c0] = True
        while todo:
            r, c = todo.pop()
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr, cc = r + dr, c + dc
                    if 0 <= rr < height and 0 <= cc < width and mask[rr, cc] and not seen[rr, cc]:
                        seen[rr, cc] = True
                        todo.append((rr, cc))
    return count


def parts(pipeline: Any, kernels: Any, inputs: list[Any], repeat: int, min_px: int) -> None:
    """Time the kernels `trace_rope` runs on a band (its inner path: the trace first from the first listed pixel,
    then `keep_traced`, then `refine_inner`), each called on its own right after a detection with the caches
    evicted before it, and `trace_rope` whole after another detection; best of `repeat` per band, each with its
    ~1-2 us dispatch. A band whose component is not the traced one (`keep_traced` 0) is left out."""
    e, t = pipeline.edges, pipeline.tracer
    width = e.shape[1]
    scratch = t.labels.reshape(-1)
    names = ["first_listed + trace_closed", "keep_traced", "refine_inner", "trace_rope"]
    per: dict[str, list[float]] = {name: [] for name in names}
    for frame, lo, hi in inputs:
        best = dict.fromkeys(names, float("inf"))
        for _ in range(repeat):
            np.add(_EVICT, 1, out=_EVICT)
            e.detect(frame, lo, hi)
            flat = e.edges.reshape(-1)
            t0 = time.perf_counter_ns()
            first = kernels.first_listed(e.stack_ro, e.count)
            n = kernels.trace_closed(flat, width, first // width, first % width, t.chain, t.codes)
            t1 = time.perf_counter_ns()
            size = kernels.keep_traced(flat, width, e.stack_ro, e.count, min_px, t.chain, n, t.stack)
            t2 = time.perf_counter_ns()
            kernels.refine_inner(e.mag_ro, e.gx_ro, e.gy_ro, lo, hi, t.chain, n, scratch, t.points)
            t3 = time.perf_counter_ns()
            np.add(_EVICT, 1, out=_EVICT)
            e.detect(frame, lo, hi)
            t4 = time.perf_counter_ns()
            t.trace(e.edges, lo, hi, e.mag_ro, e.gx_ro, e.gy_ro, e.stack_ro, e.count)
            t5 = time.perf_counter_ns()
            if n <= 0 or size <= 0:
                break
            for name, (a, b) in zip(names, ((t0, t1), (t1, t2), (t2, t3), (t4, t5)), strict=True):
                best[name] = min(best[name], (b - a) / 1000)
        if all(np.isfinite(v) for v in best.values()):
            for name in names:
                per[name].append(best[name])
    print(f"  parts on {len(per[names[0]])} bands (medians over bands of the best of {repeat}):")
    for name in names:
        print(f"  {name:28s} {np.median(per[name]):7.1f} us")


def compare(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """Names of the outputs that differ."""
    bad = []
    for key in a:
        x, y = a[key], b[key]
        same = (
            np.array_equal(x, y) and (not isinstance(x, np.ndarray) or x.dtype == y.dtype)
            if isinstance(x, np.ndarray)
            else x == y
        )
        if not same:
            bad.append(key)
    return bad


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frameset", help="frame set (default: the synthetic rig frames of bench_device)")
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--repeat", type=int, default=5, help="replays per band and tree, the fastest is kept")
    parser.add_argument("--against", metavar="REF", help="also replay with this commit's stages, alternately")
    parser.add_argument("--sizes", action="store_true", help="print the band, edge and contour sizes")
    parser.add_argument("--parts", action="store_true", help="time the kernels trace_rope runs, one by one")
    args = parser.parse_args(argv)
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path.insert(0, here)
    from bench_device import frameset_frames, rig_frames
    from bench_glue import export_ref
    from bench_roi_kernels import record

    from ropecam.device.pipeline._views import ro

    frames = frameset_frames(args.frameset, args.frames + 3) if args.frameset else rig_frames(args.frames + 3)
    kernels = importlib.import_module("ropecam.device.pipeline._kernels")
    config_cls = importlib.import_module("ropecam.device.pipeline.config").PipelineConfig
    pipeline_cls = importlib.import_module("ropecam.device.pipeline.pipeline").Pipeline
    calls, _ = record(frames, config_cls())
    inputs = [(ro(frame), ro(lo), ro(hi)) for frame, lo, hi in calls]
    height, width = frames[0][0].shape
    trees = {"this tree": pipeline_cls(config_cls(), (width, height))}
    if args.against:
        sys.path.insert(0, str(export_ref(args.against)))
        print(f"importing {args.against} as ropecam_ref (its kernels compile once)...", flush=True)
        ref_config = importlib.import_module("ropecam_ref.device.pipeline.config").PipelineConfig
        ref_pipeline = importlib.import_module("ropecam_ref.device.pipeline.pipeline").Pipeline
        trees[args.against] = ref_pipeline(ref_config(), (width, height))
    print(f"{args.frameset or 'synthetic rig frames'}: {len(inputs)} bands of {width}x{height}")
    if args.sizes:
        sizes(trees["this tree"], inputs)
    if args.parts:
        parts(trees["this tree"], kernels, inputs, args.repeat, config_cls().min_contour_px)
    best: dict[str, list[tuple[float, float, float]]] = {name: [] for name in trees}
    mismatches: dict[str, int] = {}
    for index, (frame, lo, hi) in enumerate(inputs):
        names = list(trees) if index % 2 == 0 else list(trees)[::-1]
        runs: dict[str, list[tuple[float, float]]] = {name: [] for name in trees}
        for _ in range(args.repeat):
            for name in names:
                d_us, t_us, _ = replay(trees[name], frame, lo, hi)
                runs[name].append((d_us, t_us))
        results = {}
        for name in trees:
            d = np.array(runs[name])
            best[name].append((float(d[:, 0].min()), float(d[:, 1].min()), float((d[:, 0] + d[:, 1]).min())))
            n = replay(trees[name], frame, lo, hi)[2]
            results[name] = outputs(trees[name], lo, hi, n)
        if args.against:
            for key in compare(*results.values()):
                mismatches[key] = mismatches.get(key, 0) + 1
    for name, values in best.items():
        d = np.array(values)
        print(
            f"  {name:>12}: detect {np.median(d[:, 0]):6.1f} us, trace {np.median(d[:, 1]):6.1f} us, "
            f"both {np.median(d[:, 2]):6.1f} us (medians over bands of the best of {args.repeat})"
        )
    if args.against:
        mine, theirs = np.array(best["this tree"]), np.array(best[args.against])
        ratio = np.median(mine / theirs, axis=0)
        diff = np.median(theirs - mine, axis=0)
        print(
            f"  paired, this tree / {args.against}: detect {ratio[0]:.3f}, trace {ratio[1]:.3f}, both {ratio[2]:.3f}"
            f"; saved (median of differences) {diff[0]:.1f} / {diff[1]:.1f} / {diff[2]:.1f} us"
        )
        if mismatches:
            print(f"  OUTPUTS DIFFER (bands per output): {mismatches}")
        else:
            print(f"  outputs bit-identical on all {len(inputs)} bands")
    return 1 if mismatches else 0


if __name__ == "__main__":
    sys.exit(main())
