"""Where `split_frame`'s time goes inside the pipeline: its phases timed by the CPU's time-stamp counter.

A copy of `split_frame` with a time stamp between its phases (`_phases` below: the same kernels in the same order,
checked against the real kernel on every call: the "mismatches" count must be 0) replaces nothing: the
pipeline's `split_frame` calls are intercepted, and for each the copy runs first (cold: as the pipeline would run
it, after the frame's edges and contour and, between frames, ``cv2.Canny`` on the whole frame as in
`bench_device.py`), then again at once (warm), then the real kernel (whose result the pipeline gets). The real
kernel is also timed as called (cold) and at once again (warm), dispatch included. Medians per frame (us):

    taskset -c 1 python tools/bench_split_phases.py [--frameset DIR] [--frames 60] [--passes 2]

The copy mirrors `_kernels/split_frame.py` and `split_shapes_local` (`_kernels/offsets.py`); when either changes,
change `_phases` too (a mismatch count above 0 says it differs). The time stamps are fenced (``rdtsc`` between
two full fences), which adds ~0.1 us per phase; the phases of one call add up to more than the kernel alone.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._kernels.canny import smooth_box
from ropecam.device.pipeline._kernels.geometry import find_segmentation_points_seg
from ropecam.device.pipeline._kernels.offsets import (
    dense_end_points,
    offset_by_table_thinned,
    side_sweeps,
    side_sweeps_indexed,
    slope_sweep_median,
)
from ropecam.device.pipeline._kernels.polylines import (
    anchor_start,
    extend_to_band_end_near,
    polyline_length,
    resample_polyline_of_length,
)
from ropecam.device.pipeline._kernels.smoothing import smooth_polyline
from ropecam.device.pipeline._kernels.split_frame import _SLOPE_HIGH, _SLOPE_LOW
from ropecam.device.pipeline._kernels.split_shapes import SPLIT_PARAMS
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline

PHASES = (
    "segmentation points",
    "corner box smoothed",
    "sweep from the slope",
    "side sweeps x2",
    "offsets x2",
    "tip fits x2",
    "slant, lengths",
    "anchoring x2",
    "lengths x2",
    "resample A",
    "smooth A",
    "resample B",
    "smooth B",
)
"""The phases of `_phases`, in order (stamps 0..13)."""


@intrinsic
def _rdtsc(typingctx: Any) -> Any:
    """The time-stamp counter (cycles at the nominal clock), between two full fences."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        builder.fence("seq_cst")
        function = builder.module.declare_intrinsic("llvm.readcyclecounter", fnty=ir.FunctionType(ir.IntType(64), []))
        value = builder.call(function, [])
        builder.fence("seq_cst")
        return value

    return types.int64(), codegen


