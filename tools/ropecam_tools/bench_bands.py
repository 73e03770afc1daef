"""The edge and contour stages replayed on the bands a pipeline run asked for: sizes, times, an A/B against a commit.

A pipeline runs over the frames once (its kernels one by one) and records every edge-stage call after the first
three frames: the frame and the row spans of its band (region of interest). Each recorded band is then replayed
through the stages as the pipeline calls them, ``EdgeDetector.detect`` followed at once by ``ContourTracer.trace``
(component, chain, subpixel points, contacts), with the caches evicted before the detection (as the rest of a
frame's work does); the fastest of ``--repeat`` replays per band is kept:

    taskset -c 1 python tools/bench.py bands [--frameset DIR] [--frames 40] [--repeat 5] [--against REF] [--sizes]

- ``--sizes``: per band, the rows and pixels of the spans, the edge pixels, their components, the kept
  component's pixels and the chain's length (medians and ranges).
- ``--against REF``: the same replay with REF's stages (exported as ``ropecam_ref``, see ``bench.py glue``), the
  two trees alternately band by band; prints both medians, the median of the per-band paired ratios (this tree /
  REF) and checks that the outputs are bit-identical (edge pixels as a set, edge map, contour chain, codes,
  subpixel points, component size, contacts, border pixels); exit code 1 if they differ.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import time
from typing import Any

import numpy as np

from ropecam_tools.cli import UsageError, positive_int
from ropecam_tools.frames import Frame, add_frame_arguments, frames_from, source_name
from ropecam_tools.reference import pipeline_modules
from ropecam_tools.timing import evict, paired


def record_bands(frames: list[Frame], pipeline: Any) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Run `pipeline` over `frames` with its kernels one by one; return the (frame, lo, hi) of each edge-stage
    call after the first three frames (read-only copies of the spans)."""
    pipeline.one_call = False  # a steady frame's one call (`steady_frame`) would hide the edge stage's calls
    calls: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    detect = pipeline.tracer.detect_and_trace  # the edge and contour stages in one call
    recording = [False]

    def recorded(detector: Any, frame: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> int:
        if recording[0]:
            spans = [lo.copy(), hi.copy()]
            for span in spans:
                span.flags.writeable = False
            calls.append((frame, *spans))
        return detect(detector, frame, lo, hi)

    pipeline.tracer.detect_and_trace = recorded
    try:
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            recording[0] = index >= 3
            pipeline.process(image, index, t_ns, exposure_us)
    finally:
        del pipeline.tracer.detect_and_trace  # the class's method again
    return calls


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
    evict()
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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    add_frame_arguments(parser, frames=40)
    parser.add_argument("--repeat", type=positive_int, default=5, help="replays per band and tree, the fastest is kept")
    parser.add_argument("--against", metavar="REF", help="also replay with this commit's stages, alternately")
    parser.add_argument("--sizes", action="store_true", help="print the band, edge and contour sizes")


def run(args: argparse.Namespace) -> int:
    """Record the bands, replay them, print the times (and the comparison with REF)."""
    frames = frames_from(args, args.frames + 3)
    _, config_cls, pipeline_cls = pipeline_modules(None)
    height, width = frames[0][0].shape
    inputs = record_bands(frames, pipeline_cls(config_cls(), (width, height)))
    if not inputs:
        raise UsageError(f"{source_name(args)}: no edge-stage call recorded in {len(frames)} frames")
    trees = {"this tree": pipeline_cls(config_cls(), (width, height))}
    if args.against:
        try:
            _, ref_config, ref_pipeline = pipeline_modules(args.against)
        except ValueError as exc:
            raise UsageError(str(exc)) from exc
        trees[args.against] = ref_pipeline(ref_config(), (width, height))
    print(f"{source_name(args)}: {len(inputs)} bands of {width}x{height}")
    if args.sizes:
        sizes(trees["this tree"], inputs)
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
        figures = [paired(mine[:, k], theirs[:, k]) for k in range(3)]
        print(
            f"  paired, this tree / {args.against}: detect {figures[0][0]:.3f}, trace {figures[1][0]:.3f}, both "
            f"{figures[2][0]:.3f}; saved (median of differences) {figures[0][1]:.1f} / {figures[1][1]:.1f} / "
            f"{figures[2][1]:.1f} us"
        )
        if mismatches:
            print(f"  OUTPUTS DIFFER (bands per output): {mismatches}")
        else:
            print(f"  outputs bit-identical on all {len(inputs)} bands")
    return 1 if mismatches else 0
