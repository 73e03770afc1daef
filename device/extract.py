"""`ropecam-device extract`: run the rope pipeline offline over recorded frames and write one JSON line per frame."""

from __future__ import annotations

import argparse
import itertools
import json
import logging
import sys
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ropecam.shared.cli import declare_outputs

__all__ = ["register", "run_extract"]

log = logging.getLogger(__name__)

HELP = """\
Measure the rope in recorded frames: the rope at the start and at the end of each exposure (centrelines, fixed end
first, free tip last, in distorted pixels (u, v), OpenCV convention: (0, 0) is the centre of the top-left pixel),
segmentation points, material points and stretch. One JSON object per line and frame, written as it goes:

  {"frame": 0, "t_ns": ..., "t_end_ns": ..., "status": "OK", "method": "BLUR_SPLIT", "order_confidence": 0.93,
   "begin": [[u, v], ...], "end": [[u, v], ...], "tips": {"begin": [u, v], "end": [u, v]},
   "fixed_end": [u, v], "segmentation_points": [[u, v], [u, v]],
   "material_points": {"s_m": [...], "begin": [[u, v], ...], "end": [[u, v], ...]},
   "stretch": {"begin": 1.0, "end": 1.0}, "pipeline_us": 412.0, ...}

A frame that cannot be measured gets a status (BAD_FRAME, NO_ROPE, LOST_TRACK, ROPE_CLIPPED) and null shapes; the
run goes on. INPUT is a frame set (the simulator's format), a folder of images, or a video. A folder of images is
a sequence in name order when --fps gives its frame rate; without --fps its images are separate photos, each
measured on its own as the first frame of a stream (nothing learned on one, such as the fixed end, the width or
the thresholds, carries over to the next).

examples:
  ropecam-device extract sim/rig --out rig.jsonl
  ropecam-device extract frames/ --fps 119 --exposure-ms 4 --out frames.jsonl --method paper
  ropecam-device extract photos/ --out photos.jsonl                   # separate still photos
  ropecam-device extract run.avi --fps 119 --exposure-ms 4 --config device.toml --out run.jsonl
"""


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the `extract` sub-command."""
    parser = subparsers.add_parser(
        "extract",
        help="measure the rope in recorded frames (frame set, image folder, video) -> JSON lines",
        description=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("input", metavar="INPUT", help="frame set folder, image folder or video file")
    parser.add_argument("--out", required=True, metavar="FILE", help="output JSON-lines file ('-' for stdout)")
    parser.add_argument(
        "--fps",
        type=float,
        help="frame rate; an image folder without it is a set of separate photos (default: the input's own)",
    )
    parser.add_argument(
        "--exposure-ms", type=float, help="exposure time in ms (default: the frame set's; 0 for folders/videos)"
    )
    parser.add_argument(
        "--method",
        choices=("blur_split", "paper", "centerline", "static"),
        help="blur_split (default), paper (the paper's literal operator and scoring), centerline (centreline of the "
        "blurred band) or static (no split: still scenes and photos)",
    )
    parser.add_argument("--config", metavar="TOML", help="device.toml; its [pipeline] table sets the pipeline")
    parser.add_argument(
        "--fixed-end", nargs=2, type=float, metavar=("U", "V"), help="fixed end pixel (default: found automatically)"
    )
    parser.add_argument(
        "--plane",
        metavar="YAML",
        help="plane calibration (plane.yaml of `ropecam calibrate plane`): the fixed end is its origin projected "
        "into the image and material points are placed by arc length on the plane (default: [pipeline] plane_file)",
    )
    parser.add_argument(
        "--readout-us",
        type=int,
        metavar="US",
        help="rolling-shutter frame readout time in microseconds: row r starts r / height of it after row 0 "
        "(0 = global shutter, the default; "
        "default: [capture] readout_us of --config); each record's readout_ns gives every row its own time",
    )
    parser.add_argument("--limit", type=int, metavar="N", help="stop after N frames")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    declare_outputs(parser, "out")
    parser.set_defaults(func=_main)


def _main(args: argparse.Namespace) -> int:
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.shared.config import from_mapping, read_toml

    data: dict[str, Any] = {}
    where = "command line"
    readout_us: Any = 0
    readout_where = "--readout-us"
    if args.config:
        document = read_toml(args.config)
        data = dict(document.get("pipeline", {}))
        where = f"{args.config} [pipeline]"
        readout_us = document.get("capture", {}).get("readout_us", 0)
        readout_where = f"{args.config} [capture] readout_us"
    if args.readout_us is not None:
        readout_us, readout_where = args.readout_us, "--readout-us"
    overrides: dict[str, Any] = {"method": args.method, "plane_file": args.plane}
    if args.fixed_end is not None:
        overrides["fixed_end_uv"] = tuple(args.fixed_end)
    config = from_mapping(PipelineConfig, data, where=where, **overrides)
    exposure_us = None if args.exposure_ms is None else args.exposure_ms * 1000.0
    return run_extract(
        args.input, args.out, config, args.fps, exposure_us, args.limit, not args.quiet, readout_us, readout_where
    )


def run_extract(
    input_path: str | Path,
    out_path: str | Path,
    config: Any,
    fps: float | None = None,
    exposure_us: float | None = None,
    limit: int | None = None,
    progress: bool = False,
    readout_us: int = 0,
    readout_where: str = "readout_us",
) -> int:
    """Run the pipeline over `input_path` and write JSON lines to `out_path`; returns the exit code (0).

    `readout_us` is the rolling shutter's readout time (0: global shutter; `readout_where` names where it was set,
    for messages); `config.plane_file` a plane calibration. Both are checked before anything is written.

    Raises
    ------
    CaptureError
        The input cannot be opened.
    ConfigError
        A bad `readout_us` (negative, longer than the frame period) or plane file (unreadable, its origin outside
        the image, another image size).
    DataError
        The output cannot be written.
    """
    from ropecam.device.capture.sources import open_source
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.shared.config import check_readout
    from ropecam.shared.errors import DataError
    from ropecam.shared.plane import read_plane_file

    plane = None if config.plane_file is None else read_plane_file(config.plane_file)
    if plane is not None:
        plane.check_image(plane.image_size)
    source = open_source(input_path, fps, exposure_us)
    check_readout(readout_where, readout_us, source.fps)
    frames: Iterator[Any] = iter(source)
    image_size = source.image_size
    if image_size is None:  # an image folder or a video: its first readable frame gives the size
        ahead = []
        for item in frames:
            ahead.append(item)
            if item.image is not None or (limit is not None and len(ahead) >= limit):
                break
        if ahead and ahead[-1].image is not None:
            image_size = (ahead[-1].image.shape[1], ahead[-1].image.shape[0])
        frames = itertools.chain(ahead, frames)
    pipeline_first: Pipeline | None = None
    if image_size is not None:  # every check that can fail (mask, plane, readout) before the output is created
        pipeline_first = Pipeline(config, image_size, readout_us, plane)
        pipeline_first.warm_up()  # as the daemon: the first frame's time is its measurement's, not the set-up's
    total = len(source)
    if limit is not None:
        total = min(total, limit) if total else limit
    statuses: Counter[str] = Counter()
    times_us: list[float] = []
    pipeline = pipeline_first
    started = time.monotonic()
    last_report = started
    try:
        handle = sys.stdout if str(out_path) == "-" else open(out_path, "w")  # noqa: SIM115
    except OSError as exc:
        raise DataError(f"{out_path}: cannot write results: {exc.strerror}") from exc
    try:
        for count, item in enumerate(frames):
            if limit is not None and count >= limit:
                break
            image = item.image
            if image is not None and (pipeline is None or source.independent):  # a photo: measured on its own
                pipeline = Pipeline(config, (image.shape[1], image.shape[0]), readout_us, plane)
                pipeline.warm_up()
            if pipeline is None or image is None:
                record = _bad_frame(item.index, item.t_ns, item.exposure_us, item.message or "unreadable frame")
            else:
                result = pipeline.process(image, item.index, item.t_ns, item.exposure_us)
                if item.message and result.message == "":
                    result.message = item.message
                record = result.to_json()
                times_us.append(result.pipeline_us)
            statuses[record["status"]] += 1
            handle.write(json.dumps(record, separators=(",", ":")) + "\n")
            handle.flush()
            now = time.monotonic()
            if progress and now - last_report >= 1.0:
                last_report = now
                rate = (count + 1) / (now - started)
                of = f"/{total}" if total else ""
                print(f"extract: {count + 1}{of} frames, {rate:.0f} frames/s", file=sys.stderr, flush=True)
    except OSError as exc:
        raise DataError(f"{out_path}: cannot write results: {exc.strerror}") from exc
    finally:
        if handle is not sys.stdout:
            handle.close()
    frames = sum(statuses.values())
    if progress or frames == 0:
        summary = ", ".join(f"{k} {v}" for k, v in sorted(statuses.items())) or "no frames"
        median = f", median pipeline time {sorted(times_us)[len(times_us) // 2]:.0f} us" if times_us else ""
        print(f"extract: {frames} frames from {source.kind} {input_path}: {summary}{median}", file=sys.stderr)
    return 0


def _bad_frame(index: int, t_ns: int, exposure_us: float | None, message: str) -> dict[str, Any]:
    from ropecam.device.pipeline.result import FrameStatus, PipelineResult

    try:  # as `Pipeline.process`: an unknown or unusable exposure time gives t_end_ns == t_ns
        exposure_ns = max(0, round(float(exposure_us) * 1000)) if exposure_us is not None else 0
    except (TypeError, ValueError, OverflowError):
        exposure_ns = 0
    result = PipelineResult(index, t_ns, int(t_ns) + exposure_ns, FrameStatus.BAD_FRAME, message=message)
    return result.to_json()
