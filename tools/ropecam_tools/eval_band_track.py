"""An edge-free band tracker's best case: the blurred band fitted frame to frame from a seed, without edges.

    python tools/evaluate.py band-track SET [--frames N] [--blur-px B] [--windows W] [--json]

A prototype measured offline (numpy/scipy, not the device's pipeline) to decide whether a model-based band fit can
replace the edge path where the band's edges are below the noise (`lab-hard`, docs/robustness.md). On a simulator
frame set (with ``truth.npz``):

* **seed** (``--seed``): frame 0's true begin centreline, width and length (a still rope: the best case of a seed
  that the device would have to find itself), or what the device has: the pipeline's frame 0 (a fresh device with
  the set's gamma and true plane) gives its begin shape whatever its status, cut at its point farthest from the
  fixed end (a first-frames shape that runs out along the rope and back, `folds_back`), and the rope's width is
  fitted across it (`fit_width`);
* **prediction**: each frame's middle line (the rope at mid-exposure, by arc fraction) extrapolated at constant
  acceleration from the three frames before (constant velocity from two); the sweep (begin to end) from the
  predicted velocity times the exposure;
* **fit**: the frame in linear light (the set's ``camera.gamma`` undone) is sampled on lines across the predicted
  middle line (every `RESAMPLE_POINTS` along the rope), and in each of `windows` windows along the rope (the first
  `SKIP_FRACTION` near the clamp left out) a model band is fitted by least squares to all the window's profiles
  together: a rope of the learned width moving linearly from the begin to the end side, Gaussian-blurred by
  `blur_px`, with level and contrast free, its middle offset (plus a slope along the window) and its sweep
  correction free under Gaussian priors (`MID_PRIOR_PX`, `SWEEP_PRIOR_PX`). The begin and end centrelines are the
  predicted ones moved along the normal by the windows' corrections (interpolated; 0 at the fixed end);
* **length**: the far end is fitted along the rope's axis at the tip (profiles across the sweep averaged, a blurred
  step: `eval_band_snr.fit_step`'s model), and the carried length moved by it when its uncertainty is small;
* **gate**: a frame is *trusted* when the far end agrees with the carried length within `CAP_GATE_PX`, its fit's
  uncertainty is below `CAP_SIGMA_GATE_PX` and the fitted tips lie less than `SWEEP_GATE_PX` apart: what a device
  could report as OK without the truth.

Per frame: the tips' and centrelines' errors against the truth (as `truth_metrics` defines them), the fit's own
indicators, and whether the frame is trusted; trusted frames with a tip over `SILENT_TIP_PX` or a centreline over
`SILENT_CURVE_PX` off are the silent failures such a device would make. Simulated frames against the simulator's
truth: label the figures with the scene.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam_tools.cli import UsageError, positive_float, positive_int
from ropecam_tools.truth_metrics import SILENT_CURVE_PX, SILENT_TIP_PX, open_truth_set, point_to_polyline, resample

RESAMPLE_POINTS = 201
"""Points of every tracked centreline, evenly spaced by arc length from the fixed end to the tip."""
SKIP_FRACTION = 0.12
"""The part of the rope nearest the fixed end (the clamp's exit) left out of the fit; its correction is interpolated
from 0 at the fixed end."""
MID_PRIOR_PX = 3.0
"""Prior standard deviation of a window's middle offset (and its slope) from the prediction (px)."""
SWEEP_PRIOR_PX = 1.0
"""Prior standard deviation of a window's sweep from the predicted sweep (px)."""
CAP_GATE_PX = 1.0
"""A frame is trusted when its far end lies within this distance of the carried length (px) ..."""
CAP_SIGMA_GATE_PX = 0.5
"""... and the far end's fit gives an uncertainty below this (px) ..."""
SWEEP_GATE_PX = 8.0
"""... and the fitted tips lie less than this apart (px): beyond about 10 px of sweep the band's far end is below the
noise even for a fit that knows where it runs (`eval_band_snr`, docs/robustness.md)."""
MAX_WINDOWS = (RESAMPLE_POINTS - 3 - int(SKIP_FRACTION * RESAMPLE_POINTS)) // 2
"""Most fit windows along the rope: each window holds at least two of the resampled points it fits."""
TAU_STEPS = 9
"""Instants of the exposure summed in the model band."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of the band tracker evaluation."""
    parser.add_argument("set", type=Path, metavar="SET", help="a simulator frame set (with truth.npz)")
    parser.add_argument("--frames", type=positive_int, default=30, metavar="N", help="frames tracked (default 30)")
    parser.add_argument("--blur-px", type=positive_float, default=0.6, metavar="B",
                        help="the model band's Gaussian blur (px; default 0.6, chosen from 0.6 / 0.8 / 1.0 on "
                        "lab-hard's tuning seed)")  # fmt: skip
    parser.add_argument("--windows", type=positive_int, default=10, metavar="W",
                        help=f"fit windows along the rope (default 10, at most {MAX_WINDOWS})")  # fmt: skip
    parser.add_argument("--seed", choices=("truth", "pipeline"), default="truth",
                        help="seed from frame 0's truth (its centreline and width), or from the pipeline's frame 0 "
                        "(its begin shape whatever its status, cut where it turns back; the width fitted across "
                        "it)")  # fmt: skip
    parser.add_argument("--json", action="store_true", help="print the per-frame rows and the summary as JSON")


def _arc(line: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))])


