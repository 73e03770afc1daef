"""Start-up latency: the time per frame of a fresh daemon's first frames against its steady frames.

Each run is a fresh process (the edge model's tables are built once per process), which builds and warms the
pipeline as the daemon does before its camera starts (`Pipeline.warm_up`) and then measures a recorded frame set
unpaced, timing each `Pipeline.process` call. Prints, as medians over the runs: the warm-up, the first `--first`
frames one by one and their sum, the steady frame (median of the frames after them), the ratio of the two, the
frames a replay paced at 30 and 119 FPS would skip for that latency (newest-frame policy, as a camera), and the same
sums in the thread's CPU time (which other processes on a shared machine disturb less than wall time).

    python tools/bench.py first-frames --frameset DIR [--config TOML] [--runs 5] [--first 20]
        [--against-python OTHER_VENV/bin/python]

The frame set the demo streams: ``ropecam simulate rig-soft --out DIR --frames 60 --first-exposure-ms 50``.
Pin it to a core (``taskset -c 1``) and read it as a ratio: absolute times drift with the load.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from ropecam_tools.cli import UsageError, positive_int


def one_process(frameset: Path, config_path: Path | None = None) -> dict[str, object]:
    """Time the warm-up and every frame of `frameset` through a fresh pipeline in this process (ms), with the
    daemon's configuration `config_path` (None: the defaults)."""
    from ropecam.device.capture.replay import FrameSetSource
    from ropecam.device.daemon.config import load_device_config
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.device.pipeline.result import FrameStatus, PipelineResult

    config = load_device_config(config_path, capture={"source": f"frames:{frameset}"})
    source = FrameSetSource(frameset, paced=False)
    source.start()
    started = time.perf_counter()
    pipeline = Pipeline(config.pipeline, source.image_size, config.capture.readout_us, None)
    pipeline.warm_up()
    warm_up_ms = (time.perf_counter() - started) * 1e3
    out = PipelineResult(0, 0, 0, FrameStatus.BAD_FRAME)
    times, cpu, statuses = [], [], []
    while (frame := source.read(1.0)) is not None:
        started, started_cpu = time.perf_counter(), time.thread_time()
        result = pipeline.process(frame.image, frame.sequence, frame.t_ns, frame.exposure_us, out=out)
        times.append((time.perf_counter() - started) * 1e3)
        cpu.append((time.thread_time() - started_cpu) * 1e3)
        statuses.append(result.status.name)
    source.stop()
    return {"warm_up_ms": warm_up_ms, "frame_ms": times, "cpu_ms": cpu, "statuses": statuses}


def skipped_when_paced(frame_ms: list[float], fps: float) -> int:
    """Frames a replay of ``len(frame_ms)`` frames paced at `fps` would skip when the i-th frame measured takes
    ``frame_ms[i]``: a free pipeline takes the newest frame available and the ones it overtook are skipped, as with
    a camera (reading and sending taken as free)."""
    period_ms, count = 1e3 / fps, len(frame_ms)
    now_ms, last, skipped, measured = 0.0, -1, 0, 0
    while last < count - 1:
        newest = min(int(now_ms // period_ms), count - 1)
        if newest <= last:  # nothing new yet: wait for the next frame
            newest = last + 1
            now_ms = newest * period_ms
        skipped += newest - last - 1
        now_ms += frame_ms[measured]
        last, measured = newest, measured + 1
    return skipped


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--frameset", type=Path, required=True, help="recorded frame set (e.g. rig-soft, 60 frames)")
    parser.add_argument("--config", type=Path, help="the daemon's device.toml (default: built-in defaults)")
    parser.add_argument("--runs", type=positive_int, default=5, help="fresh processes (default 5); medians")
    parser.add_argument("--first", type=positive_int, default=20, help="start-up frames (default 20)")
    parser.add_argument(
        "--against-python",
        metavar="PY",
        help="also run another tree's interpreter (its venv's python), alternately: before/after under one load",
    )
    parser.add_argument("--one-process", action="store_true", help=argparse.SUPPRESS)  # one run, JSON on stdout


def _report(label: str, runs: list[dict], first_count: int) -> None:
    """Print the medians over `runs` (see the module docstring)."""
    count = len(runs[0]["frame_ms"])
    frame_ms = [statistics.median(r["frame_ms"][i] for r in runs) for i in range(count)]
    steady = statistics.median(frame_ms[first_count:])
    first = frame_ms[:first_count]
    warm = statistics.median(r["warm_up_ms"] for r in runs)
    not_ok = sorted({s for r in runs for s in r["statuses"] if s != "OK"})
    print(f"{label}: {len(runs)} fresh processes, medians; warm-up {warm:.1f} ms")
    print(f"  first {first_count} frames (ms): " + " ".join(f"{t:.1f}" for t in first))
    print(f"  first {first_count} frames {sum(first):.1f} ms = {sum(first) / steady:.0f} steady frames; steady "
          f"frame {steady:.2f} ms (median of frames {first_count}-{count - 1}); frame 0 {first[0] / steady:.0f} x "
          "steady")  # fmt: skip
    print("  skipped when paced (from the medians): " + ", ".join(
        f"{fps:g} FPS {skipped_when_paced(frame_ms, fps)}" for fps in (30.0, 119.0)))  # fmt: skip
    cpu_ms = [statistics.median(r["cpu_ms"][i] for r in runs) for i in range(count)]
    cpu_steady = statistics.median(cpu_ms[first_count:])
    print(
        f"  CPU time of this thread (less sensitive to other processes): first {first_count} frames "
        f"{sum(cpu_ms[:first_count]):.1f} ms = {sum(cpu_ms[:first_count]) / cpu_steady:.0f} steady frames of "
        f"{cpu_steady:.2f} ms; per run: " + " ".join(f"{sum(r['cpu_ms'][:first_count]):.0f}" for r in runs)
    )
    print("  first frames' total per run (ms): " + " ".join(f"{sum(r['frame_ms'][:first_count]):.0f}" for r in runs)
          + (f"; statuses other than OK: {', '.join(not_ok)}" if not_ok else ""))  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    if args.one_process:
        print(json.dumps(one_process(args.frameset, args.config)))
        return 0
    from ropecam.device.capture.frameset import FrameSet

    count = len(FrameSet(args.frameset))
    if count <= args.first:
        raise UsageError(f"--frameset {args.frameset}: {count} frames, need more than --first {args.first}")
    bench = Path(__file__).resolve().parents[1] / "bench.py"
    pythons = {"this tree": sys.executable}
    if args.against_python:
        pythons[args.against_python] = args.against_python
    runs: dict[str, list[dict]] = {label: [] for label in pythons}
    for _ in range(args.runs):  # alternately, so that both see the same load
        for label, python in pythons.items():
            command = [python, str(bench), "first-frames", "--frameset", str(args.frameset), "--one-process"]
            command += ["--config", str(args.config)] if args.config else []
            done = subprocess.run(command, capture_output=True, text=True)
            if done.returncode != 0:
                raise RuntimeError(f"{label}: {' '.join(command)} failed:\n{done.stderr}")
            runs[label].append(json.loads(done.stdout))
    print(f"{args.frameset}:")
    for label, done_runs in runs.items():
        _report(label, done_runs, args.first)
    return 0
