"""Soak the rig daemon: replay a recorded frame set in a loop at the camera rate for a long time, in this process.

Reports, every --report-s and at the end: frames captured and measured, frames dropped (camera side: skipped by the
newest-frame policy; link side: queue and transport), sequence gaps seen by the receiver, RSS and its growth after
the warm-up, and CPU time per frame. Acceptance of issue 6 (3): 10 minutes at 119 FPS, RSS growth <= 1 MB, 0 drops.

    python tools/soak.py device --frameset sim/rig --fps 119 --duration-s 600
    python tools/soak.py device --duration-s 60 --json          # makes a small rig set itself
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import threading
import time
from pathlib import Path


def rss_kib() -> int:
    """Resident set size of this process in KiB (Linux)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--frameset", type=Path, help="recorded frame set (default: simulate 60 rig frames)")
    parser.add_argument("--fps", type=float, default=119.0, help="replay rate (default 119)")
    parser.add_argument("--duration-s", type=float, default=600.0, help="how long (default 600)")
    parser.add_argument("--warmup-s", type=float, default=20.0, help="RSS growth is measured after this")
    parser.add_argument("--report-s", type=float, default=30.0, help="progress line period")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""

    from ropecam.device.capture.config import CaptureConfig
    from ropecam.device.daemon.config import DeviceConfig, SenderConfig
    from ropecam.device.daemon.runner import Daemon
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.shared.protocol import FrameResult, Status, decode_message
    from ropecam.shared.transport import open_transport

    frameset = args.frameset
    if frameset is None:
        from ropecam.host.cli import main as host_main

        frameset = Path(tempfile.mkdtemp(prefix="soak-")) / "rig"
        host_main(["simulate", "rig", "--out", str(frameset), "--frames", "60", "--first-exposure-ms", "100", "-q"])
    config = DeviceConfig(
        capture=CaptureConfig(source=f"frames:{frameset}?fps={args.fps}&loop=1"),
        pipeline=PipelineConfig(rope_length_m=0.411, material_points_m=(0.1, 0.2, 0.3, 0.411)),
        sender=SenderConfig(sink="loop://soak", status_period_s=1.0),
    )
    host = open_transport("loop://soak")
    received = {"frames": 0, "gaps": 0, "last": None, "camera_skipped": 0}

    def receive() -> None:
        while not host.closed:
            data = host.receive(0.2)
            if data is None:
                continue
            message = decode_message(data)
            last = received["last"]
            if last is not None and message.header.sequence != last + 1:
                received["gaps"] += 1
            received["last"] = message.header.sequence
            if isinstance(message.record, FrameResult):
                received["frames"] += 1
            elif isinstance(message.record, Status):  # the newest-frame policy's count (the pipeline fell behind)
                received["camera_skipped"] = int(dict(message.record.counters).get("capture_skipped", 0))

    receiver = threading.Thread(target=receive, daemon=True)
    receiver.start()
    daemon = Daemon(config)
    stop = threading.Event()
    runner = threading.Thread(target=lambda: daemon.run(stop), daemon=True)
    started = time.monotonic()
    cpu_start = time.process_time()
    runner.start()
    rss_after_warmup = None
    next_report = started + args.report_s
    while time.monotonic() - started < args.duration_s:
        time.sleep(0.5)
        elapsed = time.monotonic() - started
        if rss_after_warmup is None and elapsed >= args.warmup_s:
            rss_after_warmup = rss_kib()
        if time.monotonic() >= next_report:
            next_report += args.report_s
            print(f"{elapsed:7.1f} s: measured {daemon.frames_measured}, received {received['frames']}, "
                  f"RSS {rss_kib() / 1024:.1f} MiB", file=sys.stderr, flush=True)  # fmt: skip
    rss_end = rss_kib()  # while still running: after the stop, buffers are freed and growth would read negative
    stop.set()
    runner.join(30)
    time.sleep(0.5)
    host.close()
    cpu = time.process_time() - cpu_start
    sender = daemon.sender.stats if daemon.sender else None
    result = {
        "duration_s": round(time.monotonic() - started, 1),
        "fps": args.fps,
        "frames_measured": daemon.frames_measured,
        "frames_received": received["frames"],
        "expected_frames": round(args.fps * args.duration_s),
        "sequence_gaps": received["gaps"],
        "camera_skipped": received["camera_skipped"],
        "queue_dropped": sender.dropped_queue_full if sender else None,
        "link_dropped": sender.dropped_by_link if sender else None,
        "statuses": dict(daemon.statuses),
        "rss_mib": round(rss_end / 1024, 2),
        "rss_growth_after_warmup_mib": None
        if rss_after_warmup is None
        else round((rss_end - rss_after_warmup) / 1024, 3),
        "max_rss_mib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "cpu_ms_per_frame": round(1000 * cpu / max(daemon.frames_measured, 1), 3),
    }
    print(json.dumps(result, indent=2) if args.json else "\n".join(f"{k}: {v}" for k, v in result.items()))
    return 0
