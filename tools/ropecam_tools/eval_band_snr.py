"""What the noise leaves of a blurred rope's band: its edges' signal-to-noise ratio and how well a best-case fit
places the band's far end and its side, with the geometry taken from the simulator's truth.

    python tools/evaluate.py band-snr SET [--frames N] [--predicted] [--json]

For each frame of a simulator frame set (with ``truth.npz``), independently of the pipeline:

* ``step``: the band's level above the plate on the outer half of the rope (median over profiles across the band,
  taken along each true centreline point's normal; the band's plateau is ``contrast * w / (w + sweep)``), in the
  frame's grey levels (after the camera's gamma and sharpening, as the pipeline sees them);
* ``noise``: the plate's pixel noise (median absolute deviation of neighbouring pixels' differences / sqrt 2,
  away from the band) and after the pipeline's 1 px Gaussian smoothing (``noise_smooth``);
* ``snr_px = step / noise``: one pixel's signal-to-noise ratio; ``snr_edge = snr_px * sqrt(L)``: an edge of L
  pixels along the band averaged (L: the outer half's arc length);
* ``cap_px``, ``side_px``: the far end of the band (the arc the tip sweeps) and the begin side near the tip
  (its last 40 px), each placed by a least-squares fit of a blurred step to the profile averaged along that edge,
  the edge's geometry (the true tips, the true begin centreline) given: signed distance from the true position.

The scatter of ``cap_px`` and ``side_px`` over frames is the floor any edge or profile method meets at that noise:
it knows where to look, averages along the whole edge and fits the edge's shape. With ``--predicted`` the edges are
sought along the geometry extrapolated at constant velocity from the two frames before (their truth: what a motion
model that knew them exactly would predict), and still measured from the frame's true positions. Frames are grouped
by the tip's sweep (0-3, 3-10, 10+ px). Simulated frames against the simulator's truth: label the figures with the
scene.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam_tools.truth_metrics import open_truth_set

SWEEP_CLASSES_PX = ((0.0, 3.0), (3.0, 10.0), (10.0, math.inf))
"""Frames are summarised by the tip's sweep in these ranges (px)."""
SIDE_LENGTH_PX = 40.0
"""The begin side is fitted over this much of the rope's arc before the tip."""
SMOOTH_SIGMA_PX = 1.0
"""The pipeline's default Gaussian smoothing before its edges."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of the band SNR evaluation."""
    parser.add_argument("set", type=Path, metavar="SET", help="a simulator frame set (with truth.npz)")
    parser.add_argument("--frames", type=int, metavar="N", help="frames measured (default all)")
    parser.add_argument("--predicted", action="store_true",
                        help="seek the far end and the side along the geometry extrapolated from the two frames "
                        "before (a motion model's best case) instead of the frame's own truth")  # fmt: skip
    parser.add_argument("--json", action="store_true", help="print the per-frame rows and the summary as JSON")


