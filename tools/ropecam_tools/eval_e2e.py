"""The rig daemon at the camera rate, end to end: every result received over UDP and serial, equal to offline.

`ropecam-device run` in its own process replays a recorded frame set paced at --fps into UDP loopback and,
separately, into a pty serial pair; a receiver here collects every FrameResult and compares them with the offline
pipeline over the frames the daemon measured (the pipeline carries state from frame to frame, so a skipped frame
changes the next ones: the reference skips it too).

Prints per transport: FrameResults received of those in the set, frames the daemon skipped (newest-frame policy:
the pipeline fell behind the camera) in its first --start-s seconds and after them, sequence gaps, and whether
every received result equals the offline one (status, method, both shapes within the sender's shape tolerance,
0.1 px). A fresh daemon learns the rope on its first frames (tables per lens-blur reading, the static mask:
docs/daemon.md) and skips camera frames meanwhile, so the set must last well beyond --start-s (e.g. `ropecam
simulate rig --frames 360`: 3 s at 119 FPS). Exit 0 when every received result equals the offline one, no sequence
number is missing and nothing was skipped after the start. Repeat with --runs: a shared machine's load spikes show.

    python tools/evaluate.py e2e --frameset sim/rig --fps 119 [--start-s 1] [--runs 3] [--transports udp serial]
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import itertools
import json
import os
import pty
import subprocess
import sys
import time
from pathlib import Path
from typing import Any


@functools.lru_cache(maxsize=4)
def _offline(frameset: Path, measured: frozenset[int]) -> dict[int, Any]:
    """The offline pipeline's results over the frames numbered `measured` (the others skipped, as the daemon did)."""
    from ropecam.device.capture.frameset import FrameSet
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.device.pipeline.result import to_wire

    frames = FrameSet(frameset)
    pipeline = Pipeline(PipelineConfig(), frames.image_size)
    pipeline.warm_up()  # as the daemon does before its camera starts
    return {
        r.frame: to_wire(pipeline.process(image, r.frame, r.t_ns, r.exposure_us))
        for r, image in frames
        if r.frame in measured
    }


def _same(got: Any, want: Any) -> bool:
    from ropecam.device.daemon.config import SenderConfig
    from ropecam.shared.protocol.shapes import polyline_distances_px

    # The sender's shape codec; a frame its byte budget cut names the looser tolerance (0: shapes left out).
    cut = got.quality.get("wire_tolerance_px")
    tolerance = (SenderConfig().shape_tolerance_px if cut is None else cut) + 1e-6

    if got.status != want.status or got.method != want.method:
        return False
    for name in ("begin_px", "end_px"):
        a, b = getattr(got, name), getattr(want, name)
        if cut == 0.0 and a is None:
            continue
        if (a is None) != (b is None):
            return False
        if a is not None and polyline_distances_px(b, a).max() > tolerance:
            return False
    return True


def _daemon(frameset: Path, fps: float, sink: str) -> subprocess.Popen[bytes]:
    command = [sys.executable, "-m", "ropecam.device.cli", "run", "--source", f"frames:{frameset}?fps={fps:g}",
               "--sink", sink]  # fmt: skip
    return subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _receive_udp(frameset: Path, fps: float) -> tuple[list[bytes], int]:
    from ropecam.shared.transport import open_transport

    host = open_transport("udp://127.0.0.1:0?listen=1")
    process = _daemon(frameset, fps, f"udp://127.0.0.1:{host.local_address[1]}")
    packets = []
    try:
        while process.poll() is None:
            data = host.receive(0.05)
            if data is not None:
                packets.append(data)
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            data = host.receive(0.05)
            if data is not None:
                packets.append(data)
    finally:
        host.close()
    return packets, process.returncode


