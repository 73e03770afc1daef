"""`ropecam monitor`: receive one transport, show per-device statistics live, optionally record MCAP."""

from __future__ import annotations

import argparse
import signal
import socket
import sys
import time
from collections.abc import Callable
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING, Final
from urllib.parse import parse_qsl, urlsplit, urlunsplit

from ropecam.shared.cli import declare_outputs
from ropecam.shared.errors import ConfigError

if TYPE_CHECKING:
    from ropecam.host.monitor.display import PlainDisplay, RichDisplay
    from ropecam.host.monitor.live_model import LiveModel
    from ropecam.host.receiver import Packet, Receiver
    from ropecam.host.session import Session

__all__ = ["DECODE_BACKLOG", "StopSignals", "monitor_loop", "recording_parts_to_replace", "register", "rig_metadata"]

DECODE_BACKLOG: Final = 64
"""Above this backlog no FrameResult is fully decoded (recorded raw and counted); between a quarter of it and it,
frames are decoded round robin over the devices (`Session.fair_decode`); below, all are."""

HELP = """\
Receive the device stream(s) on one transport, show a live table with one row per device (rate, period jitter,
sequence losses/duplicates/reordering, bad packets, bytes/s, latency when the clocks agree, device pipeline time
p50/p99, tip position, order confidence, warnings when loss appears) and optionally record everything to MCAP.

The recording holds the raw wire messages (exact replay with `ropecam replay`), the decoded shapes as Foxglove
scenes and point clouds (protobuf by default, --encoding json), the transforms between the plane, camera and image
frames, Status and Log messages; a Foxglove layout is written beside it (run.layout.json). With --foxglove the
same channels are served live to the Foxglove app (Open connection -> Foxglove WebSocket -> ws://127.0.0.1:8765).

The recording is flushed every 0.5 s: after a crash `ropecam recover` rebuilds everything up to the last flush. A
full disk or failing file stops the recording with a message; the monitor keeps running. Stop with Ctrl-C or
SIGTERM (the recording is closed properly).

A udp:// source binds that address and port (0.0.0.0: all interfaces); several devices may send to it.

examples:
  ropecam monitor --source udp://0.0.0.0:5600 --record run.mcap
  ropecam sim-device --to udp://127.0.0.1:5600 --device-id 3     (another terminal: a simulated device)
  ropecam monitor --source "serial:///dev/ttyUSB0?baud=921600" --no-ui --duration-s 60
  ropecam monitor --source udp://127.0.0.1:5600 --record run.mcap --roll-mb 1024
  ropecam monitor --source udp://0.0.0.0:5600 --plane plane.yaml --foxglove     (live view in Foxglove)
"""


def rig_metadata(source: str) -> dict[str, dict[str, str]]:
    """Return the metadata records every recording carries (host, software version, source, start time)."""
    try:
        software = version("ropecam")
    except PackageNotFoundError:
        software = "unknown"
    return {
        "rig": {
            "host": socket.gethostname(),
            "ropecam_version": software,
            "source": source,
            "start_time_ns": str(time.time_ns()),
            "raw_channel": "/ropecam/wire: one ropecam.WireMessage (protobuf) per wire message, its data field the "
            "bytes as received (docs/protocol.md)",
        }
    }


def listening_url(url: str) -> str:
    """Return `url` made to receive: ``udp://HOST:PORT`` binds HOST:PORT (``listen=1``) unless it says otherwise.

    A transport URL ``udp://HOST:PORT`` on its own means "send to HOST:PORT"; a monitor always receives, so
    ``udp://0.0.0.0:5600`` (all interfaces) and ``udp://127.0.0.1:5600`` mean "bind there".
    """
    parts = urlsplit(url)
    if parts.scheme != "udp" or "listen" in dict(parse_qsl(parts.query)):
        return url
    query = f"{parts.query}&listen=1" if parts.query else "listen=1"
    return urlunsplit(parts._replace(query=query))


