"""The split's time inside a whole pipeline run, this tree against another commit, per kernel, in one process.

`bench_glue.py --against` compares whole frames, whose medians move by +-20 us with the load of a shared machine;
this tool wraps every kernel of both trees and `BlurSplitter.split` with timers and gives the same frames to both
pipelines alternately (the order swapped every frame), then prints per-frame medians of each kernel, of `split()`
and of the whole `process` call (after `--settle` frames of each of `--passes` passes; a first pass warms up):

    taskset -c 1 python tools/bench_split_ab.py --against 28578f5 [--frameset /work/eval/rig-soft]
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_glue  # a sibling tool: frame loading and the export of the other commit


def _wrap_kernels(kernels: Any, acc: dict[str, int]) -> None:
    """Replace each compiled kernel of the `_kernels` package by a wrapper adding its time (ns) to ``acc[name]``."""
    for name in dir(kernels):
        function = getattr(kernels, name)
        if not hasattr(function, "py_func"):
            continue

        def timed(*args: Any, _f: Any = function, _name: str = name) -> Any:
            start = time.perf_counter_ns()
            try:
                return _f(*args)
            finally:
                acc[_name] = acc.get(_name, 0) + time.perf_counter_ns() - start

        setattr(kernels, name, timed)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--against", required=True, metavar="REF", help="git commit to compare with")
    parser.add_argument("--frameset", default="/work/eval/rig", help="frame set folder (default: %(default)s)")
    parser.add_argument("--frames", type=int, default=60, help="frames per pass (default: %(default)s)")
    parser.add_argument("--passes", type=int, default=3, help="timed passes (default: %(default)s)")
    parser.add_argument("--settle", type=int, default=16, help="frames left out at the start of each pass")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    frames = bench_glue.load_frames(args.frameset, args.frames)
    sys.path.insert(0, str(bench_glue.export_ref(args.against)))
    height, width = frames[0][0].shape
    variants: dict[str, tuple[Any, Any, dict[str, int]]] = {}
    for label, prefix in (("this tree", "ropecam"), (args.against, "ropecam_ref")):
        acc: dict[str, int] = {}
        _wrap_kernels(importlib.import_module(f"{prefix}.device.pipeline._kernels"), acc)
        pipeline = importlib.import_module(f"{prefix}.device.pipeline.pipeline").Pipeline
        config = importlib.import_module(f"{prefix}.device.pipeline.config").PipelineConfig
        variants[label] = (pipeline, config, acc)
    rows: dict[str, list[dict[str, int]]] = {label: [] for label in variants}
    for pass_index in range(args.passes + 1):
        pipelines = {label: make(config(), (width, height)) for label, (make, config, _) in variants.items()}
        for label, pipeline in pipelines.items():  # time `split` through an instance attribute
            real, spent = pipeline.splitter.split, variants[label][2]

            def split(*a: Any, _real: Any = real, _spent: dict[str, int] = spent, **k: Any) -> Any:
                start = time.perf_counter_ns()
                try:
                    return _real(*a, **k)
                finally:
                    _spent["<split()>"] = _spent.get("<split()>", 0) + time.perf_counter_ns() - start

            pipeline.splitter.split = split
        labels = list(pipelines)
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            for label in labels if (index + pass_index) % 2 == 0 else labels[::-1]:
                acc = variants[label][2]
                acc.clear()
                start = time.perf_counter_ns()
                pipelines[label].process(image, index, t_ns, exposure_us)
                total = time.perf_counter_ns() - start
                if pass_index > 0 and index >= args.settle:
                    rows[label].append({**acc, "<process()>": total})
    names = sorted({name for values in rows.values() for row in values for name in row})
    labels = list(rows)
    print(f"{args.frameset}: {len(rows[labels[0]])} frames each; medians per frame (us)")
    print(f"{'':32s} {labels[0]:>12s} {labels[1]:>12s}")
    for name in names:
        medians = [float(np.median([row.get(name, 0) for row in rows[label]])) / 1000.0 for label in labels]
        if max(medians) >= 1.0:
            print(f"{name:32s} {medians[0]:12.1f} {medians[1]:12.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