def _receive_serial(frameset: Path, fps: float) -> tuple[list[bytes], int]:
    from ropecam.shared.protocol.framing import Deframer

    master, slave = pty.openpty()
    name = os.ttyname(slave)
    os.close(slave)
    os.set_blocking(master, False)
    deframer = Deframer()
    packets: list[bytes] = []
    process = _daemon(frameset, fps, f"serial://{name}?baud=921600")
    try:
        end = None
        while end is None or time.monotonic() < end:
            if end is None and process.poll() is not None:
                end = time.monotonic() + 0.5
            try:
                packets.extend(deframer.feed(os.read(master, 65536)))
            except (BlockingIOError, OSError):
                time.sleep(0.002)
    finally:
        with contextlib.suppress(OSError):
            os.close(master)
    return packets, process.returncode


def run_once(frameset: Path, fps: float, transport: str, start_s: float) -> dict[str, Any]:
    """One daemon run over one transport; the counts and the comparison."""
    from ropecam.device.capture.frameset import FrameSet
    from ropecam.shared.errors import ProtocolError
    from ropecam.shared.protocol import FrameResult, decode_message

    receive = _receive_udp if transport == "udp" else _receive_serial
    packets, code = receive(frameset, fps)
    results, sequences = [], []
    for data in packets:
        try:
            message = decode_message(data)
        except ProtocolError:
            continue
        sequences.append(message.header.sequence)
        if isinstance(message.record, FrameResult):
            results.append(message.record)
    records = FrameSet(frameset).records
    first = records[0].frame
    start_frames = round(start_s * fps)  # paced replay: frame k is handed over k / fps after the start
    got = {r.frame_index for r in results}
    missed = [r.frame for r in records if r.frame not in got]
    expected = _offline(frameset, frozenset(got))  # runs that measured the same frames share it
    equal = sum(1 for r in results if r.frame_index in expected and _same(r, expected[r.frame_index]))
    gaps = sum(max(0, b - a - 1) for a, b in itertools.pairwise(sequences))
    return {"transport": transport, "exit_code": code, "frames": len(records), "received": len(results),
            "equal_to_offline": equal, "skipped_at_start": sum(f - first < start_frames for f in missed),
            "skipped_after_start": sum(f - first >= start_frames for f in missed),
            "sequence_gaps": gaps}  # fmt: skip


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--frameset", type=Path, required=True, help="recorded frame set (e.g. ropecam simulate rig)")
    parser.add_argument("--fps", type=float, default=119.0, help="replay rate (default 119)")
    parser.add_argument("--start-s", type=float, default=1.0,
                        help="the daemon's start-up: frames it skips in these first seconds are counted apart and "
                        "do not fail the run (default 1.0)")  # fmt: skip
    parser.add_argument("--runs", type=int, default=1, help="runs per transport (default 1)")
    parser.add_argument("--transports", nargs="+", choices=("udp", "serial"), default=["udp", "serial"])
    parser.add_argument("--json", action="store_true", help="print JSON rows")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    from ropecam.device.capture.frameset import FrameSet
    from ropecam_tools.cli import UsageError

    frames = len(FrameSet(args.frameset).records)  # a missing or bad set fails here, before any daemon starts
    if frames <= round(args.start_s * args.fps):
        raise UsageError(
            f"--frameset {args.frameset}: {frames} frames last no longer than --start-s {args.start_s:g} s at "
            f"{args.fps:g} FPS: nothing would be measured after the start-up; use a longer set"
        )
    rows = []
    for transport in args.transports:
        for _ in range(args.runs):
            row = run_once(args.frameset, args.fps, transport, args.start_s)
            rows.append(row)
            if args.json:
                print(json.dumps(row), flush=True)
            else:
                print(f"{transport:6s} at {args.fps:g} FPS: received {row['received']} of {row['frames']} "
                      f"FrameResults, {row['equal_to_offline']} equal to the offline pipeline over the same frames; "
                      f"skipped by the daemon {row['skipped_at_start']} in its first {args.start_s:g} s, "
                      f"{row['skipped_after_start']} after; {row['sequence_gaps']} sequence gaps; "
                      f"exit {row['exit_code']}", flush=True)  # fmt: skip
    good = all(r["received"] == r["equal_to_offline"] and r["skipped_after_start"] == r["sequence_gaps"] == 0
               and r["exit_code"] == 0 for r in rows)  # fmt: skip
    return 0 if good else 1
