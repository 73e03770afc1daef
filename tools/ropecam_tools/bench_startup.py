"""Time from starting `ropecam-device run` to the first FrameResult at a UDP receiver (issue 6, acceptance 4).

Runs the daemon as a subprocess on a recorded rig frame set, `--repeats` times, and prints the median. `--cold`
empties the Numba cache first (one run), which measures compilation on a fresh install.

    python tools/bench.py startup [--frameset DIR] [--repeats 5] [--cold]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def first_result_s(frameset: Path, env: dict[str, str]) -> float:
    from ropecam.shared.protocol import FrameResult, decode_message
    from ropecam.shared.transport import open_transport

    host = open_transport("udp://127.0.0.1:0?listen=1")
    port = host.local_address[1]
    command = [sys.executable, "-m", "ropecam.device.cli", "run", "--source", f"frames:{frameset}?loop=1",
               "--sink", f"udp://127.0.0.1:{port}"]  # fmt: skip
    started = time.perf_counter()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        while time.perf_counter() - started < 300:
            data = host.receive(0.05)
            if data is not None and isinstance(decode_message(data).record, FrameResult):
                return time.perf_counter() - started
        raise RuntimeError("no result within 300 s")
    finally:
        process.terminate()
        process.wait(30)
        host.close()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--frameset", type=Path, help="recorded frame set (default: simulate 5 rig frames)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--cold", action="store_true", help="empty a private Numba cache first (one cold run)")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    frameset = args.frameset
    if frameset is None:
        from ropecam.host.cli import main as host_main

        frameset = Path(tempfile.mkdtemp(prefix="startup-")) / "rig"
        host_main(["simulate", "rig", "--out", str(frameset), "--frames", "5", "--first-exposure-ms", "100", "-q"])
    env = dict(os.environ)
    if args.cold:
        cache = Path(tempfile.mkdtemp(prefix="numba-cold-"))
        env["NUMBA_CACHE_DIR"] = str(cache)
        print(f"cold start (empty NUMBA_CACHE_DIR): {first_result_s(frameset, env):.2f} s")
        print(f"warm start (same cache, now filled): {first_result_s(frameset, env):.2f} s")
        shutil.rmtree(cache, ignore_errors=True)
        return 0
    times = [first_result_s(frameset, env) for _ in range(args.repeats)]
    print(f"start to first result: median {statistics.median(times):.2f} s over {len(times)} runs "
          f"(min {min(times):.2f}, max {max(times):.2f})")  # fmt: skip
    return 0