def load_calibration(
    camera_path: str | None, plane_path: str | None
) -> tuple[tuple | None, dict[str, dict[str, str]], list[tuple[str, str, bytes]]]:
    """Read --camera/--plane files: return ((camera, plane) or None, metadata records, attachments for the MCAP).

    The plane file (``ropecam calibrate plane``) holds the camera it was measured with; --camera, when given,
    overrides the intrinsics (e.g. a newer intrinsic calibration).

    Raises
    ------
    ConfigError
        --camera without --plane (pixels cannot become metres without the plane pose).
    DataError
        A file is missing or malformed (from `ropecam.host.calibration.files`).
    """
    if plane_path is None:
        if camera_path is not None:
            raise ConfigError("--camera needs --plane too: metres on the plane need the plane pose (plane.yaml)")
        return None, {}, []
    from ropecam.host.calibration.files import read_camera, read_plane

    plane_file = read_plane(plane_path)
    camera = read_camera(camera_path).camera if camera_path is not None else plane_file.camera
    metadata = {
        "calibration": {
            "camera_file": str(camera_path or plane_path),
            "plane_file": str(plane_path),
            "camera_matrix": repr(camera.camera_matrix.tolist()),
            "distortion": repr(camera.distortion.tolist()),
            "image_size": repr(camera.image_size),
            "plane_rotation": repr(plane_file.plane.rotation.tolist()),
            "plane_translation_m": repr(plane_file.plane.translation_m.tolist()),
        }
    }
    attachments = [(Path(p).name, "application/x-yaml", Path(p).read_bytes()) for p in {camera_path, plane_path} if p]
    return (camera, plane_file.plane), metadata, attachments


def load_live_model(
    model_path: str, calibration: tuple | None
) -> tuple[LiveModel, dict[str, dict[str, str]], tuple[str, str, bytes]]:
    """Simulate the rope of `model_path` once and return the live model source, its metadata and attachment.

    Raises
    ------
    ConfigError
        No --plane (the model lives in metres on the plane), or a bad rope.toml.
    """
    if calibration is None:
        raise ConfigError("--model needs --plane: the model is compared in metres on the plane")
    from ropecam.host.model.cli import load_model_config
    from ropecam.host.model.solver import CableModel
    from ropecam.host.monitor.live_model import LiveModel

    rope, solver = load_model_config(Path(model_path))
    print(f"monitor: simulating the model of {model_path} ({solver.duration_s:g} s of swing)", file=sys.stderr)
    trajectory, _ = CableModel(rope, solver).run()
    metadata = {"model": {"file": str(model_path), "rope": repr(rope), "solver": repr(solver)}}
    return (
        LiveModel(trajectory, rope.length_m, calibration),
        metadata,
        (
            Path(model_path).name,
            "application/toml",
            Path(model_path).read_bytes(),
        ),
    )


def monitor_loop(
    receiver: Receiver,
    session: Session,
    display: PlainDisplay | RichDisplay | None,
    duration_s: float | None,
    should_stop: Callable[[], bool] = lambda: False,
    decode_backlog: int = DECODE_BACKLOG,
) -> None:
    """Run until `duration_s` passed or `should_stop()`; every packet goes through `session.handle`.

    FrameResults are fully decoded while the backlog is small (load shedding keeps the receive path at wire rate:
    nothing is lost, undecoded frames stay in the raw channel; see `DECODE_BACKLOG`). When it stops, the packets
    already received are still handled.
    """

    def decide(packet: Packet) -> bool:
        backlog = receiver.backlog
        if backlog < decode_backlog // 4:
            return True
        return backlog < decode_backlog and session.fair_decode(packet)

    start = time.monotonic()
    next_display = start + (display.period_s if display is not None else 1e18)
    next_tick = start
    while not should_stop():
        packet = receiver.poll(0.05)
        if packet is not None:
            session.handle(packet, decode=decide(packet))
        now = time.monotonic()
        if now >= next_tick:
            session.tick()
            next_tick = now + 0.05
        if display is not None and now >= next_display:
            display.update(session, session.snapshot(time.time_ns()))
            next_display += display.period_s
            if next_display < now:
                next_display = now + display.period_s
        if duration_s is not None and now - start >= duration_s:
            break
    for packet in receiver.remaining():
        session.handle(packet, decode=decide(packet))