@njit(nogil=True, error_model="numpy")
def _phases(
    points, chain, mag, gx, gy, frame, weights, spans_lo, spans_hi, box_lo, box_hi, tmp, smooth, params, state,
    curves, table, sweep_index, lines, sides, scratch, turn, idx, out_seg, out_info, stamps,
):  # fmt: skip
    """`split_frame` with `stamps[k]` taken before phase k (0 where a phase did not run); same returns."""
    stamps[:] = 0
    stamps[0] = _rdtsc()
    n = np.int32(state[5])
    width = params[8]
    fixed_r = np.float32(state[0])
    fixed_c = np.float32(state[1])
    search = np.float32(max(params[SPLIT_PARAMS + 2], 1.2 * state[4]))
    found = find_segmentation_points_seg(
        points, n, np.int32(params[SPLIT_PARAMS]), fixed_r, fixed_c, search, np.int32(params[SPLIT_PARAMS + 1]),
        np.float32(params[SPLIT_PARAMS + 3]), scratch[1], turn, lines[0], scratch[2], idx,
    )  # fmt: skip
    stamps[1] = _rdtsc()
    out_info[6] = -1.0
    if found < 0:
        return K.SPLIT_STATIC
    i_fix = idx[0]
    seg_a = idx[1]
    seg_b = idx[3]
    ar = np.float64(points[seg_a, 0])
    ac = np.float64(points[seg_a, 1])
    br = np.float64(points[seg_b, 0])
    bc = np.float64(points[seg_b, 1])
    grow = params[SPLIT_PARAMS + 4]
    height = smooth.shape[0]
    cols = smooth.shape[1]
    smooth_box(
        frame, weights, spans_lo, spans_hi, max(0, math.floor(min(ar, br) - grow)),
        min(height - 1, math.ceil(max(ar, br) + grow)), max(0, math.floor(min(ac, bc) - grow)),
        min(cols - 1, math.ceil(max(ac, bc) + grow)), box_lo, box_hi, tmp, smooth,
    )  # fmt: skip
    stamps[2] = _rdtsc()
    out_seg[0, 0] = points[seg_a, 0]
    out_seg[0, 1] = points[seg_a, 1]
    out_seg[1, 0] = points[seg_b, 0]
    out_seg[1, 1] = points[seg_b, 1]
    sweep = math.hypot(ar - br, ac - bc)
    contrast = state[3]
    if sweep < 1.5 * width and contrast >= 5.0:
        total = 0.0
        count = 0
        for side in range(2):
            median = slope_sweep_median(
                chain, n, i_fix, seg_a if side == 0 else seg_b, np.int32(1 if side == 0 else -1), mag, _SLOPE_LOW,
                _SLOPE_HIGH, np.float32(contrast), curves[0], curves[1], scratch[2],
            )  # fmt: skip
            if math.isfinite(median):
                total += median
                count += 1
        if count > 0:
            sweep = min(total if count == 1 else total / 2.0, 1.5 * width)
    out_info[6] = sweep
    stamps[3] = _rdtsc()
    if sweep < params[SPLIT_PARAMS + 5] * width:
        return K.SPLIT_STATIC
    # `split_shapes_packed_near` -> `split_shapes_local`, step by step.
    inv_contrast = np.float32(1.0 / contrast)
    polarity = np.float32(state[2])
    half = np.int32(params[0])
    step_px = np.float32(params[1])
    width_px = np.float32(params[2])
    cap_px = np.float32(params[3])
    skip_px = np.float32(params[4])
    span_px = np.float32(params[5])
    blur_px = np.float32(params[6])
    slant_gain_px = params[7]
    out_step_px = np.float32(params[9])
    smoothing_px = np.float32(params[10])
    side_a, side_b, out_a, out_b = sides[0], sides[1], sides[2], sides[3]
    plus = np.int32(1)
    minus = np.int32(-1)
    if sweep_index.shape[0] >= 2:
        side_sweeps_indexed(chain, n, i_fix, seg_a, plus, mag, inv_contrast, curves[0], curves[1], sweep_index, half,
                            lines[0], lines[1])  # fmt: skip
        side_sweeps_indexed(chain, n, i_fix, seg_b, minus, mag, inv_contrast, curves[0], curves[1], sweep_index, half,
                            lines[0], lines[2])  # fmt: skip
    else:
        side_sweeps(chain, n, i_fix, seg_a, plus, mag, inv_contrast, curves[0], curves[1], half, lines[0], lines[1])
        side_sweeps(chain, n, i_fix, seg_b, minus, mag, inv_contrast, curves[0], curves[1], half, lines[0], lines[2])
    stamps[4] = _rdtsc()
    keep = dense_end_points(skip_px, span_px)
    na = offset_by_table_thinned(
        points, chain, n, i_fix, seg_a, plus, gx, gy, polarity, lines[1], step_px, table, keep, keep, side_a
    )
    nb = offset_by_table_thinned(
        points, chain, n, i_fix, seg_b, minus, gx, gy, polarity, lines[2], step_px, table, keep, keep, side_b
    )
    stamps[5] = _rdtsc()
    na = extend_to_band_end_near(
        side_a, na, points, n, smooth, width_px, cap_px, skip_px, span_px, blur_px, scratch[1], fixed_r, fixed_c
    )
    nb = extend_to_band_end_near(
        side_b, nb, points, n, smooth, width_px, cap_px, skip_px, span_px, blur_px, scratch[1], fixed_r, fixed_c
    )
    stamps[6] = _rdtsc()
    if na >= 3 and nb >= 3:
        a1r = float(side_a[na - 1, 0])
        a1c = float(side_a[na - 1, 1])
        b1r = float(side_b[nb - 1, 0])
        b1c = float(side_b[nb - 1, 1])
        u_r = a1r - float(side_a[na - 3, 0]) + b1r - float(side_b[nb - 3, 0])
        u_c = a1c - float(side_a[na - 3, 1]) + b1c - float(side_b[nb - 3, 1])
        norm = math.sqrt(u_r * u_r + u_c * u_c)
        if norm > 0.0 and slant_gain_px > 0:
            u_r = u_r / norm
            u_c = u_c / norm
            d_r = b1r - a1r
            d_c = b1c - a1c
            along = d_r * u_r + d_c * u_c
            across = abs(d_r * u_c - d_c * u_r)
            if not across - 2.0 * slant_gain_px < 1.0:
                shift = min(max(along / (across - 2.0 * slant_gain_px), -1.5), 1.5) * slant_gain_px
                side_a[na - 1, 0] = side_a[na - 1, 0] - np.float32(shift * u_r)
                side_a[na - 1, 1] = side_a[na - 1, 1] - np.float32(shift * u_c)
                side_b[nb - 1, 0] = side_b[nb - 1, 0] + np.float32(shift * u_r)
                side_b[nb - 1, 1] = side_b[nb - 1, 1] + np.float32(shift * u_c)
    len_a = polyline_length(side_a, na)
    len_b = polyline_length(side_b, nb)
    out_info[2] = len_a
    out_info[3] = len_b
    stamps[7] = _rdtsc()
    if abs(len_a - len_b) > max(3.0 * params[8], 0.1 * max(len_a, len_b)):
        return K.NOT_FOUND
    na = anchor_start(side_a, na, fixed_r, fixed_c, skip_px, span_px)
    nb = anchor_start(side_b, nb, fixed_r, fixed_c, skip_px, span_px)
    stamps[8] = _rdtsc()
    len_a = polyline_length(side_a, na)
    len_b = polyline_length(side_b, nb)
    out_info[2] = len_a
    out_info[3] = len_b
    stamps[9] = _rdtsc()
    k = 10
    for side in range(2):
        poly = side_a if side == 0 else side_b
        out = out_a if side == 0 else out_b
        count = resample_polyline_of_length(
            poly, na if side == 0 else nb, len_a if side == 0 else len_b, out_step_px, out
        )
        stamps[k] = _rdtsc()
        if count < 0:
            return K.FULL
        out_info[side] = count
        out_info[4 + side] = 0.0
        if smoothing_px > 0.0 and count >= 3:
            if smooth_polyline(out, count, smoothing_px, scratch[0], poly) < 0:
                return K.INVALID
            out_info[4 + side] = 1.0
        stamps[k + 1] = _rdtsc()
        k += 2
    return 2


