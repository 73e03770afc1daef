"""Measure the frame sources' per-frame overhead and the pacing of a recorded frame set at the rig's rate.

Writes a temporary frame set (default 119 frames of 1024x544, the rig camera's size) and reports, all in this
process:

1. preload: time and memory to decode the set into memory;
2. unpaced replay: median / p99 time of one `FrameSetSource.read` (looping), against a bare ``frames[i]`` numpy
   view as the floor;
3. paced replay at the set's rate for `--paced-s` seconds: frames delivered, skipped, dropped, and how late each
   read returns after the frame's instant (median / max);
4. the V4L2 source over the fake camera: median time of `read` for GREY (mapped buffer, no copy) and YUYV (Y copied
   out), excluding the fake's own frame generation.

    python tools/bench.py capture
    python tools/bench.py capture --frames 60 --paced-s 2 --json
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from ropecam.device.capture.fake import fake_factory, uvc_like_camera
from ropecam.device.capture.frameset import FrameSetWriter
from ropecam.device.capture.replay import FrameSetSource
from ropecam.device.capture.v4l2 import V4l2Source


def write_set(root: Path, frames: int, width: int, height: int, fps: float) -> None:
    """Write a frame set of smooth noise (compresses like real frames, unlike white noise)."""
    rng = np.random.default_rng(0)
    base = rng.integers(0, 200, (height // 8 + 1, width // 8 + 1), dtype=np.uint8)
    base = np.kron(base, np.ones((8, 8), np.uint8))[:height, :width]
    with FrameSetWriter(root, (width, height), fps) as writer:
        for k in range(frames):
            writer.add(np.roll(base, k, axis=1), t_ns=round(k * 1e9 / fps), exposure_us=2000)


def quantiles_us(samples_ns: list[int]) -> dict[str, float]:
    ordered = sorted(samples_ns)
    return {
        "median_us": statistics.median(ordered) / 1e3,
        "p99_us": ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))] / 1e3,
    }


def bench_unpaced(root: Path, reads: int) -> dict[str, object]:
    source = FrameSetSource(root, paced=False, loop=True)
    started = time.perf_counter()
    source.start()
    preload_s = time.perf_counter() - started
    assert source.preloaded
    times = []
    for _ in range(reads):
        t0 = time.perf_counter_ns()
        frame = source.read(0)
        times.append(time.perf_counter_ns() - t0)
        assert frame is not None
    frames = source._preloaded  # the floor: indexing the preloaded array
    assert frames is not None
    floor = []
    for k in range(reads):
        t0 = time.perf_counter_ns()
        _ = frames[k % len(frames)]
        floor.append(time.perf_counter_ns() - t0)
    source.stop()
    read = quantiles_us(times)
    bare = quantiles_us(floor)
    return {
        "preload_s": preload_s,
        "preload_mb": frames.nbytes / 1e6,
        "read": read,
        "bare_index": bare,
        "ratio_median": read["median_us"] / bare["median_us"],
    }


def bench_paced(root: Path, seconds: float) -> dict[str, object]:
    source = FrameSetSource(root, loop=True)
    late = []
    with source:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            frame = source.read(1.0)
            if frame is None:
                continue
            late.append(time.monotonic_ns() - frame.t_ns)
        counters = source.counters.as_dict()
        fps = source.fps
    return {
        "fps": fps,
        "seconds": seconds,
        "expected_frames": round(seconds * fps),
        **counters,
        "late_median_us": statistics.median(late) / 1e3,
        "late_max_us": max(late) / 1e3,
    }


def bench_v4l2(fourcc: str, reads: int) -> dict[str, float]:
    camera = uvc_like_camera()
    source = V4l2Source(camera.path, 1024, 544, 119.0, fourcc, driver_factory=fake_factory(camera))
    times = []
    with source:
        for _ in range(reads):
            camera.deliver(1)
            t0 = time.perf_counter_ns()
            frame = source.read(0)
            times.append(time.perf_counter_ns() - t0)
            assert frame is not None
    return quantiles_us(times)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--frames", type=int, default=119, help="frames in the temporary set (default 119)")
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--height", type=int, default=544)
    parser.add_argument("--fps", type=float, default=119.0)
    parser.add_argument("--reads", type=int, default=5000, help="reads timed for the unpaced replay (default 5000)")
    parser.add_argument("--paced-s", type=float, default=5.0, help="seconds of paced replay (default 5)")
    parser.add_argument("--json", action="store_true", help="print JSON")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "set"
        write_set(root, args.frames, args.width, args.height, args.fps)
        result = {
            "set": {"frames": args.frames, "width": args.width, "height": args.height, "fps": args.fps},
            "unpaced": bench_unpaced(root, args.reads),
            "paced": bench_paced(root, args.paced_s),
            "v4l2_fake_grey": bench_v4l2("GREY", 500),
            "v4l2_fake_yuyv": bench_v4l2("YUYV", 500),
        }
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    u, p = result["unpaced"], result["paced"]
    print(f"set: {args.frames} frames {args.width}x{args.height} at {args.fps:g} fps")
    print(f"preload: {u['preload_s']:.2f} s, {u['preload_mb']:.1f} MB")  # type: ignore[index]
    print(
        f"unpaced read: median {u['read']['median_us']:.2f} us, p99 {u['read']['p99_us']:.2f} us "  # type: ignore[index]
        f"(bare numpy index {u['bare_index']['median_us']:.2f} us; ratio {u['ratio_median']:.1f})"  # type: ignore[index]
    )
    print(
        f"paced {p['seconds']:g} s: delivered {p['delivered']} of {p['expected_frames']} expected, skipped "
        f"{p['skipped']}, dropped {p['dropped']}, timeouts {p['timeouts']}; returned late by median "
        f"{p['late_median_us']:.0f} us, max {p['late_max_us']:.0f} us"
    )
    for key in ("v4l2_fake_grey", "v4l2_fake_yuyv"):
        q = result[key]
        print(f"{key}: read median {q['median_us']:.2f} us, p99 {q['p99_us']:.2f} us")  # type: ignore[index]
    return 0
