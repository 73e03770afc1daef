"""`ropecam-device run`: the rig daemon (capture, measure, stream; systemd-ready)."""

from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import threading
from pathlib import Path
from typing import Any

__all__ = ["register"]

EPILOG = """\
examples:
  ropecam-device run --config /etc/ropecam/device.toml
  ropecam-device run --source v4l2:///dev/video0 --fps 119 --exposure-ms 4 --sink udp://192.168.1.10:5600
  ropecam-device run --source frames:sim/rig?loop=1 --sink serial:///dev/ttyUSB0?baud=921600

device.toml has one table per component (all optional; see docs/daemon.md):
  [capture]   source, fps, exposure_us, loop, read_timeout_s
  [pipeline]  method, polarity, rope_length_m, material_points_m, fixed_end_uv, canny_low, canny_high, ...
  [sender]    sink, device_id, status_period_s, queue_frames
  [control]   key_file or key_hex (pre-shared key from `ropecam keygen`; none: remote control is off)
  [daemon]    retry_initial_s, retry_max_s, camera_give_up_s
Options given here override the file. SIGTERM or SIGINT stop the daemon cleanly. Exit codes: 0 stopped or
recording ended, 2 bad configuration, 3 camera lost longer than camera_give_up_s. The closing line accounts for
every frame: measured (by status), skipped (the pipeline was late: a newer frame overtook them), dropped (never
delivered: driver or recording gaps); --summary-json writes the same as JSON.
"""


def register(subparsers: Any) -> None:
    """Add `ropecam-device run` to the command line."""
    parser = subparsers.add_parser(
        "run",
        help="run the rig daemon: capture, measure every frame, stream results to the host",
        description=__doc__,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", type=Path, help="device.toml (default: built-in defaults)")
    parser.add_argument("--source", help="frame source URL: v4l2:///dev/video0?... or frames:DIR?loop=1")
    parser.add_argument("--sink", help="where results go: udp://HOST:PORT or serial:///dev/ttyX?baud=N")
    parser.add_argument("--fps", type=float, help="frame rate (camera setting, or replay pace)")
    parser.add_argument("--exposure-ms", type=float, help="camera exposure time in milliseconds")
    parser.add_argument("--device-id", type=int, help="this device's id in every message (1..65534)")
    parser.add_argument(
        "--summary-json",
        type=Path,
        metavar="FILE",
        help="on exit, write where every frame went (measured, skipped, dropped), the statuses and the exit code "
        "(replaced at every run: the state of the last one)",
    )
    parser.set_defaults(func=run_daemon)


def run_daemon(args: argparse.Namespace) -> int:
    """Run the daemon in the foreground (logs to stdout for journald)."""
    from ropecam.device.daemon.config import load_device_config
    from ropecam.device.daemon.runner import Daemon
    from ropecam.device.daemon.systemd import Notifier
    from ropecam.shared.errors import DataError

    exposure_us = None if args.exposure_ms is None else round(args.exposure_ms * 1000)
    config = load_device_config(
        args.config,
        capture={"source": args.source, "fps": args.fps, "exposure_us": exposure_us},
        sender={"sink": args.sink, "device_id": args.device_id},
    )
    logging.getLogger("ropecam").setLevel(min(logging.INFO, logging.getLogger().level))  # journald gets INFO
    # The application reads the environment; library code gets the values passed in.
    watchdog = os.environ.get("WATCHDOG_USEC")
    notifier = Notifier(os.environ.get("NOTIFY_SOCKET"), int(watchdog) if watchdog and watchdog.isdigit() else None)
    stop = threading.Event()

    def on_signal(signum: int, frame: object) -> None:
        logging.getLogger("ropecam.device").info("signal %d: stopping", signum)
        stop.set()

    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, on_signal)
    daemon = Daemon(config, notifier=notifier)
    code = daemon.run(stop)
    print(daemon.summary(code), flush=True)
    if args.summary_json is not None:
        summary = {**daemon.accounting(), "statuses": dict(sorted(daemon.statuses.items())), "exit": code}
        try:
            args.summary_json.write_text(json.dumps(summary, indent=1) + "\n")
        except OSError as exc:
            raise DataError(f"{args.summary_json}: cannot write the summary: {exc}") from exc
    return code
