"""Frames for the tools: the synthetic rig frames made on the fly, or the first frames of a recorded frame set."""

from __future__ import annotations

import argparse

import numpy as np

Frame = tuple[np.ndarray, int, float]
"""One frame as the pipeline takes it: (image uint8 (H, W), t_ns, exposure_us)."""


def rig_frames(count: int) -> list[Frame]:
    """`count` synthetic 1024x544 frames of the rig: 4 ms exposure at 119 FPS, a 420 px rope of 3 px on noise."""
    from ropecam.device.capture.synthetic import SyntheticRope

    rope = SyntheticRope(
        width=1024, height=544, fixed_uv=(512.3, 40.6), length_px=420.0, diameter_px=3.0, amplitude_rad=0.5,
        period_s=1.4, fps=119.0, exposure_us=4000, noise_dn=2.0,
    )  # fmt: skip
    return [(f.image, f.t_ns, float(f.exposure_us)) for f in rope.frames(count, start=5)]


def frameset_frames(path: str, count: int) -> list[Frame]:
    """The first `count` frames of the frame set in folder `path` (fewer if it has fewer)."""
    from ropecam.device.capture.frameset import FrameSet

    frameset = FrameSet(path)
    return [
        (frameset.read(i), frameset.records[i].t_ns, float(frameset.records[i].exposure_us))
        for i in range(min(count, len(frameset)))
    ]


def add_frame_arguments(parser: argparse.ArgumentParser, frames: int) -> None:
    """Add ``--frameset DIR`` (default: the synthetic rig frames) and ``--frames N`` (default `frames`)."""
    from ropecam_tools.cli import positive_int

    parser.add_argument(
        "--frameset", metavar="DIR", help="a recorded frame set (default: synthetic 1024x544 rig frames made now)"
    )
    parser.add_argument("--frames", type=positive_int, default=frames, help="frames to use (default: %(default)s)")


def frames_from(args: argparse.Namespace, count: int | None = None) -> list[Frame]:
    """The frames `add_frame_arguments`'s options choose: `count` of them (default ``args.frames``)."""
    count = args.frames if count is None else count
    return frameset_frames(args.frameset, count) if args.frameset else rig_frames(count)


def source_name(args: argparse.Namespace) -> str:
    """How a report names the frames: the frame set's folder, or the synthetic rig frames."""
    return args.frameset or "synthetic rig frames (1024x544, 4 ms)"
