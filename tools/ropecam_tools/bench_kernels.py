"""Chosen kernels inside the whole device pipeline, per frame; with --against, against another commit's.

The pipeline runs over the frames with only the named kernels wrapped by a timer (each adds ~0.1 us per call), its
kernels called one by one (``one_call = False``: a steady frame's one ``steady_frame`` call would hide them), with
``cv2.Canny`` on the whole frame between frames (as ``bench.py device``: it evicts the caches as a frame's other work
does). With ``--against REF`` the other commit's pipeline (exported as ``ropecam_ref``, see ``bench.py glue``) runs
in the same process over the same frames, the two trees in alternating order frame by frame.

Prints, after the first ``--settle`` frames of each pass, the medians per frame of each kernel, of the named kernels
together (``<timed kernels>``) and of the whole pipeline; with ``--against`` also for REF, with the median of the
per-frame paired differences (REF - this tree) and ratios (this tree / REF):

    taskset -c 1 python tools/bench.py kernels [--frameset DIR] [--against REF] \\
        [--kernels detect_and_trace split_frame | --kernels all] [--split] [--passes 3]

``--kernels all`` times every kernel of the ``_kernels`` package (a kernel only one tree has shows 0 in the other);
``--split`` also times ``BlurSplitter.split`` (the split stage with its Python) as ``<split()>``.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import time
from typing import Any

import cv2
import numpy as np

from ropecam_tools.cli import UsageError, positive_int
from ropecam_tools.frames import add_frame_arguments, frames_from, source_name
from ropecam_tools.reference import pipeline_modules
from ropecam_tools.timing import KernelTimer, compiled_names, format_table


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    add_frame_arguments(parser, frames=60)
    parser.add_argument("--passes", type=positive_int, default=3, help="passes over the frames (default: %(default)s)")
    parser.add_argument("--settle", type=int, default=16, help="frames left out at the start of each pass")
    parser.add_argument("--against", metavar="REF", help="also time this git commit's kernels, alternately")
    parser.add_argument(
        "--kernels", nargs="+", default=["detect_and_trace", "split_frame"], help="kernels to time, or `all`"
    )
    parser.add_argument("--split", action="store_true", help="also time BlurSplitter.split (the split stage)")


def run(args: argparse.Namespace) -> int:
    """Time the named kernels inside the pipeline(s); print the table."""
    cv2.setNumThreads(1)
    trees: dict[str, tuple[Any, Any, KernelTimer]] = {}
    for label, ref in [("this tree", None)] + ([(args.against, args.against)] if args.against else []):
        try:
            kernels, config, pipeline = pipeline_modules(ref)
        except ValueError as exc:
            raise UsageError(str(exc)) from exc
        unknown = set(args.kernels) - {"all", *compiled_names(kernels)}
        if ref is None and unknown:
            raise UsageError(f"--kernels: no such kernel {sorted(unknown)}; the kernels: {compiled_names(kernels)}")
        trees[label] = (pipeline, config, KernelTimer(kernels, None if args.kernels == ["all"] else args.kernels))
    frames = frames_from(args)
    if len(frames) <= args.settle:
        raise UsageError(f"{source_name(args)} gives {len(frames)} frames, need more than --settle {args.settle}")
    height, width = frames[0][0].shape
    rows: dict[str, list[dict[str, float]]] = {label: [] for label in trees}
    for pass_index in range(args.passes + 1):  # the first pass warms up
        pipelines = {label: make(config(), (width, height)) for label, (make, config, _) in trees.items()}
        for pipeline in pipelines.values():  # the kernels one by one: a steady frame's one call (`steady_frame`)
            pipeline.one_call = False  # would hide them (an older tree ignores the attribute)
        if args.split:
            for label, pipeline in pipelines.items():
                _time_split(pipeline.splitter, trees[label][2].spent)
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            order = list(trees) if (index + pass_index) % 2 == 0 else list(trees)[::-1]
            for label in order:
                spent = trees[label][2].spent
                spent.clear()
                start = time.perf_counter_ns()
                pipelines[label].process(image, index, t_ns, exposure_us)
                total = time.perf_counter_ns() - start
                if pass_index > 0 and index >= args.settle:
                    rows[label].append({**{name: ns / 1000 for name, ns in spent.items()}, "pipeline": total / 1000})
            cv2.Canny(image, 20, 50, L2gradient=True)
    for _, _, timer in trees.values():
        timer.restore()
    print(f"{source_name(args)}: {len(rows['this tree'])} frames per tree (us per frame, medians)")
    print(kernel_table(rows, args.against))
    return 0


def kernel_table(rows: dict[str, list[dict[str, float]]], against: str | None) -> str:
    """The table of per-frame medians (and, with `against`, paired differences and ratios) of each timed name."""
    names = sorted({name for values in rows.values() for row in values for name in row} - {"pipeline"})
    for values in rows.values():  # the timed kernels together (e.g. one fused kernel against the ones it replaces)
        for row in values:
            row["<timed kernels>"] = sum(v for name, v in row.items() if name not in ("pipeline", "<split()>"))
    names += ["<timed kernels>", "pipeline"]
    mine = np.array([[row.get(name, 0.0) for name in names] for row in rows["this tree"]])
    theirs = np.array([[row.get(name, 0.0) for name in names] for row in rows[against]]) if against else None
    header = ["kernel", "this tree"] + ([against, "paired diff", "ratio"] if against else [])
    table = []
    for k, name in enumerate(names):
        mine_us = float(np.median(mine[:, k]))
        if theirs is None:
            if mine_us >= 0.5 or name == "pipeline":  # kernels that rarely run (first frames, fallbacks) left out
                table.append([name, mine_us])
            continue
        theirs_us = float(np.median(theirs[:, k]))
        if max(mine_us, theirs_us) < 0.5 and name != "pipeline":
            continue
        ratio = float(np.median(mine[:, k] / np.maximum(theirs[:, k], 1e-9))) if theirs_us > 0 else float("nan")
        table.append([name, mine_us, theirs_us, float(np.median(theirs[:, k] - mine[:, k])), f"{ratio:.3f}"])
    return format_table(header, table)


def _time_split(splitter: Any, spent: dict[str, int]) -> None:
    """Time `splitter.split` (through an instance attribute) as ``spent["<split()>"]``."""
    real = splitter.split

    def split(*a: Any, **k: Any) -> Any:
        start = time.perf_counter_ns()
        try:
            return real(*a, **k)
        finally:
            spent["<split()>"] = spent.get("<split()>", 0) + time.perf_counter_ns() - start

    splitter.split = split