class StopSignals:
    """Turn Ctrl-C (SIGINT) and SIGTERM into a stop request while in the ``with`` block; restore the old handlers.

    The loop then ends at its next check and still handles every packet already received (`monitor_loop`'s final
    drain), instead of a KeyboardInterrupt skipping it. A second Ctrl-C while stopping interrupts as usual.
    """

    def __init__(self) -> None:
        self.signal_name: str | None = None
        """Name of the first stop signal received (None: none)."""
        self._previous: dict[int, object] = {}

    def requested(self) -> bool:
        """Say whether a stop signal arrived."""
        return self.signal_name is not None

    def _handle(self, number: int, _frame: object) -> None:
        if self.signal_name is not None and number == signal.SIGINT:
            raise KeyboardInterrupt  # the second Ctrl-C: the user insists
        self.signal_name = signal.Signals(number).name

    def __enter__(self) -> StopSignals:
        for number in (signal.SIGINT, signal.SIGTERM):
            self._previous[number] = signal.signal(number, self._handle)
        return self

    def __exit__(self, *_exc: object) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, handler)


def _run(args: argparse.Namespace) -> int:
    from ropecam.host.monitor.display import PlainDisplay, RichDisplay, format_row
    from ropecam.host.monitor.foxglove_live import FoxgloveLive, parse_address
    from ropecam.host.receiver import Receiver
    from ropecam.host.recording.proto import make_encoder
    from ropecam.host.recording.writer import Recorder, RecordingConfig
    from ropecam.host.session import Session
    from ropecam.shared.transport import open_transport

    if args.duration_s is not None and args.duration_s <= 0:
        raise ConfigError(f"--duration-s must be > 0, got {args.duration_s}")
    if args.roll_mb < 0 or args.roll_s < 0:
        raise ConfigError(f"--roll-mb and --roll-s must be >= 0 (0: no rolling), got {args.roll_mb}, {args.roll_s}")
    calibration, calibration_metadata, attachments = load_calibration(args.camera, args.plane)
    config = None
    if args.record:
        config = RecordingConfig(
            Path(args.record),
            roll_bytes=int(args.roll_mb * 1e6),
            roll_s=args.roll_s,
            overwrite=args.force,
            fsync=args.fsync,
        )
    model = None
    if args.model is not None:
        model, model_metadata, model_attachment = load_live_model(args.model, calibration)
        calibration_metadata |= model_metadata
        attachments.append(model_attachment)
    encoder = make_encoder(args.encoding)
    transport = open_transport(listening_url(args.source))  # first: a busy port must not leave a stray file
    live = recorder = None
    try:
        if args.foxglove is not None:
            live = FoxgloveLive(*parse_address(args.foxglove))
        if config is not None:
            metadata = rig_metadata(args.source) | calibration_metadata
            metadata["rig"]["decode"] = args.decode
            recorder = Recorder(config, metadata, attachments)
    except ConfigError:
        transport.close()
        if live is not None:
            live.close()
        raise
    session = Session(recorder, calibration, model, encoder, live)
    receiver = Receiver(transport)
    where = f", recording to {recorder.path}" if recorder is not None else ""
    if live is not None:
        print(f"monitor: Foxglove live view at {live.url} (Foxglove: Open connection -> Foxglove WebSocket)",
              file=sys.stderr, flush=True)  # fmt: skip
    use_rich = not args.no_ui and sys.stdout.isatty()
    display: RichDisplay | PlainDisplay | None = None
    interrupted = False
    stop = StopSignals()
    try:
        backlog = {"auto": DECODE_BACKLOG, "all": 1 << 62, "none": 0}[args.decode]
        with stop:
            # The stop handlers first, then the ready line: a SIGTERM sent as soon as it appears (a service
            # manager, `MonitorProcess`) still closes the recording instead of killing the process.
            print(f"monitor: receiving on {args.source}{where}; Ctrl-C stops", file=sys.stderr, flush=True)
            display = RichDisplay(args.source) if use_rich else PlainDisplay()
            monitor_loop(receiver, session, display, args.duration_s, stop.requested, backlog)
    except KeyboardInterrupt:
        interrupted = True  # a second Ctrl-C during the final drain: what was handled is still recorded
    finally:
        if display is not None:
            display.close()
        session.close()
        transport.close()
        if live is not None:
            live.close()
    for row in session.snapshot(time.time_ns()):
        print("final: " + format_row(row))
    if receiver.overflow:
        print(f"warning: {receiver.overflow} packets dropped: the host fell more than 200000 packets behind")
    if recorder is not None:
        if recorder.error:
            print(
                f"error: {recorder.error}; {recorder.unrecorded} messages after it were not recorded", file=sys.stderr
            )
            return 1
        parts = ", ".join(str(p) for p in recorder.parts)
        print(f"recorded {recorder.messages} messages to {parts}")
    if interrupted:
        print(f"interrupted by a second Ctrl-C: {receiver.backlog} received packets were not handled", file=sys.stderr)
    elif stop.signal_name is not None:
        print(f"stopped by {'Ctrl-C' if stop.signal_name == 'SIGINT' else stop.signal_name}", file=sys.stderr)
    return 0


