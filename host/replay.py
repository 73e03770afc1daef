"""`ropecam replay`: feed a recording's raw wire channel through the live path again (statistics, decoding, recording).

Each recorded message re-enters `Session.handle` with its recorded receive time, so the statistics and every decoded
channel of a new recording (``--record``) come out exactly as the live ones did.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ropecam.host.monitor.cli import recording_parts_to_replace
from ropecam.host.offline import frames_messages
from ropecam.host.recording.encoding import add_encoding_option
from ropecam.host.recording.reader import count_raw, device_frames, iter_raw, recording_parts
from ropecam.shared.cli import declare_outputs
from ropecam.shared.errors import ConfigError, DataError, UsageError

if TYPE_CHECKING:
    from ropecam.host.model_overlay import ModelOverlay
    from ropecam.host.session import Session
    from ropecam.shared.protocol.wire import Message

__all__ = ["register", "replay", "replay_messages"]


def replay(
    paths: Sequence[Path],
    session: Session,
    speed: float | None = None,
    progress: Callable[[int], None] | None = None,
    on_message: Callable[[Message], None] | None = None,
) -> int:
    """Run every raw message of the recording `paths` through `session`; return the count (see `replay_messages`)."""
    return replay_messages(iter_raw(paths), session, speed, progress, on_message)


def replay_messages(
    messages: Iterable[tuple[bytes, int]],
    session: Session,
    speed: float | None = None,
    progress: Callable[[int], None] | None = None,
    on_message: Callable[[Message], None] | None = None,
) -> int:
    """Run raw wire messages (bytes, receive time ns) through `session` (a `ropecam.host.session.Session`), as the
    live receiver does; return the count.

    Parameters
    ----------
    speed
        1.0 replays in real time (2.0 twice as fast); None as fast as possible.
    progress
        Called with the number of messages done (optional).
    on_message
        Called with every message the session decoded (optional).
    """
    from ropecam.host.receiver import check_packet

    count = 0
    first_t_ns = None
    start = time.monotonic()
    for data, receive_t_ns in messages:
        if speed is not None:
            first_t_ns = receive_t_ns if first_t_ns is None else first_t_ns
            delay = start + (receive_t_ns - first_t_ns) / 1e9 / speed - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        message = session.handle(check_packet(data, receive_t_ns))
        if message is not None and on_message is not None:
            on_message(message)
        count += 1
        if count % 64 == 0:
            session.tick()
            if progress is not None:
                progress(count)
    if progress is not None:
        progress(count)
    return count


class _JsonlExport:
    """Write one device's FrameResults as `ropecam-device extract` JSON lines (input of `ropecam compare`)."""

    def __init__(self, path: Path, device_id: int | None, overwrite: bool) -> None:
        try:
            self._handle = open(path, "w" if overwrite else "x", encoding="utf-8")  # noqa: SIM115  (closed in close)
        except FileExistsError as exc:
            raise UsageError(f"{path} exists; choose another --export-jsonl or pass --force") from exc
        except OSError as exc:
            raise ConfigError(f"cannot write {path}: {exc.strerror or exc}") from exc
        self.path = path
        self.device_id = device_id
        self.frames = 0
        self.other_devices: set[int] = set()

    def add(self, message: Message) -> None:
        import json

        from ropecam.shared.protocol.jsonl import frame_result_json
        from ropecam.shared.protocol.records import FrameResult

        if not isinstance(message.record, FrameResult):
            return
        device_id = message.header.device_id
        if self.device_id is None:
            self.device_id = device_id
        if device_id != self.device_id:
            self.other_devices.add(device_id)
            return
        self._handle.write(json.dumps(frame_result_json(message.record), separators=(",", ":")) + "\n")
        self.frames += 1

    def close(self) -> None:
        self._handle.close()

    def summary(self) -> str:
        text = f"exported {self.frames} frames of device {self.device_id} to {self.path}"
        if self.other_devices:
            text += f" (devices {sorted(self.other_devices)} left out: choose with --device)"
        return text


def _fit_model(
    messages: Callable[[], Iterable[tuple[bytes, int]]], label: str, args: argparse.Namespace, calibration: tuple
) -> tuple[ModelOverlay, int]:
    """First pass over the recording: one device's FrameResults -> `ModelOverlay.fit` (release time, model run)."""
    import sys

    from ropecam.host.model.cli import load_model_config
    from ropecam.host.model_overlay import ModelOverlay
    from ropecam.host.progress import fit_progress

    rope, solver = load_model_config(Path(args.model))
    ordered, device_id = device_frames(messages(), args.device)
    if device_id is None:
        raise DataError(f"{label} holds no FrameResult: nothing to compare with the model")
    print(f"device {device_id}: {len(ordered)} frames; fitting the release time of the model", file=sys.stderr)

    overlay = ModelOverlay.fit(
        ordered, calibration, rope, solver, release_time_s=args.release_time_s, progress=fit_progress()
    )
    newline = "\n" if sys.stderr.isatty() else ""  # ends the progress line rewritten in place
    print(
        f"{newline}release at {overlay.release_time_s:.6f} s (device clock); "
        f"RMS error {overlay.rms_error_m * 1e3:.3f} mm",
        file=sys.stderr,
    )
    return overlay, device_id


