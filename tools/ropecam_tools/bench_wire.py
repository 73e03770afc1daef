"""Wire size per frame set: the bytes each FrameResult costs on the link, against a serial line's budget.

For each recorded frame set (e.g. `ropecam simulate PRESET --out DIR`) it reports the FrameResult messages as the
daemon sends them: the device pipeline's results (warmed up as the daemon warms it), `to_wire`, `encode_message`
with the stream's `ShapeHint`, the sender's shape tolerance (`[sender] shape_tolerance_px`) and its byte budget
(`[sender] frame_budget_bytes`: a frame over it goes with looser shapes or none, `ropecam.shared.protocol.budget`;
``--frame-budget-bytes 0`` measures without it), protocol version 2 (with the quality record); and the
COBS-framed bytes the serial link carries. The serial line's bytes per frame are ``baud / 10 / fps`` (8N1), 774 B
at 921600 baud and 119 FPS; ``cut`` counts the frames the sender's budget cut, ``over_budget`` those over the line's.

With ``--source truth`` (or ``both``) the frame set's true shapes go through the same encoder instead, resampled at
the pipeline's output step with Gaussian noise of ``--noise-px`` per coordinate (0.01 px: the device's shapes on
rig and rig-soft are that rough, p95 0.017 px from a smooth fit), both tips, the fixed end, the default material
points, stretch ratios and a quality record of five measures: what a scene costs once the device measures its
shapes right (the lab presets' shapes are not yet right: issue 19).

    python tools/bench.py wire-size sim/rig sim/rig-soft sim/lab [--source both] [--fps 119 --baud 921600]
    python tools/bench.py wire-size sim/rig-soft --first 6 --check     # exit 1 when a frame is over the budget
    python tools/bench.py wire-size sim/lab --config device.toml       # the device as `ropecam-device setup` set it
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from ropecam.device.daemon.config import SenderConfig
from ropecam.shared.protocol import FrameResult, ShapeHint
from ropecam.shared.protocol.budget import MIN_BUDGET_BYTES, encode_within_budget
from ropecam.shared.protocol.framing import frame as cobs_frame
from ropecam.shared.protocol.shapes import ShapeCodecConfig

_QUALITY = {
    "length_ratio": 1.002,
    "width_ratio": 0.98,
    "fixed_end_px": 0.4,
    "tip_separation_px": 9.7,
    "blur_evidence": 0.45,
}
"""The quality record of a typical measured frame (the device's five measures on rig-soft)."""


def budget_bytes(baud: float, fps: float) -> float:
    """Bytes per frame a serial line carries at `baud` (8N1: 10 bits per byte) and `fps` frames per second."""
    return baud / 10.0 / fps


def device_records(frameset: Path, first: int | None, config: Any = None) -> list[FrameResult]:
    """The FrameResult records the daemon sends for the frames of `frameset`, measured with `config` (a
    `PipelineConfig`; None: the default settings) and its plane calibration, as `extract` and the daemon use them."""
    from ropecam.device.capture.frameset import FrameSet
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.result import to_wire
    from ropecam_tools.bench_device import new_pipeline

    frames = FrameSet(frameset)
    pipeline = new_pipeline(config or PipelineConfig(), frames.image_size)
    pipeline.warm_up()
    records = []
    for k, (row, image) in enumerate(frames):
        if first is not None and k >= first:
            break
        records.append(to_wire(pipeline.process(image, row.frame, row.t_ns, row.exposure_us)))
    return records


def _resample(points: np.ndarray, step_px: float) -> np.ndarray:
    """`points` (n, 2) resampled at `step_px` along their arc length (both ends kept)."""
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    count = max(2, round(arc[-1] / step_px) + 1)
    s = np.linspace(0.0, arc[-1], count)
    return np.stack([np.interp(s, arc, points[:, 0]), np.interp(s, arc, points[:, 1])], axis=1)


def _at_fraction(points: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    s = fractions * arc[-1]
    return np.stack([np.interp(s, arc, points[:, 0]), np.interp(s, arc, points[:, 1])], axis=1)


def truth_records(frameset: Path, first: int | None, noise_px: float, seed: int = 0) -> list[FrameResult]:
    """FrameResult records carrying the true shapes of `frameset` as the device would fill them (see the module
    docstring)."""
    from ropecam.device.capture.frameset import FrameSet
    from ropecam.device.pipeline.config import PipelineConfig

    frames = FrameSet(frameset)
    truth = np.load(frameset / "truth.npz")
    config = PipelineConfig()
    s_m = np.asarray(config.material_points_m, np.float64)
    fractions = s_m / config.rope_length_m
    rng = np.random.default_rng(seed)
    fixed = tuple(float(v) for v in truth["fixed_end_px"])
    records = []
    for k, row in enumerate(frames.records):
        if first is not None and k >= first:
            break
        shapes = []
        for key in ("begin_px", "end_px"):
            shape = _resample(truth[key][k], config.output_step_px)
            shapes.append(shape + rng.normal(0.0, noise_px, shape.shape))
        begin, end = shapes
        records.append(
            FrameResult(
                frame_index=int(row.frame),
                exposure_start_t_ns=int(truth["t_begin_ns"][k]),
                exposure_end_t_ns=int(truth["t_end_ns"][k]),
                order_confidence=0.93,
                begin_px=begin,
                end_px=end,
                begin_tip_px=tuple(begin[-1]),
                end_tip_px=tuple(end[-1]),
                fixed_end_px=fixed,
                material_s_m=tuple(s_m),
                material_begin_px=_at_fraction(begin, fractions),
                material_end_px=_at_fraction(end, fractions),
                stretch_begin=1.0013,
                stretch_end=0.9991,
                pipeline_us=2400,
                quality=_QUALITY,
            )
        )
    return records


def wire_sizes(
    records: list[FrameResult], tolerance_px: float, frame_budget_bytes: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Encode `records` as one device stream (the sender's hint, tolerance and byte budget); return the message
    bytes, the COBS-framed bytes and the budget's cut (`encode_within_budget`, 0: as measured) of each."""
    hint = ShapeHint()
    config = ShapeCodecConfig(tolerance_px=tolerance_px)
    messages, framed, cuts = [], [], []
    for sequence, record in enumerate(records):
        message, cut = encode_within_budget(
            record, frame_budget_bytes, device_id=1, sequence=sequence, t_ns=record.exposure_end_t_ns + 2_000_000,
            shape_config=config, hint=hint,
        )  # fmt: skip
        messages.append(len(message))
        framed.append(len(cobs_frame(message)))
        cuts.append(cut)
    return np.array(messages), np.array(framed), np.array(cuts)


def report_row(
    label: str, source: str, records: list[FrameResult], tolerance_px: float, budget: float, frame_budget_bytes: int = 0
) -> dict:
    """Sizes of one frame set from one source."""
    messages, framed, cuts = wire_sizes(records, tolerance_px, frame_budget_bytes)
    statuses: dict[str, int] = {}
    for record in records:
        statuses[record.status.name] = statuses.get(record.status.name, 0) + 1
    worst = int(np.argmax(framed)) if len(framed) else -1
    cut_statuses: dict[str, int] = {}  # whether the budget cut frames the device reported OK
    for k in np.flatnonzero(cuts):
        cut_statuses[records[k].status.name] = cut_statuses.get(records[k].status.name, 0) + 1
    return {
        "set": label,
        "source": source,
        "frames": len(records),
        "mean_bytes": round(float(messages.mean()), 1) if len(messages) else None,
        "max_framed_bytes": int(framed.max()) if len(framed) else None,
        "worst_frame": int(records[worst].frame_index) if worst >= 0 else None,
        "over_budget": int(np.sum(framed > budget)),
        "cut": int(np.sum(cuts > 0)),
        "cut_frames": [int(records[k].frame_index) for k in np.flatnonzero(cuts)],
        "cut_statuses": cut_statuses,
        "first_6_framed": framed[:6].tolist(),
        "statuses": statuses,
    }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("framesets", nargs="+", metavar="FRAMESET", help="recorded frame sets (`ropecam simulate`)")
    parser.add_argument(
        "--source", choices=("device", "truth", "both"), default="device",
        help="device: the pipeline's results (default); truth: the true shapes (device-like noise); both",
    )  # fmt: skip
    parser.add_argument("--first", type=int, metavar="N", help="only the first N frames of each set")
    parser.add_argument("--noise-px", type=float, default=0.01, help="with truth: noise per coordinate (0.01 px)")
    parser.add_argument("--baud", type=float, default=921600.0, help="serial line rate (default 921600)")
    parser.add_argument("--fps", type=float, default=119.0, help="frame rate of the budget (default 119)")
    parser.add_argument(
        "--shape-tolerance-px", type=float,
        help="shape codec tolerance (default: --config's [sender] shape_tolerance_px, else the daemon's "
        f"{SenderConfig().shape_tolerance_px})",
    )  # fmt: skip
    parser.add_argument(
        "--frame-budget-bytes", type=int,
        help="the sender's byte budget per frame (default: --config's [sender] frame_budget_bytes, else the "
        f"daemon's {SenderConfig().frame_budget_bytes}; 0: none)",
    )  # fmt: skip
    parser.add_argument(
        "--config",
        metavar="TOML",
        help="measure the device with the [pipeline] table of this device.toml (`ropecam-device setup` writes it), "
        "with its plane_file and mask, as a set-up rig runs, and its [sender] table's shape tolerance and byte "
        "budget (default: the defaults, a fresh device)",
    )
    parser.add_argument("--method", default="blur_split", choices=("blur_split", "paper", "centerline"))
    parser.add_argument("--check", action="store_true", help="exit 1 when a framed message is over the budget")
    parser.add_argument("--json", action="store_true", help="print one JSON object per set and source")


def _sender_config(path: str | None) -> SenderConfig:
    """The [sender] table of the device.toml at `path` (its keys checked as the daemon checks them), else the
    daemon's defaults."""
    if not path:
        return SenderConfig()
    from ropecam.shared.config import from_mapping, read_toml
    from ropecam.shared.errors import RopecamError
    from ropecam_tools.cli import UsageError

    try:
        return from_mapping(SenderConfig, dict(read_toml(path).get("sender", {})), where=f"{path} [sender]")
    except (RopecamError, ValueError) as exc:
        raise UsageError(f"--config {path}: {exc}") from exc


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code (1: over the budget with --check)."""
    from ropecam_tools.bench_device import load_config
    from ropecam_tools.cli import UsageError

    if (
        args.frame_budget_bytes is not None
        and args.frame_budget_bytes != 0
        and args.frame_budget_bytes < MIN_BUDGET_BYTES
    ):
        raise UsageError(
            f"--frame-budget-bytes must be 0 (none) or >= {MIN_BUDGET_BYTES}, got {args.frame_budget_bytes}"
        )
    budget = budget_bytes(args.baud, args.fps)
    config = load_config(args)
    sender = _sender_config(args.config)
    if args.shape_tolerance_px is None:
        args.shape_tolerance_px = sender.shape_tolerance_px
    if args.frame_budget_bytes is None:
        args.frame_budget_bytes = sender.frame_budget_bytes
    sources = ("device", "truth") if args.source == "both" else (args.source,)
    rows: list[dict[str, Any]] = []
    for path in (Path(p) for p in args.framesets):
        for source in sources:
            if source == "device":
                records = device_records(path, args.first, config)
            else:
                records = truth_records(path, args.first, args.noise_px)
            row = report_row(path.name, source, records, args.shape_tolerance_px, budget, args.frame_budget_bytes)
            rows.append(row)
            if args.json:
                print(json.dumps({**row, "budget_bytes": round(budget, 1)}), flush=True)
            else:
                print(
                    f"{row['set']:<14} {source:<6} {row['frames']:>4} frames: mean {row['mean_bytes']} B, max "
                    f"{row['max_framed_bytes']} B framed (frame {row['worst_frame']}), {row['over_budget']} over the "
                    f"budget of {budget:.0f} B, {row['cut']} cut by the sender's budget {row['cut_frames']} "
                    f"{row['cut_statuses']}; first "
                    f"frames {row['first_6_framed']}",
                    flush=True,
                )
    if not args.json:
        print(
            f"budget: {args.baud:.0f} baud 8N1 at {args.fps:g} FPS; shape tolerance {args.shape_tolerance_px} px; "
            f"sender's budget {args.frame_budget_bytes} B; bytes: whole messages (header, payload, CRC); max: "
            "COBS-framed as on the serial line"
        )
    return 1 if args.check and any(row["over_budget"] for row in rows) else 0
