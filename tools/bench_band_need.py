"""Replay the band's measured-error kernel (`band_need`) of a pipeline run against another commit's, in one process.

Runs the device pipeline over a frame set, records every `band_need` call (inputs and outputs), then replays
the calls with this tree's kernel and with the one of `--against` (its `_kernels/prediction.py`, compiled beside
this tree's), alternated per call, warm and with the caches evicted (a 4 MB write) before each call. Prints the
medians (us), the median paired difference (against - this tree) and the calls whose outputs differ.

Example: ``taskset -c 0 python tools/bench_band_need.py --frameset /work/eval/rig --against main``
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from bench_device import frameset_frames

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline

_KERNEL_FILE = "device/pipeline/_kernels/prediction.py"


def _record(frameset: str, frames: int) -> list[tuple[list, int, np.ndarray, np.ndarray]]:
    images = frameset_frames(frameset, frames)
    height, width = images[0][0].shape
    pipeline = Pipeline(PipelineConfig(), (width, height))
    calls = []
    kernel = K.band_need

    def recording(*args):
        copies = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
        result = kernel(*args)
        calls.append((copies, result, args[-2].copy(), args[-1].copy()))
        return result

    K.band_need = recording
    try:
        for i, (image, t_ns, exposure_ns) in enumerate(images):
            pipeline.process(image, i, t_ns, exposure_ns)
    finally:
        K.band_need = kernel
    return calls


def _load_against(commit: str, folder: str):
    source = subprocess.run(["git", "show", f"{commit}:{_KERNEL_FILE}"], capture_output=True, text=True, check=True)
    path = Path(folder) / "against_prediction.py"
    path.write_text(source.stdout)
    spec = importlib.util.spec_from_file_location("against_prediction", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.band_need


def _call(fn, args, evict):
    hist = args[10].copy()
    profile = args[11].copy()
    call = list(args)
    call[10] = hist
    call[11] = profile
    if evict is not None:
        evict.fill(1)
    t0 = time.perf_counter_ns()
    result = fn(*call)
    return time.perf_counter_ns() - t0, result, hist, profile


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frameset", default="/work/eval/rig", help="frame set folder (default: /work/eval/rig)")
    parser.add_argument("--frames", type=int, default=60, help="frames of the run (default: 60)")
    parser.add_argument("--against", default="main", help="git commit whose kernel to compare (default: main)")
    parser.add_argument("--rounds", type=int, default=7, help="replays of every call per variant (default: 7)")
    args = parser.parse_args()
    calls = _record(args.frameset, args.frames)
    print(f"{args.frameset}: {len(calls)} band_need calls recorded")
    with tempfile.TemporaryDirectory() as folder:
        against = _load_against(args.against, folder)
        differ = 0
        for inputs, *_ in calls:
            _, r_this, h_this, p_this = _call(K.band_need, inputs, None)
            _, r_ref, h_ref, p_ref = _call(against, inputs, None)
            same = r_this == r_ref and np.array_equal(h_this, h_ref) and np.array_equal(p_this, p_ref)
            differ += not same
        print(f"  outputs: {'identical' if differ == 0 else f'{differ} calls differ'} ({len(calls)} calls)")
        evict = np.zeros(4 << 20, np.uint8)
        for cold in (False, True):
            this_ns, ref_ns, paired = [], [], []
            for rnd in range(args.rounds):
                for k, (inputs, *_rest) in enumerate(calls):
                    order = (K.band_need, against) if (rnd + k) % 2 else (against, K.band_need)
                    t = {fn: _call(fn, inputs, evict if cold else None)[0] for fn in order}
                    this_ns.append(t[K.band_need])
                    ref_ns.append(t[against])
                    paired.append(t[against] - t[K.band_need])
            print(
                f"  {'cold' if cold else 'warm'}: this tree {np.median(this_ns) / 1e3:.2f} us, {args.against} "
                f"{np.median(ref_ns) / 1e3:.2f} us, median paired difference {np.median(paired) / 1e3:+.2f} us"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