def resample_to(line: NDArray[np.float64], length_px: float) -> NDArray[np.float64]:
    """Return `RESAMPLE_POINTS` points of the polyline `line` ((n, 2) u, v) evenly spaced from its start to arc
    length `length_px`, continued straight along its last direction beyond its end."""
    arcs = _arc(line)
    s = np.linspace(0.0, length_px, RESAMPLE_POINTS)
    out = np.stack([np.interp(s, arcs, line[:, 0]), np.interp(s, arcs, line[:, 1])], axis=1)
    beyond = s > arcs[-1]
    if beyond.any():
        direction = line[-1] - line[max(len(line) - 4, 0)]
        out[beyond] = line[-1] + (s[beyond] - arcs[-1])[:, None] * direction / (math.hypot(*direction) + 1e-12)
    return out


def _frame_normals(line: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    tangent = np.gradient(line, axis=0)
    tangent /= np.hypot(*tangent.T)[:, None] + 1e-12
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1), tangent


def _sample(image: NDArray[np.float64], points: NDArray[np.float64]) -> NDArray[np.float64]:
    from scipy.ndimage import map_coordinates

    return map_coordinates(image, [points[..., 1], points[..., 0]], order=1, mode="nearest")


def band_profile(
    t: NDArray[np.float64], begin: NDArray[np.float64], end: NDArray[np.float64], width_px: float, blur_px: float
) -> NDArray[np.float64]:
    """Return the share of the exposure a rope of `width_px` covers at offsets `t` while it moves linearly from
    offset `begin` to `end` (broadcast together), Gaussian-blurred by `blur_px`."""
    from scipy.special import erf

    taus = np.linspace(0.0, 1.0, TAU_STEPS)
    x = t[..., None] - (begin[..., None] + taus * (end - begin)[..., None])
    scale = math.sqrt(2.0) * blur_px
    return (0.5 * (erf((x + width_px / 2) / scale) - erf((x - width_px / 2) / scale))).mean(-1)