def _export_csv(
    messages: Callable[[], Iterable[tuple[bytes, int]]], label: str, args: argparse.Namespace, calibration: tuple
) -> str:
    """Write one device's measured material points in metres (`ropecam.host.compare.table`); return a summary."""
    from ropecam.host.compare.cli import parse_points
    from ropecam.host.compare.measurement import default_points, measured_frame, tracks_from_frames
    from ropecam.host.compare.table import sample_table, write_table
    from ropecam.host.model.cli import load_model_config

    if args.rope_length_m is not None:
        length_m = args.rope_length_m
    elif args.model is not None:
        length_m = load_model_config(Path(args.model))[0].length_m
    else:
        raise ConfigError("--export-csv needs the rope's length: --rope-length-m (or --model rope.toml)")
    if not length_m > 0:
        raise ConfigError(f"--rope-length-m must be > 0 m, got {length_m}")
    points = parse_points(args.points) or default_points(length_m)
    ordered, device_id = device_frames(messages(), args.device)
    if device_id is None:
        raise DataError(f"{label} holds no FrameResult: no material points to export")
    skipped: list[str] = []
    tracks, _ = tracks_from_frames([measured_frame(f) for f in ordered], *calibration, points, length_m, skipped)
    written = write_table(sample_table(tracks), Path(args.export_csv))
    measured = int(tracks.measured.sum())
    return (
        f"exported {measured} measured material-point samples of device {device_id} ({len(ordered)} frames, "
        f"{len(points)} points) to {', '.join(str(p) for p in written)}"
        + (f"; {len(skipped)} shapes off the plane left empty" if skipped else "")
    )


