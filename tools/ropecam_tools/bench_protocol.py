"""Bytes per FrameResult on the rig scenario, and encode / decode time per message.

The rig scenario (`ropecam.host.sim.rig_polylines`): the paper's 0.411 m rope swinging down from horizontal, 119 FPS,
4 ms exposure, the paper's camera 1.5 m from the plane; each frame carries both shapes (~400 points each, ~0.02 px
noise), both tips, the fixed end, 4 material points on both shapes, stretch ratios and timings. Encoding keeps a
`ShapeHint` across frames as the device's sender does. Every message is timed on its own; the times reported are
medians over all messages of --repeats runs: robust to other processes on a shared machine (whose scheduler
time slices, ~4 ms, land on a few messages whatever they cost).

    python tools/bench.py protocol [--frames 119] [--noise uniform|gaussian|none] [--repeats 5] [--json]
    python tools/bench.py protocol --frameset sim/rig      # the device pipeline's real output on recorded frames
    python tools/bench.py protocol --frameset sim/rig --output-smoothing-px 0   # ... without output smoothing

With --frameset, the FrameResults are what the device pipeline measures on a recorded frame set (e.g. from
`ropecam simulate rig`), converted exactly as the daemon converts them; then each message is timed as the daemon
spends it after the pipeline: `to_wire`, `encode_message` (shape coder, header, CRC) and the serial link's COBS
`frame` ("daemon per frame"; the "encode" figure is `encode_message` alone, as without --frameset).

Besides sizes and times it reports the shapes' roughness: the distance of every device point to a least-squares
cubic spline with a knot every ~20 px (p95 and max). A rope has no wiggles at that scale, so this is measurement
noise; every point the spline coder cannot reach within 0.05 px costs a correction (mean per shape, reported).
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import time
from typing import Any

import numpy as np

from ropecam.device.daemon.config import SenderConfig
from ropecam.host.sim.stream import rig_frame_results
from ropecam.shared.protocol import FrameResult, ShapeHint, decode_message, encode_message
from ropecam.shared.protocol._kernels import fit_bspline, sample_bspline
from ropecam.shared.protocol.framing import frame
from ropecam.shared.protocol.shapes import MAX_CONTROL_POINTS, ShapeCodecConfig, polyline_distances_px
from ropecam.shared.protocol.wire import CRC_BYTES, HEADER_BYTES

SERIAL_BUDGET_BYTES = 921600 / 10 / 119  # 8N1: 10 bits per byte


def build_records(count: int, noise: str, seed: int) -> list[FrameResult]:
    """FrameResults as the device would fill them for `count` rig frames (`host.sim.stream.rig_frame_results`)."""
    return rig_frame_results(count, seed=seed, noise=noise, stretch_wobble=0.002)


def pipeline_results(frameset: str, rope_length_m: float, output_smoothing_px: float | None) -> list[Any]:
    """The device pipeline's results over a recorded frame set (copied out of its buffers), frames with both
    shapes only."""
    from ropecam.device.capture.frameset import FrameSet
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.host.compare.measurement import default_points

    frames = FrameSet(frameset)
    points = tuple(default_points(rope_length_m))
    options = {} if output_smoothing_px is None else {"output_smoothing_px": output_smoothing_px}
    config = PipelineConfig(rope_length_m=rope_length_m, material_points_m=points, **options)
    pipeline = Pipeline(config, frames.image_size)
    # The result's arrays are views into the pipeline's buffers, valid until its next call: copied at once.
    results = [copy.deepcopy(pipeline.process(image, r.frame, r.t_ns, r.exposure_us)) for r, image in frames]
    return [r for r in results if r.begin is not None and r.end is not None]


def daemon_stream(
    results: list[Any], hint: ShapeHint, shape_config: ShapeCodecConfig | None = None
) -> tuple[list[bytes], dict[str, list[float]]]:
    """Do per result what the daemon does after the pipeline (`to_wire`, `encode_message` with the stream's hint,
    the serial link's COBS `frame`) and return the messages and the seconds of each step per message."""
    from ropecam.device.pipeline.result import to_wire

    out: list[bytes] = []
    seconds: dict[str, list[float]] = {"to_wire": [], "encode": [], "frame": [], "total": []}
    for sequence, result in enumerate(results):
        start = time.perf_counter()
        record = to_wire(result)
        converted = time.perf_counter()
        t_ns = record.exposure_end_t_ns + 2_000_000
        options = {"hint": hint, "shape_config": shape_config}
        message = encode_message(record, device_id=1, sequence=sequence, t_ns=t_ns, pack_options=options)
        encoded = time.perf_counter()
        frame(message)
        framed = time.perf_counter()
        out.append(message)
        for key, value in (
            ("to_wire", converted - start),
            ("encode", encoded - converted),
            ("frame", framed - encoded),
            ("total", framed - start),
        ):
            seconds[key].append(value)
    return out, seconds


def roughness_px(points: np.ndarray, knot_spacing_px: float = 20.0) -> np.ndarray:
    """Distance of each point (n, 2) to a least-squares cubic B-spline with a knot every ~`knot_spacing_px`."""
    t = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    length = t[-1]
    if length <= 0.0 or len(points) < 8:
        return np.zeros(len(points))
    m = int(min(MAX_CONTROL_POINTS, len(points) // 2, max(4, round(length / knot_spacing_px) + 3)))
    control = np.empty((m, 2))
    if fit_bspline(points, t / length, m, np.empty(4), np.empty((m, m)), control) != m:
        return np.zeros(len(points))
    dense = np.empty((8 * len(points), 2))
    sample_bspline(control, np.empty(4), dense)
    return polyline_distances_px(points, dense)


def roughness_stats(records: list[FrameResult]) -> dict[str, float]:
    """Roughness (p95, max) of all shapes."""
    distances = np.concatenate([roughness_px(s) for r in records for s in (r.begin_px, r.end_px) if s is not None])
    return {
        "roughness_p95_px": round(float(np.percentile(distances, 95)), 4),
        "roughness_max_px": round(float(distances.max()), 4),
    }


def encode_stream(
    records: list[FrameResult], hint: ShapeHint | None = None, shape_config: ShapeCodecConfig | None = None
) -> tuple[list[bytes], list[float]]:
    """Encode all records as one device stream (`hint`: the stream's encoder memory, a fresh one by default;
    `shape_config`: the shape codec's tolerance, its default when None); return the messages and the seconds each
    one took."""
    hint = hint if hint is not None else ShapeHint()
    out, seconds = [], []
    for sequence, record in enumerate(records):
        t_ns = record.exposure_end_t_ns + 2_000_000
        options = {"hint": hint, "shape_config": shape_config}
        start = time.perf_counter()
        out.append(encode_message(record, device_id=1, sequence=sequence, t_ns=t_ns, pack_options=options))
        seconds.append(time.perf_counter() - start)
    return out, seconds


def decode_stream(messages: list[bytes]) -> tuple[list[FrameResult], list[float]]:
    """Decode every message; return the records and the seconds each one took."""
    out, seconds = [], []
    for message in messages:
        start = time.perf_counter()
        out.append(decode_message(message).record)
        seconds.append(time.perf_counter() - start)
    return out, seconds


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--frames", type=int, default=119, help="frames of the swing (default 119 = 1 s)")
    parser.add_argument(
        "--noise",
        choices=("uniform", "gaussian", "none"),
        default="uniform",
        help="device polyline noise: uniform in +-0.02 px (default), gaussian sigma 0.02 px, none",
    )
    parser.add_argument("--repeats", type=int, default=5, help="timing runs; the median is reported (default 5)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--shape-tolerance-px", type=float, default=SenderConfig().shape_tolerance_px,
        help="shape codec tolerance (default: the daemon's [sender] shape_tolerance_px, %(default)s)",
    )  # fmt: skip
    parser.add_argument("--frameset", help="measure the device pipeline's output on this recorded frame set instead")
    parser.add_argument("--rope-length-m", type=float, default=0.411, help="with --frameset (default 0.411)")
    parser.add_argument(
        "--output-smoothing-px",
        type=float,
        help="with --frameset: the pipeline's output_smoothing_px (default: the PipelineConfig default; 0 = off)",
    )


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""

    results: list[Any] = []
    if args.frameset:
        from ropecam.device.pipeline.result import to_wire

        results = pipeline_results(args.frameset, args.rope_length_m, args.output_smoothing_px)
        records = [to_wire(r) for r in results]
        args.frames, args.noise = len(records), f"pipeline output on {args.frameset}"
    else:
        records = build_records(args.frames, args.noise, args.seed)
    shape_config = ShapeCodecConfig(tolerance_px=args.shape_tolerance_px)
    encode_s: list[float] = []
    decode_s: list[float] = []
    daemon_s: dict[str, list[float]] = {}
    messages: list[bytes] = []
    hint = ShapeHint()
    for _ in range(args.repeats):
        hint = ShapeHint()
        if results:
            messages, steps = daemon_stream(results, hint, shape_config)
            encode_s += steps["encode"]
            for key, values in steps.items():
                daemon_s.setdefault(key, []).extend(values)
        else:
            messages, seconds = encode_stream(records, hint, shape_config)
            encode_s += seconds
        decoded, seconds = decode_stream(messages)
        decode_s += seconds
    sizes = np.array([len(m) for m in messages])
    errors = []
    for record, back in zip(records, decoded, strict=True):
        for a, b in ((record.begin_px, back.begin_px), (record.end_px, back.end_px)):
            errors.append(max(float(np.max(polyline_distances_px(a, b))), float(np.hypot(*(a[-1] - b[-1])))))
    result = {
        "frames": args.frames,
        "noise": args.noise,
        "mean_bytes_per_frame_result": round(float(sizes.mean()), 1),
        "max_bytes": int(sizes.max()),
        "header_and_crc_bytes": HEADER_BYTES + CRC_BYTES,
        "serial_budget_bytes": round(SERIAL_BUDGET_BYTES, 1),
        "mean_points_per_shape": round(float(np.mean([len(r.begin_px) for r in records])), 1),
        "max_shape_error_px": round(max(errors), 4),
        **roughness_stats(records),
        "corrections_per_shape": round(hint.corrections_sent / max(1, hint.shapes_coded), 2),
        "encode_us_per_message": round(statistics.median(encode_s) * 1e6, 1),
        "decode_us_per_message": round(statistics.median(decode_s) * 1e6, 1),
        "repeats": args.repeats,
    }
    if daemon_s:
        # The device's whole per-frame cost after the pipeline, and its steps (medians per message).
        for key, values in daemon_s.items():
            result[f"daemon_{key}_us_per_message"] = round(statistics.median(values) * 1e6, 1)
    if args.json:
        print(json.dumps(result))
    else:
        print(f"rig scenario, {args.frames} frames, {args.noise} noise, {result['mean_points_per_shape']} points/shape")
        print(
            f"  FrameResult: mean {result['mean_bytes_per_frame_result']} B, max {result['max_bytes']} B "
            f"(header + CRC {result['header_and_crc_bytes']} B; serial budget {result['serial_budget_bytes']} B)"
        )
        print(f"  worst shape error {result['max_shape_error_px']} px (tolerance {args.shape_tolerance_px} px)")
        print(f"  shape roughness (distance to a smooth fit) p95 {result['roughness_p95_px']} px, "
              f"max {result['roughness_max_px']} px; {result['corrections_per_shape']} corrections/shape")  # fmt: skip
        print(f"  encode {result['encode_us_per_message']} us/message, "
              f"decode {result['decode_us_per_message']} us/message (medians over {args.repeats} runs)")  # fmt: skip
        if daemon_s:
            steps = {key: result[f"daemon_{key}_us_per_message"] for key in daemon_s}
            print(f"  daemon per frame: to_wire + encode + COBS frame {steps['total']} us (to_wire "
                  f"{steps['to_wire']}, encode {steps['encode']}, frame {steps['frame']} us; medians)")  # fmt: skip
    return 0