def fit_window(
    profiles: NDArray[np.float64], t: NDArray[np.float64], begin0: NDArray[np.float64], end0: NDArray[np.float64],
    width_px: float, blur_px: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:  # fmt: skip
    """Fit one window's model band to its `profiles` ((m, k) at offsets `t`), the begin and end sides predicted at
    `begin0`, `end0` ((m,) offsets). Return the parameters (level, contrast, middle offset, sweep correction, slope
    of the middle offset over the window) and their standard errors (from the fit's Jacobian and residual)."""
    from scipy.optimize import least_squares

    along = (np.arange(len(begin0)) - (len(begin0) - 1) / 2) / max(len(begin0) - 1, 1)
    scale = float(np.std(profiles)) + 1e-6
    priors = np.array([math.inf, math.inf, MID_PRIOR_PX, SWEEP_PRIOR_PX, MID_PRIOR_PX])

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        level, contrast, mid, sweep, slope = q
        shift = mid + slope * along
        model = level + contrast * band_profile(
            t[None, :], (begin0 + shift - sweep / 2)[:, None], (end0 + shift + sweep / 2)[:, None], width_px, blur_px
        )
        return np.concatenate([(model - profiles).ravel(), q[2:] / priors[2:] * scale])

    start = [float(np.median(profiles)), max(float(profiles.max() - np.median(profiles)), 1.0), 0.0, 0.0, 0.0]
    fit = least_squares(residual, start, bounds=([-50.0, 0.0, -8.0, -8.0, -8.0], [300.0, 300.0, 8.0, 8.0, 8.0]))
    spread = float(np.std(fit.fun[: profiles.size]))
    try:
        errors = np.sqrt(np.diag(np.linalg.inv(fit.jac.T @ fit.jac))) * spread
    except np.linalg.LinAlgError:
        errors = np.full(5, math.inf)
    return fit.x, errors


def fit_far_end(
    image: NDArray[np.float64], tip_begin: NDArray[np.float64], tip_end: NDArray[np.float64],
    axis: NDArray[np.float64], blur_px: float,
) -> tuple[float, float]:  # fmt: skip
    """Return where the band ends along `axis` (px from the tips, positive outwards) and that fit's standard error:
    profiles along the axis through the swept arc (from `tip_begin` to `tip_end`), averaged, a blurred step fitted
    (its blur fixed at `blur_px`)."""
    from scipy.optimize import least_squares
    from scipy.special import erfc

    u = np.arange(-14.0, 10.01, 0.5)
    sweep = float(math.hypot(*(tip_end - tip_begin)))
    fractions = np.linspace(0.1, 0.9, max(3, int(sweep))) if sweep > 1 else np.array([0.5])
    lines = np.stack([(tip_begin + f * (tip_end - tip_begin))[None, :] + u[:, None] * axis[None, :] for f in fractions])
    profile = _sample(image, lines).mean(0)

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        level, height, at = q
        return level + height * 0.5 * erfc((u - at) / (math.sqrt(2.0) * blur_px)) - profile

    start = [float(np.median(profile[-8:])), max(float(np.ptp(profile)), 1.0), 0.0]
    fit = least_squares(residual, start, bounds=([-50.0, 0.0, -8.0], [300.0, 300.0, 8.0]))
    try:
        error = float(math.sqrt(np.linalg.inv(fit.jac.T @ fit.jac)[2, 2]) * np.std(fit.fun))
    except np.linalg.LinAlgError:
        error = math.inf
    return float(fit.x[2]), error


def fit_width(image: NDArray[np.float64], line: NDArray[np.float64], blur_px: float) -> float:
    """Return the width of a still rope along `line` ((n, 2) u, v) in `image`: the profiles across it (the part
    beyond `SKIP_FRACTION` of it) averaged, and a blurred bar (level, contrast, offset and width free) fitted."""
    from scipy.optimize import least_squares

    line = resample_to(line, float(_arc(line)[-1]))[int(SKIP_FRACTION * RESAMPLE_POINTS) : -3]
    normal, _ = _frame_normals(line)
    t = np.arange(-10.0, 10.01, 0.5)
    profile = _sample(image, line[:, None, :] + t[None, :, None] * normal[:, None, :]).mean(0)

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        level, contrast, at, width = q
        return level + contrast * band_profile(t, np.array(at), np.array(at), width, blur_px) - profile

    start = [float(np.median(profile)), max(float(np.ptp(profile)), 1.0), 0.0, 2.0]
    fit = least_squares(residual, start, bounds=([-50.0, 0.0, -3.0, 0.5], [300.0, 300.0, 3.0, 10.0]))
    return float(fit.x[3])


def pipeline_seed(frameset: Any) -> NDArray[np.float64]:
    """Return the begin shape ((n, 2) u, v) a fresh device (the set's gamma, its true plane) measures on frame 0,
    whatever its status, cut at its point farthest from its start (the fixed end).

    Raises
    ------
    ValueError
        The pipeline gave no shape on frame 0.
    """
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam_tools.truth_metrics import frameset_plane

    config = PipelineConfig(gamma=frameset.camera_gamma or 1.0)
    pipeline = Pipeline(config, frameset.image_size, 0, frameset_plane(frameset.meta))
    record = frameset.records[0]
    result = pipeline.process(frameset.read(0), 0, record.t_ns, float(record.exposure_us))
    if result.begin is None:
        raise ValueError(f"the pipeline gave no shape on frame 0 ({result.status.name}: {result.message})")
    shape = result.begin[:, ::-1].astype(np.float64)
    turn = int(np.argmax(np.hypot(*(shape - shape[0]).T)))
    return shape[: turn + 1]


class BandTracker:
    """Follow the band from a seed centreline, one frame at a time (see the module's docstring).

    Parameters
    ----------
    seed
        The rope at the seed frame ((n, 2) u, v, fixed end first), still during that frame's exposure.
    width_px, blur_px
        The rope's width and the model band's blur (px).
    period_ns
        The frame period.
    windows
        Fit windows along the rope.
    """

    def __init__(self, seed: NDArray[np.float64], width_px: float, blur_px: float, period_ns: float, windows: int):
        if windows < 1:
            raise ValueError(f"windows must be at least 1, got {windows}")
        self.length_px = float(_arc(seed)[-1])
        self.length0_px = self.length_px
        self.width_px, self.blur_px, self.period_ns, self.windows = width_px, blur_px, period_ns, windows
        self.mids = [resample_to(seed, self.length_px)]

    def track(self, image: NDArray[np.float64], exposure_ns: float) -> dict[str, Any]:
        """Fit the band in `image` (linear light, float) and return the begin and end centrelines (``begin``,
        ``end``), the far end's offset from the carried length and its uncertainty (``cap_px``, ``cap_sigma_px``),
        the largest standard error of a window's side (``side_sigma_px``) and whether the frame is trusted."""
        velocity = (self.mids[-1] - self.mids[-2]) / self.period_ns if len(self.mids) > 1 else 0.0 * self.mids[-1]
        if len(self.mids) > 2:  # a swinging rope accelerates: constant velocity lags and loses it at 10-15 px sweeps
            velocity = velocity + (self.mids[-1] - 2 * self.mids[-2] + self.mids[-3]) / self.period_ns
        mid = self.mids[-1] + velocity * self.period_ns
        sweep = velocity * exposure_ns
        begin0, end0 = mid - sweep / 2, mid + sweep / 2
        normal, tangent = _frame_normals(mid)
        t_begin = np.einsum("ij,ij->i", begin0 - mid, normal)
        t_end = np.einsum("ij,ij->i", end0 - mid, normal)
        reach = float(np.max(np.abs(t_end - t_begin))) / 2 + self.width_px + 8.0
        t = np.arange(-reach, reach + 0.01, 0.5)
        profiles = _sample(image, mid[:, None, :] + t[None, :, None] * normal[:, None, :])
        bounds = np.linspace(int(SKIP_FRACTION * RESAMPLE_POINTS), RESAMPLE_POINTS - 3, self.windows + 1).astype(int)
        knots, begin_shift, end_shift, sigmas = [0.0], [0.0], [0.0], []
        for a, b in itertools.pairwise(bounds):
            q, errors = fit_window(profiles[a:b], t, t_begin[a:b], t_end[a:b], self.width_px, self.blur_px)
            knots.append((a + b - 1) / 2)
            begin_shift.append(q[2] - q[3] / 2)
            end_shift.append(q[2] + q[3] / 2)
            sigmas.append(float(max(errors[2], errors[3])))
        # the last window's slope carries its offset to the tip
        tip_shift = q[2] + q[4] * ((RESAMPLE_POINTS - 1) - (a + b - 1) / 2) / max(b - a - 1, 1)
        knots.append(RESAMPLE_POINTS - 1.0)
        begin_shift.append(tip_shift - q[3] / 2)
        end_shift.append(tip_shift + q[3] / 2)
        index = np.arange(RESAMPLE_POINTS)
        begin = begin0 + np.interp(index, knots, begin_shift)[:, None] * normal
        end = end0 + np.interp(index, knots, end_shift)[:, None] * normal
        carried = resample_to(begin, self.length_px)[-1], resample_to(end, self.length_px)[-1]
        cap_px, cap_sigma_px = fit_far_end(image, carried[0], carried[1], tangent[-1], self.blur_px)
        if cap_sigma_px < 1.0 and abs(cap_px) < 6.0:
            self.length_px += cap_px
        begin, end = resample_to(begin, self.length_px), resample_to(end, self.length_px)
        sweep_px = float(math.hypot(*(end[-1] - begin[-1])))
        trusted = abs(cap_px) < CAP_GATE_PX and cap_sigma_px < CAP_SIGMA_GATE_PX and sweep_px < SWEEP_GATE_PX
        self.mids.append(resample_to(0.5 * (begin + end), self.length0_px))
        return {
            "begin": begin, "end": end, "cap_px": cap_px, "cap_sigma_px": cap_sigma_px,
            "side_sigma_px": max(sigmas), "trusted": trusted,
        }  # fmt: skip


def track_set(
    path: Path, frames: int = 30, blur_px: float = 0.6, windows: int = 10, seed: str = "truth"
) -> list[dict[str, Any]]:
    """Track the band over the first `frames` frames of the simulator frame set at `path` from frame 0 (`seed`:
    ``"truth"`` or ``"pipeline"``, see the module's docstring) and return one row per frame from frame 1 on (the
    errors against the truth, the fit's indicators, ``trusted``).

    Raises
    ------
    ValueError
        The frame set has no ground truth, fewer than 2 frames, or an unknown `seed`.
    """
    frameset, truth = open_truth_set(path)
    count = min(frames, len(frameset))
    if count < 2:
        raise UsageError(f"{path}: band-track needs at least 2 frames, got {count}")
    gamma = frameset.camera_gamma or 1.0
    if seed == "truth":
        line, width_px = truth["begin_px"][0], float(truth["width_px"][0])
    elif seed == "pipeline":
        line = pipeline_seed(frameset)
        width_px = fit_width(255.0 * (frameset.read(0).astype(np.float64) / 255.0) ** gamma, line, blur_px)
    else:
        raise ValueError(f"seed must be 'truth' or 'pipeline', got {seed!r}")
    tracker = BandTracker(line, width_px, blur_px, 1e9 / float(frameset.fps), windows)
    rows = []
    for index in range(1, count):
        image = 255.0 * (frameset.read(index).astype(np.float64) / 255.0) ** gamma
        fitted = tracker.track(image, float(frameset.records[index].exposure_us) * 1000.0)
        true_b, true_e = truth["begin_px"][index], truth["end_px"][index]
        tip = max(math.hypot(*(fitted["begin"][-1] - true_b[-1])), math.hypot(*(fitted["end"][-1] - true_e[-1])))
        curve = max(
            float(point_to_polyline(resample(true_b, 100), fitted["begin"]).mean()),
            float(point_to_polyline(resample(true_e, 100), fitted["end"]).mean()),
        )
        rows.append({
            "frame": index, "sweep_px": float(math.hypot(*(truth["tip_end_px"][index] - truth["tip_begin_px"][index]))),
            "tip_px": tip, "curve_px": curve, "cap_px": fitted["cap_px"], "cap_sigma_px": fitted["cap_sigma_px"],
            "side_sigma_px": fitted["side_sigma_px"], "trusted": bool(fitted["trusted"]),
            "silent": bool(fitted["trusted"] and (tip > SILENT_TIP_PX or curve > SILENT_CURVE_PX)),
        })  # fmt: skip
    return rows


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Return the tracked frames' figures: tip mean / p95 and centreline mean over every frame and over the trusted
    ones, the trusted and silent counts, and the first frame whose centreline is over `SILENT_CURVE_PX` off (the
    track lost)."""
    tips = np.array([r["tip_px"] for r in rows])
    curves = np.array([r["curve_px"] for r in rows])
    trusted = np.array([r["trusted"] for r in rows])
    lost = [r["frame"] for r in rows if r["curve_px"] > SILENT_CURVE_PX]
    return {
        "frames": len(rows), "tip_mean_px": float(tips.mean()), "tip_p95_px": float(np.percentile(tips, 95)),
        "curve_mean_px": float(curves.mean()), "trusted": int(trusted.sum()),
        "trusted_tip_mean_px": float(tips[trusted].mean()) if trusted.any() else math.nan,
        "trusted_tip_max_px": float(tips[trusted].max()) if trusted.any() else math.nan,
        "trusted_curve_max_px": float(curves[trusted].max()) if trusted.any() else math.nan,
        "silent": int(sum(r["silent"] for r in rows)), "lost_from": lost[0] if lost else None,
    }  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Track one frame set's band from its seed (frame 0's truth or the pipeline's frame 0); print the per-frame
    table and the summary (or JSON)."""
    if args.windows > MAX_WINDOWS:
        raise UsageError(f"--windows {args.windows}: at most {MAX_WINDOWS} (two resampled points per window)")
    if not (args.set / "truth.npz").is_file():
        raise UsageError(f"{args.set}: not a simulator frame set (no truth.npz; make one with `ropecam simulate`)")
    rows = track_set(args.set, args.frames, args.blur_px, args.windows, args.seed)
    summary = summarise(rows)
    if args.json:
        print(json.dumps({"scene": args.set.name, "seed": args.seed, "frames": rows, "summary": summary}, indent=1))
        return 0
    seeded = "frame 0's truth" if args.seed == "truth" else "the pipeline's frame 0, cut where it turns back"
    print(f"{args.set.name} (simulated; seeded with {seeded}): the band tracked without edges")
    print("| frame | sweep (px) | tip (px) | centreline (px) | far end vs length (px) | its sigma | trusted |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        trusted = ("yes" if r["trusted"] else "no") + (" (silent)" if r["silent"] else "")
        print(f"| {r['frame']} | {r['sweep_px']:.1f} | {r['tip_px']:.2f} | {r['curve_px']:.2f} | {r['cap_px']:+.2f} | "
              f"{r['cap_sigma_px']:.2f} | {trusted} |")  # fmt: skip
    s = summary
    print(f"\nall {s['frames']} frames: tip {s['tip_mean_px']:.2f} / p95 {s['tip_p95_px']:.2f} px, centreline "
          f"{s['curve_mean_px']:.2f} px; trusted {s['trusted']} (tip mean {s['trusted_tip_mean_px']:.2f}, max "
          f"{s['trusted_tip_max_px']:.2f} px, centreline max {s['trusted_curve_max_px']:.2f} px), silent "
          f"{s['silent']}; centreline over {SILENT_CURVE_PX:g} px from frame {s['lost_from']}")  # fmt: skip
    return 0