def _sample(image: NDArray[np.float64], x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    from scipy.ndimage import map_coordinates

    return map_coordinates(image, [y, x], order=1, mode="nearest")


def fit_step(u: NDArray[np.float64], profile: NDArray[np.float64], bright_below: bool) -> tuple[float, float]:
    """Return the position and height of a Gaussian-blurred step fitted to `profile` sampled at `u` (least squares;
    level, height, position and blur free); the bright side is ``u < position`` when `bright_below`."""
    from scipy.optimize import least_squares
    from scipy.special import erfc

    sign = 1.0 if bright_below else -1.0
    half = (profile.max() + profile.min()) / 2

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        level, height, at, blur = q
        return level + height * 0.5 * erfc(sign * (u - at) / (math.sqrt(2) * blur)) - profile

    ends = profile[-8:] if bright_below else profile[:8]
    start = [float(np.median(ends)), max(float(np.ptp(profile)), 1.0), float(u[np.argmin(np.abs(profile - half))]), 1.2]
    fit = least_squares(residual, start, bounds=([-255.0, 0.0, u[0], 0.3], [255.0, 255.0, u[-1], 6.0]))
    return float(fit.x[2]), float(fit.x[1])


def _band_mask(shape: tuple[int, int], begin: NDArray[np.float64], end: NDArray[np.float64], margin_px: int):
    import cv2

    mask = np.zeros(shape, np.uint8)
    for line in (begin, end):
        cv2.polylines(mask, [np.round(line).astype(np.int32)], False, 1, thickness=margin_px)
    cv2.fillPoly(mask, [np.concatenate([begin, end[::-1]]).astype(np.int32)], 1)
    return mask.astype(bool)


def _mad(values: NDArray[np.float64]) -> float:
    return float(np.median(np.abs(values - np.median(values))) * 1.4826)


def _normal(line: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    tangent = line[min(k + 1, len(line) - 1)] - line[max(k - 1, 0)]
    tangent = tangent / (math.hypot(*tangent) + 1e-12)
    return np.array([-tangent[1], tangent[0]])


def predict(truth: Any, index: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return frame `index`'s begin centreline and begin and end tips extrapolated at constant velocity from the
    two frames before it (``index >= 2``; frames evenly spaced): where a motion model that knew those frames
    exactly would look."""
    if index < 2:
        raise ValueError(f"a prediction needs two earlier frames, got frame {index}")
    begin, tip_begin, tip_end = (
        2.0 * truth[key][index - 1] - truth[key][index - 2] for key in ("begin_px", "tip_begin_px", "tip_end_px")
    )
    return begin, tip_begin, tip_end


def measure_frame(
    image: NDArray[np.float64], truth: Any, index: int, predicted: tuple[NDArray[np.float64], ...] | None = None
) -> dict[str, float]:
    """Return one frame's row (see the module's docstring) from its image (float grey levels) and the set's truth;
    with `predicted` (`predict`'s begin centreline and tips) the far end and the side are sought along the
    predicted geometry instead of the true one, their positions still measured from the true ones."""
    import cv2

    width = float(truth["width_px"][index])
    begin, end = truth["begin_px"][index], truth["end_px"][index]
    tip_begin, tip_end = truth["tip_begin_px"][index], truth["tip_end_px"][index]
    sweep = float(math.hypot(*(tip_end - tip_begin)))
    plate = ~_band_mask(image.shape, begin, end, int(2 * width + 25))
    diff = image[:, 1:] - image[:, :-1]
    noise = _mad(diff[plate[:, 1:] & plate[:, :-1]]) / math.sqrt(2)
    smooth = cv2.GaussianBlur(image, (0, 0), SMOOTH_SIGMA_PX)
    high_pass = smooth - cv2.GaussianBlur(image, (0, 0), 4 * SMOOTH_SIGMA_PX)
    noise_smooth = _mad(high_pass[plate])
    count = len(begin)
    steps = []
    for k in range(count // 2, count, 4):
        normal = _normal(begin, k)
        ahead = float(np.dot(end[k] - begin[k], normal))
        a0, a1 = min(0.0, ahead) - width / 2, max(0.0, ahead) + width / 2
        t = np.arange(a0 - 12, a1 + 12.01, 0.5)
        values = _sample(image, begin[k][0] + t * normal[0], begin[k][1] + t * normal[1])
        inside = (t > a0 + 0.3 * width) & (t < a1 - 0.3 * width)
        outside = (t < a0 - 4) | (t > a1 + 4)
        if inside.any():
            steps.append(float(np.mean(values[inside]) - np.median(values[outside])))
    step = float(np.median(steps)) if steps else math.nan
    arc = float(np.hypot(*np.diff(begin[count // 2 :], axis=0).T).sum())
    # where the edges are sought: the true geometry, or the predicted one
    look, look_tb, look_te = (begin, tip_begin, tip_end) if predicted is None else predicted
    # the far end: profiles along the rope's axis through the swept arc, averaged, fitted
    axis = look[-1] - look[-6]
    axis = axis / math.hypot(*axis)
    u = np.arange(-14.0, 10.01, 0.5)
    look_sweep = float(math.hypot(*(look_te - look_tb)))
    fractions = np.linspace(0.1, 0.9, max(3, int(look_sweep))) if look_sweep > 1 else np.array([0.5])
    lines = [(look_tb + f * (look_te - look_tb))[:, None] + u * axis[:, None] for f in fractions]
    cap = np.mean([_sample(image, x, y) for x, y in lines], 0)
    cap_px, cap_step = fit_step(u, cap, bright_below=True)
    cap_px -= float(np.dot(0.5 * (tip_begin + tip_end) - 0.5 * (look_tb + look_te), axis))
    # the begin side over the last SIDE_LENGTH_PX of arc: profiles along the normal into the band, averaged
    spacing = float(np.median(np.hypot(*np.diff(look, axis=0).T)))
    into = (look_te - look_tb) / (look_sweep + 1e-12)
    v = np.arange(-10.0, 6.01, 0.5)
    profiles, offsets = [], []
    for k in range(count - 1 - int(SIDE_LENGTH_PX / spacing), count - 4):
        normal = _normal(look, k)
        normal = normal if np.dot(normal, into) >= 0 else -normal
        profiles.append(_sample(image, look[k][0] + v * normal[0], look[k][1] + v * normal[1]))
        offsets.append(float(np.dot(begin[k] - look[k], normal)))  # the true side from the sought one
    side_px, _ = fit_step(v, np.mean(profiles, 0), bright_below=False)
    side_px -= float(np.mean(offsets))
    return {
        "frame": index, "sweep_px": sweep, "step": step, "noise": noise, "noise_smooth": noise_smooth,
        "snr_px": step / noise, "snr_edge": step / noise * math.sqrt(arc), "cap_step": cap_step,
        "cap_px": cap_px, "side_px": side_px,
    }  # fmt: skip


def summarise(rows: list[dict[str, float]]) -> list[dict[str, float]]:
    """Return one summary per sweep class of `SWEEP_CLASSES_PX` with frames: medians of the step, noise and SNRs,
    and the far end's and the side's fitted positions (mean: the bias of the step model; scatter: the standard
    deviation and the median absolute deviation x 1.4826, robust to the odd failed fit)."""
    out = []
    for lo, hi in SWEEP_CLASSES_PX:
        chosen = [r for r in rows if lo <= r["sweep_px"] < hi]
        if not chosen:
            continue
        col = {key: np.array([r[key] for r in chosen]) for key in chosen[0]}
        out.append({
            "sweep_from_px": lo, "sweep_to_px": hi, "frames": len(chosen),
            **{key: float(np.median(col[key])) for key in ("step", "noise", "noise_smooth", "snr_px", "snr_edge")},
            "cap_mean_px": float(col["cap_px"].mean()), "cap_std_px": float(col["cap_px"].std()),
            "cap_mad_px": _mad(col["cap_px"]), "side_mean_px": float(col["side_px"].mean()),
            "side_std_px": float(col["side_px"].std()), "side_mad_px": _mad(col["side_px"]),
        })  # fmt: skip
    return out


def measure_set(path: Path, frames: int | None = None, predicted: bool = False) -> list[dict[str, float]]:
    """Return the rows of every frame (at most `frames`) of the simulator frame set at `path`; with `predicted`,
    the edges sought along `predict`'s geometry (from frame 2 on).

    Raises
    ------
    ValueError
        The frame set has no ground truth.
    """
    frameset, truth = open_truth_set(path)
    count = len(frameset) if frames is None else min(frames, len(frameset))
    first = 2 if predicted else 0
    return [
        measure_frame(frameset.read(i).astype(np.float64), truth, i, predict(truth, i) if predicted else None)
        for i in range(first, count)
    ]


def run(args: argparse.Namespace) -> int:
    """Measure the band's SNR and the best-case edge placement of one frame set; print the table (or JSON)."""
    rows = measure_set(args.set, args.frames, args.predicted)
    summary = summarise(rows)
    if args.json:
        print(json.dumps({"scene": args.set.name, "frames": rows, "summary": summary}, indent=1))
        return 0
    where = "extrapolated from the two frames before" if args.predicted else "from the truth"
    print(f"{args.set.name} (simulated; geometry {where}): the band against the plate's noise")
    print("| tip sweep (px) | frames | step (DN) | noise px / smoothed (DN) | SNR per px | SNR along the outer "
          "half | far end: bias / scatter (px) | side: bias / scatter (px) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for s in summary:
        span = f"{s['sweep_from_px']:.0f}" + ("+" if math.isinf(s["sweep_to_px"]) else f"-{s['sweep_to_px']:.0f}")
        print(f"| {span} | {s['frames']} | {s['step']:.1f} | {s['noise']:.1f} / {s['noise_smooth']:.1f} | "
              f"{s['snr_px']:.2f} | {s['snr_edge']:.1f} | {s['cap_mean_px']:+.2f} / {s['cap_std_px']:.2f} "
              f"(MAD {s['cap_mad_px']:.2f}) | {s['side_mean_px']:+.2f} / {s['side_std_px']:.2f} "
              f"(MAD {s['side_mad_px']:.2f}) |")  # fmt: skip
    return 0
