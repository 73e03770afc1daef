"""Harris corners against the segmentation points (the paper's Fig. 7), scored on the simulator's true tips.

The paper shows that a Harris detector marks many points along the blurred rope's edge while its segmentation
operator marks the few that split the band. Here both are measured against ground truth: for each frame, the
rope's true free tip at the start and at the end of the exposure (two points) are compared with

* ``harris``: `cv2.goodFeaturesToTrack(..., useHarrisDetector=True)` on the Canny edge map of the frame, as in
  the paper's figure (or on the blurred frame itself with ``--on frame``);
* ``paper`` and ``blur_split`` (the default method): the segmentation points the pipeline reports
  (`PipelineResult.segmentation_points`; none on frames where the method fell back to a centreline).

Per exposure and detector it prints: points per frame, the share of true tips with a point within
``--radius-px`` (detected), the mean and p95 distance from each true tip to the nearest point, and the share of
points that are within ``--radius-px`` of a true tip (precision).

    python tools/evaluate.py harris [--frameset DIR ...] [--exposures-ms 1 5 9 15] [--frames 24]
                                   [--radius-px 3] [--on edges|frame] [--fixed-end auto|truth]
                                   [--plot fig.png] [--json]

Without ``--frameset`` the synthetic renderer of `tools/evaluate.py accuracy` provides the frames and truth.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import cv2
import numpy as np

from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam_tools.cli import UsageError
from ropecam_tools.eval_accuracy import build_sequences

DETECTORS = ("harris", "paper", "blur_split")


def harris_points(image: np.ndarray, on: str, quality: float, min_distance_px: float, block: int) -> np.ndarray:
    """Harris corners (u, v) of one frame (`on` = ``frame`` or ``edges``)."""
    source = image if on == "frame" else cv2.Canny(cv2.GaussianBlur(image, (0, 0), 1.0), 20, 50, L2gradient=True)
    found = cv2.goodFeaturesToTrack(
        source, maxCorners=0, qualityLevel=quality, minDistance=min_distance_px, blockSize=block,
        useHarrisDetector=True, k=0.04,
    )  # fmt: skip
    return np.zeros((0, 2)) if found is None else found.reshape(-1, 2).astype(np.float64)


def score(points_per_frame: list[np.ndarray], tips_per_frame: list[np.ndarray], radius_px: float) -> dict[str, Any]:
    """Distances of the true tips to the nearest reported point, detection rate and precision."""
    distances, near_points, total_points = [], 0, 0
    detected = 0
    tips_total = 0
    for points, tips in zip(points_per_frame, tips_per_frame, strict=True):
        tips_total += len(tips)
        total_points += len(points)
        if len(points) == 0:
            continue
        d = np.hypot(*(points[None, :, :] - tips[:, None, :]).transpose(2, 0, 1))  # (tips, points)
        nearest = d.min(axis=1)
        distances.extend(nearest.tolist())
        detected += int(np.count_nonzero(nearest <= radius_px))
        near_points += int(np.count_nonzero(d.min(axis=0) <= radius_px))
    dist = np.array(distances) if distances else np.array([np.nan])
    return {
        "points_per_frame": total_points / max(1, len(points_per_frame)),
        "detected": detected / max(1, tips_total),
        "dist_mean_px": float(np.mean(dist)),
        "dist_p95_px": float(np.percentile(dist, 95)),
        "precision": near_points / total_points if total_points else float("nan"),
    }


def score_sequence(
    sequence: list, args: argparse.Namespace, fixed_uv: tuple[float, float] | None = None
) -> tuple[list[dict[str, Any]], dict[str, list[np.ndarray]]]:
    """Score every detector on one sequence; also return the points per detector and frame (u, v)."""
    height, width = sequence[0][0].shape
    tips = [np.stack([b[-1], e[-1]]).astype(np.float64) for _, _, _, b, e in sequence]
    points: dict[str, list[np.ndarray]] = {}
    for name in DETECTORS:
        found = []
        if name == "harris":
            for image, *_ in sequence:
                found.append(harris_points(image, args.on, args.quality, args.min_distance_px, args.block_size))
        else:
            pipeline = Pipeline(PipelineConfig(method=name, fixed_end_uv=fixed_uv), (width, height))
            for index, (image, t_ns, exposure_us, _, _) in enumerate(sequence):
                r = pipeline.process(image, index, t_ns, exposure_us)
                seg = r.segmentation_points
                found.append(np.zeros((0, 2)) if seg is None else seg[:, ::-1].astype(np.float64).copy())
        points[name] = found
    rows = [{"detector": name, "frames": len(sequence), **score(points[name], tips, args.radius_px)} for name in points]
    return rows, points


def plot(
    path: str, rows: list[dict[str, Any]], example: tuple[float, np.ndarray, np.ndarray, dict], radius_px: float
) -> None:
    """Fig. 7-like example crop around the tips, and distance / detection rate against exposure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    exposure, image, tips, points = example
    centre = tips.mean(axis=0)
    half = max(25.0, 1.2 * float(np.hypot(*(tips[0] - tips[1]))))
    ax = axes[0]
    ax.imshow(image, cmap="gray", vmin=0, vmax=255)
    styles = {"harris": ("x", "tab:red"), "paper": ("o", "tab:cyan"), "blur_split": ("+", "tab:orange")}
    for name, (marker, colour) in styles.items():
        p = points[name]
        if marker == "o":
            ax.scatter(
                p[:, 0], p[:, 1], marker=marker, s=60, facecolors="none", edgecolors=colour, label=f"{name} ({len(p)})"
            )
        else:
            ax.scatter(p[:, 0], p[:, 1], marker=marker, s=60, c=colour, label=f"{name} ({len(p)})")
    ax.scatter(tips[:, 0], tips[:, 1], marker="*", s=120, c="lime", label="true tips")
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] + half, centre[1] - half)
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    ax.set_title(f"Tip region, {exposure:g} ms exposure (legend: points in the whole frame)")
    ax.legend(fontsize=8, loc="lower left")
    for name, (_, colour) in styles.items():
        pts = sorted(
            (r["exposure_ms"], r["dist_mean_px"], r["detected"], r["precision"]) for r in rows if r["detector"] == name
        )
        x = [p[0] for p in pts]
        axes[1].plot(x, [p[1] for p in pts], marker="o", color=colour, label=name)
        axes[2].plot(x, [100 * p[2] for p in pts], marker="o", color=colour, label=f"{name}: tips detected")
        axes[2].plot(x, [100 * p[3] for p in pts], marker="s", ls="--", color=colour, label=f"{name}: precision")
    axes[1].set_ylim(bottom=0)
    axes[1].set_xlabel("exposure time (ms)")
    axes[1].set_ylabel("mean distance, true tip to nearest point (px)")
    axes[1].set_title("Distance to the true tips")
    axes[2].set_xlabel("exposure time (ms)")
    axes[2].set_ylabel(f"share within {radius_px:g} px (%)")
    axes[2].set_ylim(-5, 105)
    axes[2].set_title("Tips with a point near them; points near a tip")
    for ax in axes[1:]:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Harris corners vs segmentation points (cf. the paper's Fig. 7)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--frameset", action="extend", nargs="+", help="simulator frame set(s) (with truth.npz)")
    parser.add_argument("--exposures-ms", type=float, nargs="+", default=[1.0, 5.0, 9.0, 15.0],
                        help="synthetic exposures when no --frameset is given (default 1 5 9 15)")  # fmt: skip
    parser.add_argument("--frames", type=int, default=24, help="frames per sequence (default 24)")
    parser.add_argument("--radius-px", type=float, default=3.0, help="a tip is detected within this (default 3)")
    on_help = "Harris input: the Canny edge map, as in the paper's figure (default), or the frame"
    parser.add_argument("--on", choices=("frame", "edges"), default="edges", help=on_help)
    fixed_help = "pipeline methods: find the fixed end (default) or take it from the truth"
    parser.add_argument("--fixed-end", choices=("auto", "truth"), default="auto", help=fixed_help)
    parser.add_argument("--quality", type=float, default=0.01, help="Harris quality level (default 0.01)")
    parser.add_argument("--min-distance-px", type=float, default=3.0, help="between Harris corners (default 3)")
    parser.add_argument("--block-size", type=int, default=3, help="Harris window (default 3)")
    parser.add_argument("--plot", help="write the figure (PNG) here")
    parser.add_argument("--json", action="store_true", help="print one JSON object per row")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    if args.frames < 1:
        raise UsageError(f"--frames must be >= 1, got {args.frames}")
    sequences = build_sequences(args.frameset, args.exposures_ms, args.frames, args.fixed_end)
    rows: list[dict[str, Any]] = []
    example = None
    for number, (name, exposure, seq, fixed) in enumerate(sequences, 1):
        print(f"[{number}/{len(sequences)}] {name} ({exposure:g} ms, {len(seq)} frames)", file=sys.stderr, flush=True)
        found, points = score_sequence(seq, args, fixed)
        for row in found:
            row = {"input": name, "exposure_ms": exposure, **row}
            rows.append(row)
            if args.json:
                print(json.dumps(row), flush=True)
        if example is None or exposure >= example[0]:
            k = int(np.argmax([np.hypot(*(b[-1] - e[-1])) for *_, b, e in seq]))  # the fastest tip
            tips = np.stack([seq[k][3][-1], seq[k][4][-1]])
            example = (exposure, seq[k][0], tips, {d: points[d][k] for d in DETECTORS})
    if not args.json:
        width = max(12, *(len(r["input"]) for r in rows))
        print(f"{'input':{width}s} {'exp ms':>6s} {'detector':10s} {'pts/frame':>9s} {'detected':>8s} {'mean px':>8s} "
              f"{'p95 px':>8s} {'precision':>9s}")  # fmt: skip
        for r in rows:
            print(f"{r['input']:{width}s} {r['exposure_ms']:6.1f} {r['detector']:10s} {r['points_per_frame']:9.1f} "
                  f"{100 * r['detected']:7.0f}% {r['dist_mean_px']:8.2f} {r['dist_p95_px']:8.2f} "
                  f"{100 * r['precision']:8.0f}%")  # fmt: skip
    if args.plot and example is not None:
        plot(args.plot, rows, example, args.radius_px)
        print(f"figure written to {args.plot}", file=sys.stderr)
    return 0
