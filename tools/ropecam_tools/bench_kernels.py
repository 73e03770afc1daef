"""Chosen kernels inside the whole device pipeline, this tree against another commit, frames alternated.

Both pipelines run in one process over the same frames (the other commit's ``device/`` and ``shared/`` exported as
``ropecam_ref``, as in `bench_glue.py`), frame by frame in alternating order, with ``cv2.Canny`` on the whole
frame between frames (as `bench_device.py`). Only the kernels named are wrapped with a timer (each adds ~0.1 us).
Prints, after the first `--settle` frames of each pass, the medians per frame of each kernel and of the whole
pipeline for both trees (and of the named kernels together, `<timed kernels>`), the median of the per-frame paired
differences (REF - this tree) and of the ratios:

    taskset -c 1 python tools/bench_kernels_ab.py [--frameset /work/eval/rig] [--against main] \\
        [--kernels detect_and_trace split_frame | --kernels all] [--split] [--passes 3]

`--kernels all` times every kernel of the `_kernels` package (a kernel only one tree has shows 0 in the other);
`--split` also times `BlurSplitter.split` (the split stage with its Python) as `<split()>`.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import importlib
import sys
import time
from typing import Any

import cv2
import numpy as np


def wrap(kernels: Any, names: list[str], spent: dict[str, int]) -> None:
    """Replace each named kernel of the `kernels` package (all compiled ones for ``["all"]``; names the package
    lacks are left out) by a timed call adding its time to `spent`."""
    if names == ["all"]:
        names = [name for name in dir(kernels) if hasattr(getattr(kernels, name), "py_func")]
    for name in names:
        function = getattr(kernels, name, None)
        if function is None:
            continue

        def timed(*args: Any, _function: Any = function, _name: str = name) -> Any:
            start = time.perf_counter_ns()
            try:
                return _function(*args)
            finally:
                spent[_name] = spent.get(_name, 0) + time.perf_counter_ns() - start

        setattr(kernels, name, timed)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frameset", default="/work/eval/rig", help="frame set folder (default: %(default)s)")
    parser.add_argument("--frames", type=int, default=60, help="frames per pass (default: %(default)s)")
    parser.add_argument("--passes", type=int, default=3, help="passes over the frames (default: %(default)s)")
    parser.add_argument("--settle", type=int, default=16, help="frames left out at the start of each pass")
    parser.add_argument("--against", default="main", metavar="REF", help="the other commit (default: %(default)s)")
    parser.add_argument(
        "--kernels", nargs="+", default=["detect_and_trace", "split_frame"], help="kernels to time, or `all`"
    )
    parser.add_argument("--split", action="store_true", help="also time BlurSplitter.split (the split stage)")
    args = parser.parse_args(argv)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from bench_glue import export_ref, load_frames

    cv2.setNumThreads(1)
    frames = load_frames(args.frameset, args.frames)
    if len(frames) <= args.settle:
        parser.error(f"{args.frameset} has {len(frames)} frames, need more than --settle {args.settle}")
    sys.path.insert(0, str(export_ref(args.against)))
    height, width = frames[0][0].shape
    trees: dict[str, tuple[Any, Any, dict[str, int]]] = {}
    for label, prefix in (("this tree", "ropecam"), (args.against, "ropecam_ref")):
        kernels = importlib.import_module(f"{prefix}.device.pipeline._kernels")
        spent: dict[str, int] = {}
        wrap(kernels, args.kernels, spent)
        pipeline = importlib.import_module(f"{prefix}.device.pipeline.pipeline").Pipeline
        config = importlib.import_module(f"{prefix}.device.pipeline.config").PipelineConfig
        trees[label] = (pipeline, config, spent)
    rows: dict[str, list[dict[str, float]]] = {label: [] for label in trees}
    for pass_index in range(args.passes + 1):  # the first pass warms up
        pipelines = {label: make(config(), (width, height)) for label, (make, config, _) in trees.items()}
        for pipeline in pipelines.values():  # the kernels one by one in both trees: a steady frame's one call
            pipeline.one_call = False  # (`steady_frame`) would hide them (an older tree ignores the attribute)
        if args.split:
            for label, pipeline in pipelines.items():  # `split` timed through an instance attribute
                _time_split(pipeline.splitter, trees[label][2])
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            order = list(trees) if (index + pass_index) % 2 == 0 else list(trees)[::-1]
            for label in order:
                spent = trees[label][2]
                spent.clear()
                start = time.perf_counter_ns()
                pipelines[label].process(image, index, t_ns, exposure_us)
                total = time.perf_counter_ns() - start
                if pass_index > 0 and index >= args.settle:
                    rows[label].append({**{name: ns / 1000 for name, ns in spent.items()}, "pipeline": total / 1000})
            cv2.Canny(image, 20, 50, L2gradient=True)
    names = sorted({name for values in rows.values() for row in values for name in row} - {"pipeline"})
    for values in rows.values():  # the timed kernels together (e.g. one fused kernel against the ones it replaces)
        for row in values:
            row["<timed kernels>"] = sum(v for name, v in row.items() if name != "pipeline")
    names += ["<timed kernels>", "pipeline"]
    mine = np.array([[row.get(name, 0.0) for name in names] for row in rows["this tree"]])
    theirs = np.array([[row.get(name, 0.0) for name in names] for row in rows[args.against]])
    print(f"{args.frameset}: {len(mine)} frames per tree (us per frame)")
    for k, name in enumerate(names):
        if max(np.median(mine[:, k]), np.median(theirs[:, k])) < 0.5 and name != "pipeline":
            continue  # kernels that rarely run (first frames, fallbacks)
        ratio = np.median(mine[:, k] / np.maximum(theirs[:, k], 1e-9)) if np.median(theirs[:, k]) > 0 else np.nan
        print(
            f"  {name:>24}: this tree {np.median(mine[:, k]):7.1f}, {args.against} {np.median(theirs[:, k]):7.1f}; "
            f"paired difference {np.median(theirs[:, k] - mine[:, k]):6.1f}, ratio {ratio:.3f}"
        )
    return 0


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


if __name__ == "__main__":
    sys.exit(main())
