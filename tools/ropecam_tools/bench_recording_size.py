"""Bytes per frame of a recording's Foxglove channels in JSON and in protobuf, on the same frames.

Replays the raw wire channel of RECORDING (e.g. the demo's run.mcap) twice through `ropecam replay --record`, once
per encoding (with --plane: the plane channels and transforms too), and prints per encoding the file size, the
compressed chunk bytes, both per frame, and per channel the zstd-compressed bytes per message.

    python tools/bench.py recording-size demo-out/run.mcap --plane demo-out/plane.yaml
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

import zstandard
from mcap.reader import make_reader

from ropecam.host.cli import main as ropecam
from ropecam_tools.cli import UsageError


def _sizes(path: Path) -> tuple[int, int, int, dict[str, tuple[int, int]]]:
    """(file bytes, chunk bytes, frames, {topic: (messages, zstd bytes)}) of a recording."""
    with open(path, "rb") as handle:
        reader = make_reader(handle)
        summary = reader.get_summary()
        by_topic: dict[str, list[bytes]] = defaultdict(list)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            by_topic[channel.topic].append(message.data)
    chunks = sum(index.compressed_size for index in summary.chunk_indexes)
    frames = max(len(v) for t, v in by_topic.items() if t.endswith("/image/scene"))
    compressor = zstandard.ZstdCompressor()
    channels = {t: (len(v), len(compressor.compress(b"".join(v)))) for t, v in sorted(by_topic.items())}
    return path.stat().st_size, chunks, frames, channels


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The recording and the optional plane calibration."""
    parser.add_argument("recording", type=Path, help="an MCAP recording with the raw wire channel (e.g. demo run.mcap)")
    parser.add_argument("--plane", type=Path, help="plane.yaml: also the plane channels in metres")


def run(args: argparse.Namespace) -> int:
    """Replay the recording in each encoding and print the bytes per frame."""
    if not args.recording.is_file():
        raise UsageError(f"{args.recording}: no such recording")
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        for encoding in ("json", "protobuf"):
            out = Path(folder) / f"{encoding}.mcap"
            command = ["replay", str(args.recording), "--record", str(out), "--encoding", encoding]
            command += ["--plane", str(args.plane)] if args.plane else []
            if ropecam(command) != 0:
                print(f"ropecam {' '.join(command)} failed", file=sys.stderr)
                return 1
            results[encoding] = _sizes(out)
    for encoding, (file_bytes, chunk_bytes, frames, channels) in results.items():
        print(f"{encoding}: {frames} frames, file {file_bytes} B ({file_bytes / frames:.0f} B/frame), "
              f"chunks {chunk_bytes} B ({chunk_bytes / frames:.0f} B/frame)")  # fmt: skip
        for topic, (count, size) in channels.items():
            print(f"  {topic:40s} {count:5d} messages, zstd {size / count:8.0f} B/message")
    (json_file, json_chunks, *_), (proto_file, proto_chunks, *_) = results["json"], results["protobuf"]
    print(f"protobuf / json per frame: file {proto_file / json_file:.3f}, chunks {proto_chunks / json_chunks:.3f}")

    return 0