def recording_parts_to_replace(args: argparse.Namespace) -> list[Path]:
    """The later parts of an earlier rolled recording to ``args.record`` (outputs that ``--force`` deletes)."""
    from ropecam.host.recording.writer import later_parts

    return later_parts(Path(args.record)) if args.record else []


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `monitor` sub-command."""
    from ropecam.host.monitor.foxglove_live import DEFAULT_ADDRESS
    from ropecam.host.recording.encoding import add_encoding_option

    parser = subparsers.add_parser(
        "monitor", help="live view and MCAP recording of device streams", description=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    parser.add_argument(
        "--source", required=True, help="transport URL: udp://0.0.0.0:5600, serial:///dev/ttyUSB0?baud=921600, ..."
    )
    parser.add_argument("--record", metavar="FILE.mcap", help="record everything to this MCAP file")
    parser.add_argument("--camera", metavar="camera.yaml", help="intrinsics (ropecam calibrate); default: plane's")
    parser.add_argument(
        "--plane", metavar="plane.yaml", help="plane pose: adds tips in mm and the plane channels in metres"
    )
    parser.add_argument(
        "--model",
        metavar="rope.toml",
        help="ANCF model (as `ropecam model simulate`); needs --plane. Once a device's rope was seen at rest and "
        "then released, the model is aligned with the release and its rope and error are shown and recorded",
    )
    # --force also deletes the later parts (NAME_001.mcap, ...) of an earlier recording to --record.
    declare_outputs(parser, "record", derived=recording_parts_to_replace)
    add_encoding_option(parser)
    parser.add_argument(
        "--foxglove",
        nargs="?",
        const=DEFAULT_ADDRESS,
        metavar="HOST:PORT",
        help=f"serve the decoded channels live to the Foxglove app over its WebSocket protocol (default "
        f"{DEFAULT_ADDRESS}: this computer only; 0.0.0.0:8765 serves every network interface, see docs/monitor.md)",
    )
    parser.add_argument("--roll-mb", type=float, default=0.0, help="start a new file after this many MB (0: never)")
    parser.add_argument("--roll-s", type=float, default=0.0, help="start a new file after this many seconds (0: never)")
    parser.add_argument("--fsync", action="store_true", help="sync each flush to disk (survives power loss)")
    parser.add_argument("--duration-s", type=float, help="stop by itself after this many seconds")
    parser.add_argument("--no-ui", action="store_true", help="print one summary line per second instead of the table")
    parser.add_argument(
        "--decode",
        choices=("auto", "all", "none"),
        default="auto",
        help="full decode of FrameResults (shapes, scene channels, tip): auto = as many as the host keeps up with "
        "(default), all = every frame (a slow host falls behind), none = raw recording and statistics only "
        "(`ropecam replay --record` decodes later)",
    )
    parser.set_defaults(func=_run)
