"""Speed of the chessboard renderer (host/sim/boards.py): one 1024x544 view of the paper camera, median of runs.

    python tools/bench.py boards [--repeats 7] [--supersample 1]

Prints the one-off cost of the per-camera ray table (shared by a whole set) and the median per-view time; the
reference is the ray-table cost measured in the same run (a view should cost a fraction of it).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from ropecam.host.sim.boards import (
    BoardArt,
    RenderSettings,
    _intrinsic_poses,
    paper_camera,
    pixel_rays,
    render_board_view,
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--supersample", type=int, default=1)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    camera, art = paper_camera(), BoardArt()
    settings = RenderSettings(supersample=args.supersample)
    start = time.perf_counter()
    rays = pixel_rays(camera, args.supersample)
    rays_s = time.perf_counter() - start
    rng = np.random.default_rng(0)
    poses = _intrinsic_poses(camera, art, args.repeats, rng)
    times = []
    for pose in poses:
        start = time.perf_counter()
        render_board_view(camera, pose, art, rng, settings, rays)
        times.append(time.perf_counter() - start)
    view_s = statistics.median(times)
    print(f"ray table ({camera.image_size[0]}x{camera.image_size[1]}, supersample {args.supersample}): {rays_s:.3f} s")
    print(f"one view: median {view_s:.3f} s over {len(times)} views ({view_s / rays_s:.2f} x the ray table)")
    return 0