def _cycles_per_us() -> float:
    """The time-stamp counter's rate, measured over 0.2 s."""
    counter = njit(lambda: _rdtsc())
    counter()
    a, t0 = counter(), time.perf_counter()
    time.sleep(0.2)
    b, t1 = counter(), time.perf_counter()
    return (b - a) / (t1 - t0) / 1e6


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frameset", help="frame set folder (default: the synthetic rig frames of bench_device)")
    parser.add_argument("--frames", type=int, default=60, help="frames per pass (default: %(default)s)")
    parser.add_argument("--passes", type=int, default=2, help="timed passes (after one untimed; default 2)")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_device import frameset_frames, rig_frames

    frames = frameset_frames(args.frameset, args.frames) if args.frameset else rig_frames(args.frames)
    height, width = frames[0][0].shape
    kernel = K.split_frame
    stamps = np.zeros(len(PHASES) + 1, np.int64)
    cold: list[np.ndarray] = []
    warm: list[np.ndarray] = []
    whole: list[tuple[float, float]] = []
    mismatches = [0, 0]

    def intercepted(*call: Any) -> int:
        status = _phases(*call, stamps)
        cold.append(stamps.copy())
        _phases(*call, stamps)
        warm.append(stamps.copy())
        info, sides = call[-1].copy(), call[19].copy()
        t0 = time.perf_counter_ns()
        result = kernel(*call)
        t1 = time.perf_counter_ns()
        kernel(*call)
        whole.append(((t1 - t0) / 1000, (time.perf_counter_ns() - t1) / 1000))
        mismatches[0] += 1
        if result != status or not np.array_equal(info, call[-1]) or not np.array_equal(sides, call[19]):
            mismatches[1] += 1
        return result

    K.split_frame = intercepted
    try:
        for index in range(args.passes + 1):
            if index == 1:
                cold.clear()
                warm.clear()
                whole.clear()
            pipeline = Pipeline(PipelineConfig(), (width, height))
            pipeline.one_call = (
                False  # the kernels one by one: a steady frame's one call (`steady_frame`) would hide them
            )
            for i, (image, t_ns, exposure_us) in enumerate(frames):
                pipeline.process(image, i, t_ns, exposure_us)
                cv2.Canny(image, 20, 50, L2gradient=True)
    finally:
        K.split_frame = kernel
    rate = _cycles_per_us()
    full = [k for k, row in enumerate(cold) if row[len(PHASES)] > 0]
    source = args.frameset or "synthetic rig frames"
    if not full:
        print(
            f"{source}: no split_frame call made both shapes in {len(frames)} frames ({len(cold)} calls): the "
            "steady split starts once the contrast is known (about frame 10); give more --frames",
            file=sys.stderr,
        )
        return 2
    c = np.diff(np.array([cold[k] for k in full]), axis=1) / rate
    w = np.diff(np.array([warm[k] for k in full]), axis=1) / rate
    print(f"{source}: {len(cold)} split_frame calls, {len(full)} with both shapes, copy mismatches "
          f"{mismatches[1]} of {mismatches[0]} calls checked; us per call, medians (cold / warm)")  # fmt: skip
    for k, name in enumerate(PHASES):
        print(f"  {name:22s} {np.median(c[:, k]):7.2f} {np.median(w[:, k]):7.2f}")
    print(f"  {'phases in all':22s} {np.median(c.sum(axis=1)):7.2f} {np.median(w.sum(axis=1)):7.2f}")
    times = np.array(whole)
    print(f"  {'split_frame itself':22s} {np.median(times[:, 0]):7.2f} {np.median(times[:, 1]):7.2f}")
    return 0 if mismatches[1] == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
