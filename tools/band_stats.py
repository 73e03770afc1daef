"""Measure the region of interest (band) the pipeline builds on a frame set: its size, how much of it the rope
occupies, and how much of the prediction's margin each frame really needed.

For every frame after the first three whose band was predicted from the previous contour (the first
`band_stage` call of the frame), prints medians over the frames of:

- band rows and pixels (the spans the edge stage gets);
- rope pixels: per band row, the columns between the found contour's leftmost and rightmost pixel (the part of
  the band a one-span-per-row region cannot leave out), and their share of the band;
- the margin used (``margin_px`` and the motion uncertainty ``motion_px`` at the farthest point; `given`: the
  uncertainty the band really gave, mean over the predicted points, after the cap of the measured error) and the margin
  needed: for each contour point found, its distance to the nearest predicted point (the previous contour moved
  by the predicted rotation); `needed motion` is the smallest ``motion_px`` whose discs would still hold every
  found point, and `motion ratio` = needed / used (below 1: the margin could shrink by that factor).

    taskset -c 1 python tools/band_stats.py [--frameset /work/eval/rig] [--frames 60]
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import sys
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline


def frame_stats(frames: list[tuple[np.ndarray, int, float]], config: PipelineConfig) -> list[dict[str, float]]:
    """Run a pipeline over `frames`; return one dict of band figures per frame whose band was predicted."""
    height, width = frames[0][0].shape
    pipeline = Pipeline(config, (width, height))
    pipeline.one_call = False  # the kernels one by one: a steady frame's one call (`steady_frame`) would hide them
    band_stage = K.band_stage
    calls: list[Any] = []

    def recorded(*args: Any) -> Any:
        points, n_prev, _, use_profile, predict, t_ns, exposure_ns, margin = args[:8]
        state, log, profile, band = args[14], args[15], args[17], args[18]
        rot_a, rot_b, _ = K.predict_motion(t_ns, exposure_ns, state, log) if predict else (1.0, 0.0, 0.0)
        motion = band_stage(*args)  # (measures the last band's error first: the profile this band used)
        used = profile.copy() if use_profile else np.zeros(0)
        calls.append((points.copy(), n_prev, margin, motion, used, rot_a, rot_b, float(band[0]), float(band[1])))
        return motion

    K.band_stage = recorded
    rows_out = []
    try:
        for index, (image, t_ns, exposure_us) in enumerate(frames):
            calls.clear()
            result = pipeline.process(image, index, t_ns, exposure_us)
            if index < 3 or not calls or result.full_frame:
                continue
            points, n_prev, margin, motion, profile, rot_a, rot_b, fr, fc = calls[0][:9]
            lo, hi = pipeline.lo, pipeline.hi
            band_rows = np.flatnonzero(hi >= lo)
            band_px = int(np.sum(hi[band_rows] - lo[band_rows] + 1))
            chain = pipeline.tracer.chain[: pipeline.tracer.count]
            found = pipeline.tracer.points[: pipeline.tracer.count].astype(np.float64)
            rope_lo = np.full(height, width)
            rope_hi = np.full(height, -1)
            np.minimum.at(rope_lo, chain[:, 0], chain[:, 1])
            np.maximum.at(rope_hi, chain[:, 0], chain[:, 1])
            rope_px = int(np.sum(np.maximum(rope_hi - rope_lo + 1, 0)))
            prev = points[:n_prev].astype(np.float64)
            z = (prev[:, 0] - fr) + 1j * (prev[:, 1] - fc)
            share = np.abs(z) / max(np.abs(z).max(), 1e-12)
            moved = complex(rot_a, rot_b) * z
            predicted = np.column_stack([fr + moved.real, fc + moved.imag])
            distance, nearest = cKDTree(predicted).query(found)
            # A found point is held when distance <= margin + ceil(motion * share) of its nearest predicted point.
            needed = np.max(np.maximum(distance - margin, 0.0) / np.maximum(share[nearest], 1e-3))
            # The uncertainty the band gave (the profile's cap on motion * share), mean over the predicted points.
            given = motion * share
            if len(profile):
                given = np.minimum(given, profile[np.minimum(len(profile) - 1, (share * len(profile)).astype(int))])
            rows_out.append(
                {
                    "band_rows": len(band_rows),
                    "band_px": band_px,
                    "rope_px": rope_px,
                    "rope_share": rope_px / max(band_px, 1),
                    "margin_px": float(margin),
                    "motion_px": float(motion),
                    "needed_motion_px": float(needed),
                    "motion_ratio": float(needed / motion) if motion > 0 else float("nan"),
                    "max_miss_px": float(distance.max()),
                    "given_px": float(np.mean(given)),
                }
            )
    finally:
        K.band_stage = band_stage
    frame_stats.searches = (pipeline.roi_retries, pipeline.frames_coarse, pipeline.frames_full)  # type: ignore[attr-defined]
    return rows_out


def scale_motion(factor: float) -> None:
    """Make every pipeline's motion prediction report `factor` x its uncertainty (an experiment: the margins)."""
    from ropecam.device.pipeline.motion import MotionModel

    predict = MotionModel.predict

    def scaled(self: Any, t_ns: int, exposure_ns: int) -> tuple[float, float, float]:
        rot_a, rot_b, motion = predict(self, t_ns, exposure_ns)
        return rot_a, rot_b, motion * factor

    MotionModel.predict = scaled  # type: ignore[method-assign]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frameset", nargs="+", default=["/work/eval/rig"], help="frame set folders")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument(
        "--motion-scale", type=float, default=1.0,
        help="multiply the prediction's uncertainty (motion_px) by this, to try smaller margins (default 1)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.motion_scale != 1.0:
        scale_motion(args.motion_scale)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from bench_device import frameset_frames

    print(f"{'frame set':28s} {'frames':>6s} {'rows':>5s} {'band px':>8s} {'rope px':>8s} {'rope %':>6s} "
          f"{'margin':>6s} {'motion':>6s} {'needed':>6s} {'ratio':>6s} {'max ratio':>9s} "
          f"{'given':>6s} widened/coarse/whole")  # fmt: skip
    for folder in args.frameset:
        stats = frame_stats(frameset_frames(folder, args.frames), PipelineConfig())
        if not stats:
            print(f"{folder:28s} no predicted bands")
            continue

        def med(key: str, stats: list[dict[str, float]] = stats) -> float:
            return float(np.nanmedian([s[key] for s in stats]))

        worst = float(np.nanmax([s["motion_ratio"] for s in stats]))
        print(f"{folder[-28:]:28s} {len(stats):6d} {med('band_rows'):5.0f} {med('band_px'):8.0f} {med('rope_px'):8.0f} "
              f"{100 * med('rope_share'):6.1f} {med('margin_px'):6.1f} {med('motion_px'):6.1f} "
              f"{med('needed_motion_px'):6.1f} {med('motion_ratio'):6.2f} {worst:9.2f} {med('given_px'):6.1f} "
              f"{'/'.join(map(str, frame_stats.searches))}")  # type: ignore[attr-defined]  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