def _speed(text: str) -> float | None:
    if text == "max":
        return None
    try:
        value = float(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--speed must be a positive number or 'max', got {text!r}") from exc
    if not value > 0:
        raise argparse.ArgumentTypeError(f"--speed must be a positive number or 'max', got {text!r}")
    return value


def _run(args: argparse.Namespace) -> int:
    from ropecam.host.monitor.cli import load_calibration, rig_metadata
    from ropecam.host.monitor.display import format_row
    from ropecam.host.progress import progress_bar
    from ropecam.host.recording.proto import make_encoder
    from ropecam.host.recording.writer import Recorder, RecordingConfig
    from ropecam.host.session import Session

    if args.reprocess and args.plane is None:
        raise ConfigError("--reprocess needs --plane (and optionally --camera): the calibration to apply")
    if args.export_csv and args.plane is None:
        raise ConfigError("--export-csv needs --plane (and optionally --camera): the calibration to metres")
    if args.model is not None and (args.plane is None or not args.record):
        raise ConfigError("--model needs --plane (the model lives in metres) and --record (where its channels go)")
    if (args.recording is None) == (args.frames is None):
        raise ConfigError("give either a recording (run.mcap) or --frames DIR, not both or neither")
    calibration, calibration_metadata, attachments = load_calibration(args.camera, args.plane)
    encoder = make_encoder(args.encoding)
    if args.frames is not None:
        source = Path(args.frames)
        measured = frames_messages(source, Path(args.config) if args.config else None)
        parts: list[Path] = []

        def messages() -> Iterable[tuple[bytes, int]]:
            return iter(measured)

        total = len(measured)
    else:
        source = Path(args.recording)
        parts = recording_parts(source)

        def messages() -> Iterable[tuple[bytes, int]]:
            return iter_raw(parts)

        total = count_raw(parts)
    # Everything that can fail comes before the output files are created: a refused option or a model that cannot
    # be fitted leaves no empty or broken file behind.
    record_path = Path(args.record) if args.record else None
    exports = (
        Path(args.export_jsonl) if args.export_jsonl else None,
        Path(args.export_csv) if args.export_csv else None,
    )
    for target in (record_path, *exports):
        if target is not None and target.resolve() in {p.resolve() for p in parts}:
            raise ConfigError(f"{target} is the recording being replayed; choose another file")
    csv_summary = _export_csv(messages, str(source), args, calibration) if args.export_csv else None
    model = None
    if args.model is not None:
        overlay, model_device = _fit_model(messages, str(source), args, calibration)
        model = lambda record, device_id: overlay if device_id == model_device else None  # noqa: E731
    export = _JsonlExport(Path(args.export_jsonl), args.device, args.force) if args.export_jsonl else None
    recorder = None
    if record_path is not None:
        metadata = rig_metadata(f"replay of {source}") | calibration_metadata
        try:
            recorder = Recorder(RecordingConfig(record_path, overwrite=args.force), metadata, attachments)
        except ConfigError:
            if export is not None:
                export.close()
                export.path.unlink(missing_ok=True)  # created just now, holds nothing
            raise
    session = Session(recorder, calibration, model, encoder)
    try:
        with progress_bar("replay", max(1, total), "messages") as progress:
            count = replay_messages(
                messages(), session, args.speed, progress, on_message=export.add if export else None
            )
    finally:
        session.close()
        if export is not None:
            export.close()
    print(f"replayed {count} messages from {', '.join(str(p) for p in parts) or f'{source} (measured now)'}")
    for row in session.snapshot(session.stats.last_receive_t_ns):
        print(format_row(row))
    if session.stats.bad_packets:
        print(f"{session.stats.bad_packets} unreadable packets")
    if export is not None:
        print(export.summary())
    if csv_summary is not None:
        print(csv_summary)
    if recorder is not None:
        if recorder.error:
            print(f"error: {recorder.error}")
            return 1
        print(f"recorded {recorder.messages} messages to {', '.join(str(p) for p in recorder.parts)}")
    return 0


HELP = """\
Replay a recording made by `ropecam monitor --record`: its raw wire messages go through the same receiving,
statistics, decoding and recording code as live data, with their recorded receive times. With --record the
decoded channels are written again (also the frames the live monitor had to skip under load).
Rolled recordings (run.mcap, run_001.mcap, ...) are replayed in order; recordings of either encoding (protobuf or
JSON Foxglove channels) and of older versions replay alike, since only the raw wire channel is read. A recording cut
by a crash needs `ropecam recover` first.

examples:
  ropecam replay run.mcap
  ropecam replay run.mcap --speed 1
  ropecam replay run.mcap --record run-decoded.mcap
  ropecam replay run.mcap --record run-json.mcap --encoding json              # JSON Foxglove channels
  ropecam replay run.mcap --reprocess --plane plane.yaml --record run-metres.mcap
  ropecam replay run.mcap --export-jsonl run.jsonl && ropecam compare run.jsonl --plane plane.yaml --out report/
  ropecam replay run.mcap --plane plane.yaml --rope-length-m 0.411 --export-csv points.csv   # metres, per sample
  ropecam replay run.mcap --plane plane.yaml --model rope.toml --record run-model.mcap
  ropecam replay --frames sim/rig --config device.toml --record rig.mcap       # raw frames, measured now
"""


def _csv_outputs(args: argparse.Namespace) -> list[Path]:
    """The Parquet twin of --export-csv and the later parts of an earlier recording to --record."""
    parquet = [Path(args.export_csv).with_suffix(".parquet")] if args.export_csv else []
    return [*parquet, *recording_parts_to_replace(args)]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `replay` sub-command."""
    parser = subparsers.add_parser(
        "replay", help="replay a recording through the live path", description=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    parser.add_argument("recording", nargs="?", help="the .mcap file (first part of a rolled recording)")
    parser.add_argument(
        "--frames",
        metavar="DIR",
        help="instead of a recording: measure a raw frame set (or image folder, video) with the device pipeline "
        "offline and send its results through the same path",
    )
    parser.add_argument("--config", metavar="device.toml", help="with --frames: the device config ([pipeline])")
    parser.add_argument("--speed", type=_speed, default=None, help="1 = real time, 2 = twice as fast, max (default)")
    parser.add_argument("--record", metavar="NEW.mcap", help="record the replayed stream to a new file")
    add_encoding_option(parser)
    parser.add_argument(
        "--reprocess", action="store_true", help="apply --camera/--plane (a new calibration) to the recorded stream"
    )
    parser.add_argument("--camera", metavar="camera.yaml", help="intrinsics; default: the plane file's camera")
    parser.add_argument("--plane", metavar="plane.yaml", help="plane pose: plane channels in metres, tips in mm")
    parser.add_argument(
        "--export-jsonl",
        metavar="FILE.jsonl",
        help="also write the FrameResults as `ropecam-device extract` JSON lines (input of `ropecam compare`)",
    )
    parser.add_argument(
        "--export-csv",
        metavar="FILE.csv",
        help="also write the measured material points in metres, two samples per frame, with their in-frame "
        "velocities (and FILE.parquet when pyarrow is installed); needs --plane and --rope-length-m",
    )
    parser.add_argument("--rope-length-m", type=float, help="--export-csv: the rope's unstretched length (m)")
    parser.add_argument(
        "--points", help="--export-csv: material points, unstretched arc lengths in m (default: L/4, L/2, 3L/4, L)"
    )
    parser.add_argument(
        "--device", type=int, help="device id for --export-jsonl and --model (default: the first one seen)"
    )
    parser.add_argument(
        "--model",
        metavar="rope.toml",
        help="fit the ANCF model (as `ropecam compare`: release time by least squares) and record its rope "
        "(/device<ID>/plane/model) and its error at the material points (/device<ID>/model_error); needs --plane",
    )
    parser.add_argument("--release-time-s", type=float, help="start value of the release time fit (device clock, s)")
    # --force also replaces the later parts of an earlier rolled recording to --record.
    declare_outputs(parser, "record", "export_jsonl", "export_csv", derived=_csv_outputs)
    parser.set_defaults(func=_run)
