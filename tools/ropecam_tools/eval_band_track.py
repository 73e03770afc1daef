"""An edge-free band tracker's best case: the blurred band fitted frame to frame from a seed, without edges.

    python tools/evaluate.py band-track SET [--frames N] [--blur-px B] [--windows W] [--no-search] [--json]

A prototype measured offline (numpy/scipy, not the device's pipeline) to decide whether a model-based band fit can
replace the edge path where the band's edges are below the noise (`lab-hard`, docs/robustness.md). On a simulator
frame set (with ``truth.npz``):

* **seed** (``--seed``): frame 0's true begin centreline, width and length (a still rope: the best case of a seed
  that the device would have to find itself), or what the device has: the pipeline's frame 0 (a fresh device with
  the set's gamma and true plane) gives its begin shape whatever its status, cut at its point farthest from the
  fixed end (a first-frames shape that runs out along the rope and back, `folds_back`), and the rope's width is
  fitted across it (`fit_width`);
* **prediction**: each frame's middle line (the rope at mid-exposure, by arc fraction) from a quadratic in time
  fitted per point to the last `HISTORY` frames' middle lines and to their own sweeps (a velocity measured within
  the frame, once the prediction gives its sign), evaluated one period ahead; the sweep (begin to end) from that
  velocity times the exposure (`BandTracker.predict`);
* **fit**: the frame in linear light (the set's ``camera.gamma`` undone) is sampled on lines across the predicted
  middle line (every `RESAMPLE_POINTS` along the rope), and in each of `windows` windows along the rope (the first
  `SKIP_FRACTION` near the clamp left out) a model band is fitted by least squares to all the window's profiles
  together: a rope of the learned width moving linearly from the begin to the end side, Gaussian-blurred by
  `blur_px` (the exposure integrated in closed form, `band_profile`), with level and contrast free, its middle
  offset (plus a slope along the window) and its sweep correction free under Gaussian priors (`MID_PRIOR_PX`,
  `SWEEP_PRIOR_PX`). The begin and end centrelines are the
  predicted ones moved along the normal by the windows' corrections (interpolated; 0 at the fixed end);
* **tip** (the default; ``--straight-tip`` for session 17's model): the outer `TIP_WINDOWS` windows and the far end
  are one fit (`fit_tip`): the profiles from the outer part's start to `TIP_BEYOND_PX` beyond the carried length
  (every 0.5 px along the line near the far end), one model band whose middle offset is a quadratic along the part
  (the offset at the carried length, a slope and a curvature under a prior: the tip is measured where it is, not a
  straight window's offset extrapolated to a curling tip), cut square by a blurred step along the line whose
  position from the carried length (``cap``) is free;
* **length**: the far end (with ``--straight-tip``: fitted apart along the rope's axis at the tip, profiles across
  the sweep averaged, a blurred step: `eval_band_snr.fit_step`'s model) updates the carried length through a scalar
  Kalman filter (the length drifts by `LENGTH_DRIFT_PX` a frame at most; a far end beyond `CAP_INNOVATION_GATE`
  standard deviations is not used);
* **uncertainty**: the tips' standard error: across the rope the tip fit's offset and sweep (with
  ``--straight-tip``: the last window's offset, slope and sweep) propagated with their covariance (the Jacobian's,
  widened by the residuals' correlation along the profiles), along it the carried length's;
* **lock and re-acquisition** (``--search``, the default): each frame minus the median of `BACKGROUND_FRAMES`
  frames of the set (setup's learned background), smoothed, is searched for the band without the track: the last
  sure middle line (locked, its far end within the length's gate) turned about the fixed end and bent at
  `SEARCH_JOINTS` joints (`search_rope`, the device kernel `search_band_line`). A frame is *locked* when the evidence
  along the tracked middle line's outer part (from `LOCK_FROM`) is at least `LOCK_RATIO` of the search's line's. A
  frame that is not locked, or whose far end the length's gate refuses, is a *doubt*: it is not the search's next
  shape (a runaway line would turn its own shape and keep its score ratio near 1), and after two doubts in a row
  the track restarts from the search's lines of those two frames: the next frame is searched (from the
  last found line) before it is fitted, instead of extrapolated from the two, and the carried length's uncertainty
  is widened to `RESEED_LENGTH_SIGMA_PX`, so that the tip fit measures the far end afresh;
* **gate**: a frame is *trusted* when it is locked, the far end agrees with the carried length (within
  `CAP_INNOVATION_GATE` standard deviations), the tips' standard error is below `TIP_SIGMA_GATE_PX` and no window's
  contrast fell below `CONTRAST_GATE` of their median, and (after a re-seed) the searched lines have left the
  prediction's history (`HISTORY` frames): what a device could report as OK without the truth.

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
import time
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
TIP_SIGMA_GATE_PX = 0.5
"""... and the tips' standard error (across from the last window's fit, along from the carried length) is below
this (px) ..."""
CONTRAST_GATE = 0.5
"""... and no window's fitted contrast is below this share of the windows' median (a window that lost the band) ..."""
TIP_MARGIN_POINTS = 2
"""Resampled points at the tip left out of the side fit (the band's far end)."""
MAX_WINDOWS = (RESAMPLE_POINTS - 3 - int(SKIP_FRACTION * RESAMPLE_POINTS)) // 2
"""Most fit windows along the rope: each window holds at least two of the resampled points it fits."""
HISTORY = 5
"""Frames whose middle lines and sweeps the motion prediction fits (a quadratic in time per point)."""
VELOCITY_WEIGHT = 0.3
"""Weight of a frame's own sweep (as a velocity) against its middle line in the prediction's fit: the sweep is
measured over the exposure (a fraction of the period), so its velocity is noisier than the middle lines'."""
SIGN_SWEEP_PX = 3.0
"""A frame's sweep counts as a velocity only when the tip's predicted sweep is at least this (px): a band is the same
whichever side the rope started from, so its sign comes from the prediction."""
CURVATURE_PRIOR = 0.05
"""A weak prior (zero acceleration) that keeps the quadratic determined while only one or two frames are known."""
LENGTH_SIGMA0_PX = 0.5
"""Uncertainty of the seed's length (px)."""
LENGTH_DRIFT_PX = 0.3
"""How much the rope's length in the image may change from frame to frame (px; the projection changes it by about
0.15 px per frame on `lab-hard`'s swing)."""
CAP_BIAS_PX = 0.3
"""Error of the far end's fit beyond its statistical one (px: the step model's bias)."""
CAP_INNOVATION_GATE = 3.0
"""A far end further than this many standard deviations from the carried length is not used for the length."""
STILL_SWEEP_PX = 1e-6
"""A sweep below this (px) is a still rope in the model band (the moving band's closed form divides by the sweep)."""
SWEEP_START_PX = 0.1
"""The sweep correction's start in a fit whose predicted sweep is below this everywhere (px): the model band is even
in the sweep, so from a still prediction a fit started at 0 has no gradient in it and stays there, its uncertainty
the prior's."""
SEARCH_TURN_DEG = 45.0
"""The re-acquisition search turns each joint of the last locked middle line by up to this much (degrees)."""
SEARCH_JOINTS = 8
"""Joints of the re-acquisition search's bent line (evenly spaced from the fixed end)."""
LOCK_FROM = 0.6
"""The lock compares the evidence along the outer part of the lines from this fraction of the rope on, where a
lost track strays first."""
SEARCH_SMOOTH_PX = 3.0
"""Gaussian smoothing of the frame minus its background for the re-acquisition search (px)."""
LOCK_RATIO = 0.99
"""A frame is locked when the evidence along the tracked middle line is at least this share of the search's best
line's; two frames in a row below it and the track is re-seeded from the search."""
TIP_WINDOWS = 2
"""The outer windows replaced by one fit of the rope's outer part together with its far end (`fit_tip`)."""
TIP_BEYOND_PX = 18.0
"""How far beyond the carried length the tip fit samples the plate (px; beyond `CAP_REACH_PX`)."""
TIP_FINE_PX = 12.0
"""The tip fit samples its profiles every 0.5 px along the line within this of the carried length (px), every
2 px before: the far end is a step along the line."""
CURL_PRIOR_PX = 2.0
"""Prior standard deviation of the tip fit's curvature term (px at the start of the part, its offset and slope
held)."""
CAP_REACH_PX = 15.0
"""The tip fit seeks the far end within this of the carried length (px)."""
RESEED_LENGTH_SIGMA_PX = 5.0
"""The carried length's uncertainty after a re-seed (px): the far end is then measured afresh."""
CAP_PRIOR_PX = 8.0
"""A weak prior on the far end's offset from the carried length in the tip fit (px): the carried length has its own
uncertainty, which the Kalman filter combines."""
BACKGROUND_FRAMES = 48
"""Frames whose per-pixel median is the background of the re-acquisition search (setup's count)."""


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
    parser.add_argument("--no-search", dest="search", action="store_false",
                        help="track without the search that checks the lock and re-seeds a lost track (and "
                        "without the background it needs)")  # fmt: skip
    parser.add_argument("--straight-tip", dest="tip_fit", action="store_false",
                        help="carry the last window's straight offset to the tip and fit the far end apart (session "
                        "17's model) instead of fitting the outer windows and the far end together")  # fmt: skip
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


def _erf_integral(z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the integral of the standard normal distribution function up to `z`: z Phi(z) + phi(z)."""
    from scipy.special import ndtr

    return z * ndtr(z) + np.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)


def band_profile(
    t: NDArray[np.float64], begin: NDArray[np.float64], end: NDArray[np.float64], width_px: float, blur_px: float
) -> NDArray[np.float64]:
    """Return the share of the exposure a rope of `width_px` covers at offsets `t` while it moves linearly from
    offset `begin` to `end` (broadcast together), Gaussian-blurred by `blur_px`.

    The exposure is integrated in closed form: a blurred side at offset a - tau d (tau over the exposure, d the
    sweep) averages to blur / d (G(a / blur) - G((a - d) / blur)), G the normal distribution's integral
    (`_erf_integral`). A sum over a few instants would leave ripples between them: at 17 px of sweep nine instants
    are 2.1 px apart against a 2 px rope and 0.6 px of blur, and the model's plateau (2 / 17 of the contrast)
    ripples by half its height."""
    from scipy.special import ndtr

    sweep = np.asarray(end - begin, dtype=np.float64)
    still = np.abs(sweep) < STILL_SWEEP_PX
    divisor = np.where(still, 1.0, sweep)

    def side(a: NDArray[np.float64]) -> NDArray[np.float64]:
        moving = blur_px / divisor * (_erf_integral(a / blur_px) - _erf_integral((a - divisor) / blur_px))
        return np.where(still, ndtr((a - 0.5 * sweep) / blur_px), moving)

    x = t - begin
    return side(x + width_px / 2) - side(x - width_px / 2)


def fit_window(
    profiles: NDArray[np.float64], t: NDArray[np.float64], begin0: NDArray[np.float64], end0: NDArray[np.float64],
    width_px: float, blur_px: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:  # fmt: skip
    """Fit one window's model band to its `profiles` ((m, k) at offsets `t`), the begin and end sides predicted at
    `begin0`, `end0` ((m,) offsets). Return the parameters (level, contrast, middle offset, sweep correction, slope
    of the middle offset over the window) and their covariance (from the fit's Jacobian and residual, widened by
    the residuals' correlation along the profiles)."""
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

    sweep0 = SWEEP_START_PX if float(np.max(np.abs(end0 - begin0))) < SWEEP_START_PX else 0.0
    start = [float(np.median(profiles)), max(float(profiles.max() - np.median(profiles)), 1.0), 0.0, sweep0, 0.0]
    fit = least_squares(residual, start, bounds=([-50.0, 0.0, -8.0, -8.0, -8.0], [300.0, 300.0, 8.0, 8.0, 8.0]))
    return fit.x, _covariance(fit, profiles.shape)


def _covariance(fit: Any, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """Return the covariance of a profile fit's parameters (`fit`: scipy's least-squares result whose first
    residuals are the profiles' of `shape`, the priors' after them)."""
    residuals = fit.fun[: shape[0] * shape[1]].reshape(shape)
    spread = float(np.std(residuals))
    # neighbouring samples of a profile share the noise (0.5 px steps, a sharpened sensor): the Jacobian's
    # covariance assumes independent samples, so widen it by the residuals' own correlation along the profile
    centred = residuals - residuals.mean()
    rho = float(np.sum(centred[:, 1:] * centred[:, :-1]) / (np.sum(centred * centred) + 1e-12))
    rho = min(max(rho, 0.0), 0.95)
    try:
        return np.linalg.inv(fit.jac.T @ fit.jac) * spread**2 * (1.0 + rho) / (1.0 - rho)
    except np.linalg.LinAlgError:
        return np.full((len(fit.x), len(fit.x)), math.inf)


def _along(
    line: NDArray[np.float64], arcs: NDArray[np.float64], values: NDArray[np.float64], s: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Interpolate per-point `values` ((n, ...) of `line`, at arc lengths `arcs`) at arc lengths `s`, held at the
    last point's value beyond the line's end."""
    flat = values.reshape(len(values), -1)
    out = np.stack([np.interp(s, arcs, flat[:, k]) for k in range(flat.shape[1])], axis=1)
    return out.reshape(-1, *values.shape[1:])


def fit_tip(
    image: NDArray[np.float64], mid: NDArray[np.float64], normal: NDArray[np.float64],
    t_begin: NDArray[np.float64], t_end: NDArray[np.float64], start: int, length_px: float,
    width_px: float, blur_px: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:  # fmt: skip
    """Fit the rope's outer part and its far end together: from resampled point `start` of the predicted middle line
    `mid` ((n, 2), its normals `normal`, the predicted sides' offsets `t_begin`, `t_end` along them) to
    `TIP_BEYOND_PX` beyond the carried length `length_px` (the middle line continued straight), one model band whose
    middle offset is a quadratic along the part (its value at the carried length, its slope and its curvature: the
    tip is measured where it is, not extrapolated from a window's straight offset), with a sweep correction, cut
    square at the far end (a blurred step along the line, its position ``cap`` from the carried length free).

    Return the parameters (level, contrast, offset at the carried length, sweep correction, slope, curvature, cap),
    their covariance (the Jacobian's, widened by the residuals' correlation along the profiles) and the shift of
    the middle at each resampled point from `start` on."""
    from scipy.optimize import least_squares
    from scipy.special import erfc

    arcs = _arc(mid)
    s_start = float(arcs[start])
    span = max(length_px - s_start, 1.0)
    fine_from = length_px - TIP_FINE_PX
    s = np.concatenate([np.arange(s_start, fine_from, 2.0), np.arange(fine_from, length_px + TIP_BEYOND_PX, 0.5)])
    beyond = np.maximum(s - arcs[-1], 0.0)
    direction = mid[-1] - mid[-4]
    direction /= math.hypot(*direction) + 1e-12
    points = _along(mid, arcs, mid, s) + beyond[:, None] * direction[None, :]
    normals = _along(mid, arcs, normal, s)
    normals /= np.hypot(*normals.T)[:, None] + 1e-12
    tb, te = np.interp(s, arcs, t_begin), np.interp(s, arcs, t_end)
    reach = float(np.max(np.abs(te - tb))) / 2 + width_px + 8.0
    t = np.arange(-reach, reach + 0.01, 0.5)
    profiles = _sample(image, points[:, None, :] + t[None, :, None] * normals[:, None, :])
    x = (s - length_px) / span
    scale = float(np.std(profiles)) + 1e-6
    priors = np.array([math.inf, math.inf, MID_PRIOR_PX, SWEEP_PRIOR_PX, MID_PRIOR_PX, CURL_PRIOR_PX, CAP_PRIOR_PX])
    root2blur = math.sqrt(2.0) * blur_px

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        level, contrast, offset, sweep, slope, curl, cap = q
        shift = offset + slope * x + curl * x * x
        across = band_profile(
            t[None, :], (tb + shift - sweep / 2)[:, None], (te + shift + sweep / 2)[:, None], width_px, blur_px
        )
        along = 0.5 * erfc((s - length_px - cap) / root2blur)
        model = level + contrast * across * along[:, None]
        return np.concatenate([(model - profiles).ravel(), q[2:] / priors[2:] * scale])

    inside = s < length_px - 2.0
    first = [float(np.median(profiles)), max(float(profiles[inside].max() - np.median(profiles)), 1.0)]
    sweep0 = SWEEP_START_PX if float(np.max(np.abs(te - tb))) < SWEEP_START_PX else 0.0
    fit = least_squares(
        residual, [*first, 0.0, sweep0, 0.0, 0.0, 0.0],
        bounds=([-50.0, 0.0, -8.0, -8.0, -8.0, -8.0, -CAP_REACH_PX], [300.0, 300.0, 8.0, 8.0, 8.0, 8.0, CAP_REACH_PX]),
    )  # fmt: skip
    xs = (arcs[start:] - length_px) / span
    offset, slope, curl = fit.x[2], fit.x[4], fit.x[5]
    return fit.x, _covariance(fit, profiles.shape), offset + slope * xs + curl * xs * xs


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


def median_background(frameset: Any, gamma: float, count: int) -> NDArray[np.float64]:
    """Return the per-pixel median (linear light) of `count` frames spread over `frameset`: the plate and every
    static structure (clamp, second cable) without the moving rope, as setup's learned background is."""
    picks = np.unique(np.linspace(0, len(frameset) - 1, min(count, len(frameset))).astype(int))
    stack = np.stack([(frameset.read(int(i)).astype(np.float32) / 255.0) ** gamma for i in picks])
    return 255.0 * np.median(stack, axis=0).astype(np.float64)


def chained(shape: NDArray[np.float64], angles: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return `shape` ((n, 2), fixed end first) bent at `len(angles)` evenly spaced joints from its first point:
    the part beyond joint k turned by ``angles[k]`` (rad) about it, joint by joint from the fixed end."""
    out = shape.copy()
    for k, angle in enumerate(angles):
        joint = k * len(shape) // len(angles)
        c, s = math.cos(angle), math.sin(angle)
        d = out[joint:] - out[joint]
        out[joint:] = out[joint] + np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=1)
    return out


def bent(shape: NDArray[np.float64], turn_rad: float, bend_rad: float) -> NDArray[np.float64]:
    """Return `shape` ((n, 2), fixed end first) turned by `turn_rad` about its first point and its outer half
    turned by `bend_rad` more about its middle point."""
    return chained(shape, np.array([turn_rad, bend_rad]))


def line_score(evidence: NDArray[np.float64], line: NDArray[np.float64], start: float = SKIP_FRACTION) -> float:
    """Return the mean of `evidence` (the frame minus its background, smoothed) along `line` beyond the fraction
    `start` of it (0 outside the frame): the band's level where the line runs inside it."""
    from scipy.ndimage import map_coordinates

    points = line[int(start * len(line)) :]
    return float(map_coordinates(evidence, [points[:, 1], points[:, 0]], order=1, mode="constant", cval=0.0).mean())


def search_rope(evidence: NDArray[np.float64], shape: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """Find the band in `evidence` (the frame minus its background, smoothed, the rope brighter) without a track:
    `shape` (a middle line known before, fixed end first) bent at `SEARCH_JOINTS` joints, traced from the fixed
    end (each joint turned by up to `SEARCH_TURN_DEG` either way, the first twice that, in 0.5 degree steps, where
    the evidence along its segment and the next is highest), then every joint refined (0.25 degree steps up to 2)
    on the whole line (the device kernel `search_band_line`).
    Return the line and the evidence along it."""
    from ropecam.device.pipeline._kernels import search_band_line

    shape = np.ascontiguousarray(shape, dtype=np.float64)
    found = np.empty_like(shape)
    best = search_band_line(
        np.ascontiguousarray(evidence, dtype=np.float64), shape, SEARCH_JOINTS, SKIP_FRACTION, SEARCH_TURN_DEG, 0.5,
        2.0, 0.25, found,
    )  # fmt: skip
    return found, float(best)


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
    tip_fit
        Fit the outer `TIP_WINDOWS` windows and the far end together (`fit_tip`); without it, carry the last window's
        straight offset to the tip and fit the far end apart (session 17's model).
    restart_search
        After a re-seed, seek the next frame's band with the search before fitting it, instead of extrapolating it
        from the two searched lines.
    """

    def __init__(
        self, seed: NDArray[np.float64], width_px: float, blur_px: float, period_ns: float, windows: int,
        tip_fit: bool = True, restart_search: bool = True,
    ):  # fmt: skip
        if windows < 1:
            raise ValueError(f"windows must be at least 1, got {windows}")
        self.length_px = float(_arc(seed)[-1])
        self.length0_px = self.length_px
        self.length_var = LENGTH_SIGMA0_PX**2
        self.width_px, self.blur_px, self.period_ns, self.windows = width_px, blur_px, period_ns, windows
        self.tip_fit = tip_fit
        self.restart_search = restart_search
        self.restarted = False
        """Whether the next frame is the first after a re-seed (sought by the search before it is fitted)."""
        still = resample_to(seed, self.length_px)
        # per frame: the middle line (by arc fraction of the seed's length) and its velocity (px per frame period)
        self.mids = [still]
        self.velocities = [np.zeros_like(still)]
        self.velocity_weights = [VELOCITY_WEIGHT]  # the seed is still
        self.searched_lines = [False]
        """Per middle line of the prediction's history, whether the search gave it (a re-seed) instead of a fit."""
        self.reference = still
        self.found: NDArray[np.float64] | None = None
        self.unlocked = 0
        self.seconds: dict[str, float] = {}
        """Processor time spent per part of `track` (sample, windows, far_end, search; s), summed over the frames:
        the machine is shared, so not wall time."""
        """The last locked middle line: the shape the re-acquisition search turns and bends."""

    def _lap(self, part: str, since: float) -> float:
        now = time.process_time()
        self.seconds[part] = self.seconds.get(part, 0.0) + now - since
        return now

    def reseed(self, before: NDArray[np.float64], now: NDArray[np.float64]) -> None:
        """Restart the track from two consecutive frames' middle lines found by the search (`before`, `now`): their
        difference is the velocity; neither frame's sweep is used (the search does not measure it)."""
        self.mids = [resample_to(before, self.length0_px), resample_to(now, self.length0_px)]
        self.velocities = [np.zeros_like(self.mids[0]), np.zeros_like(self.mids[0])]
        self.velocity_weights = [0.0, 0.0]
        self.searched_lines = [True, True]
        self.restarted = self.restart_search
        # a lost track's far-end fits were not used (beyond the gate) or were wrong: the length is measured afresh
        self.length_var = max(self.length_var, RESEED_LENGTH_SIGMA_PX**2)

    def predict(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return the next frame's middle line and its velocity (px per frame period): per point, a quadratic in
        time fitted by least squares to the last `HISTORY` frames' middle lines and to their own sweeps (each
        frame's end side minus its begin side, a velocity measured within the frame, weighted by
        `VELOCITY_WEIGHT` when the frame's predicted sweep gave its sign: a band does not say which side came
        first), evaluated one period ahead."""
        count = len(self.mids)
        taus = np.arange(-count + 1, 1, dtype=np.float64)
        rows = [[1.0, tau, tau * tau] for tau in taus]
        rows += [[0.0, w, 2.0 * w * tau] for tau, w in zip(taus, self.velocity_weights, strict=True)]
        rows.append([0.0, 0.0, CURVATURE_PRIOR])
        design = np.array(rows)
        weights = np.array(self.velocity_weights)[:, None, None]
        targets = np.concatenate(
            [np.stack(self.mids), weights * np.stack(self.velocities), np.zeros((1, *self.mids[0].shape))]
        )
        coef = np.linalg.lstsq(design, targets.reshape(len(design), -1), rcond=None)[0].reshape(3, *self.mids[0].shape)
        return coef[0] + coef[1] + coef[2], coef[1] + 2.0 * coef[2]

    def track(
        self, image: NDArray[np.float64], exposure_ns: float, evidence: NDArray[np.float64] | None = None
    ) -> dict[str, Any]:
        """Fit the band in `image` (linear light, float) and return the begin and end centrelines (``begin``,
        ``end``), the far end's offset from the carried length and its uncertainty (``cap_px``, ``cap_sigma_px``),
        the tips' standard error (``tip_sigma_px``: across the rope from the last window's fit, along it the
        carried length's), the largest standard error of a window's side (``side_sigma_px``) and whether the frame
        is trusted.

        With `evidence` (the frame minus its background, smoothed by `SEARCH_SMOOTH_PX`), the band is also sought
        without the track (`search_rope`); the frame is *locked* when the evidence along the tracked middle line is
        at least `LOCK_RATIO` of the search's best, and after two frames in a row that are not, the track is
        re-seeded from the search's lines of those two frames (``reseeded``)."""
        searched = None
        if self.restarted and evidence is not None:
            # the first frame after a re-seed: the band sought in this frame from the last frame's line, not
            # extrapolated from two searched lines (whose errors at the tip the extrapolation doubles)
            clock = time.process_time()
            searched, _ = search_rope(evidence, self.mids[-1])
            self._lap("search", clock)
            mid = resample_to(searched, self.length0_px)
            velocity = mid - self.mids[-1]
        else:
            mid, velocity = self.predict()
        self.restarted = False
        sweep = velocity * exposure_ns / self.period_ns
        begin0, end0 = mid - sweep / 2, mid + sweep / 2
        normal, tangent = _frame_normals(mid)
        t_begin = np.einsum("ij,ij->i", begin0 - mid, normal)
        t_end = np.einsum("ij,ij->i", end0 - mid, normal)
        reach = float(np.max(np.abs(t_end - t_begin))) / 2 + self.width_px + 8.0
        t = np.arange(-reach, reach + 0.01, 0.5)
        clock = time.process_time()
        profiles = _sample(image, mid[:, None, :] + t[None, :, None] * normal[:, None, :])
        clock = self._lap("sample", clock)
        last = RESAMPLE_POINTS - 1 - TIP_MARGIN_POINTS
        bounds = np.linspace(int(SKIP_FRACTION * RESAMPLE_POINTS), last, self.windows + 1).astype(int)
        tip_from = int(bounds[-1 - TIP_WINDOWS]) if self.tip_fit and self.windows > TIP_WINDOWS else RESAMPLE_POINTS
        knots, begin_shift, end_shift, sigmas, contrasts = [0.0], [0.0], [0.0], [], []
        for a, b in itertools.pairwise(bounds):
            if b > tip_from:
                break
            q, covariance = fit_window(profiles[a:b], t, t_begin[a:b], t_end[a:b], self.width_px, self.blur_px)
            errors = np.sqrt(np.diag(covariance))
            knots.append((a + b - 1) / 2)
            begin_shift.append(q[2] - q[3] / 2)
            end_shift.append(q[2] + q[3] / 2)
            sigmas.append(float(max(errors[2], errors[3])))
            contrasts.append(float(q[1]))
        clock = self._lap("windows", clock)
        if tip_from < RESAMPLE_POINTS:
            # the outer part and the far end in one fit: the tip is where the quadratic offset puts it at the
            # carried length, and the far end's step is fitted with the sides that meet it
            q, covariance, shifts = fit_tip(
                image, mid, normal, t_begin, t_end, tip_from, self.length_px, self.width_px, self.blur_px
            )
            errors = np.sqrt(np.diag(covariance))
            index = np.arange(tip_from, RESAMPLE_POINTS)
            knots += [float(i) for i in index]
            begin_shift += list(shifts - q[3] / 2)
            end_shift += list(shifts + q[3] / 2)
            sigmas.append(float(max(errors[2], errors[3])))
            contrasts.append(float(q[1]))
            across_sigma_px = max(
                float(math.sqrt(max(g @ covariance @ g, 0.0)))
                for g in (np.array([0, 0, 1.0, -0.5, 0, 0, 0]), np.array([0, 0, 1.0, 0.5, 0, 0, 0]))
            )
            tip_shift, cap_px, cap_sigma_px = float(q[2]), float(q[6]), float(errors[6])
            index = np.arange(RESAMPLE_POINTS)
            begin = begin0 + np.interp(index, knots, begin_shift)[:, None] * normal
            end = end0 + np.interp(index, knots, end_shift)[:, None] * normal
        else:
            # the last window's slope carries its offset to the tip
            lever = ((RESAMPLE_POINTS - 1) - (a + b - 1) / 2) / max(b - a - 1, 1)
            tip_shift = q[2] + q[4] * lever
            # the tips' standard errors across the rope: the last window's offset, slope and sweep, with their
            # covariance
            across_sigma_px = max(
                float(math.sqrt(max(g @ covariance @ g, 0.0)))
                for g in (np.array([0.0, 0.0, 1.0, -0.5, lever]), np.array([0.0, 0.0, 1.0, 0.5, lever]))
            )
            knots.append(RESAMPLE_POINTS - 1.0)
            begin_shift.append(tip_shift - q[3] / 2)
            end_shift.append(tip_shift + q[3] / 2)
            index = np.arange(RESAMPLE_POINTS)
            begin = begin0 + np.interp(index, knots, begin_shift)[:, None] * normal
            end = end0 + np.interp(index, knots, end_shift)[:, None] * normal
            carried = resample_to(begin, self.length_px)[-1], resample_to(end, self.length_px)[-1]
            cap_px, cap_sigma_px = fit_far_end(image, carried[0], carried[1], tangent[-1], self.blur_px)
        clock = self._lap("tip" if tip_from < RESAMPLE_POINTS else "far_end", clock)
        # the length is nearly constant (the rope's projection changes it slowly): a scalar Kalman filter, not a sum
        self.length_var += LENGTH_DRIFT_PX**2
        noise_var = cap_sigma_px**2 + CAP_BIAS_PX**2
        in_gate = math.isfinite(cap_sigma_px) and cap_px**2 < CAP_INNOVATION_GATE**2 * (self.length_var + noise_var)
        if in_gate:
            gain = self.length_var / (self.length_var + noise_var)
            self.length_px += gain * cap_px
            self.length_var *= 1.0 - gain
        begin, end = resample_to(begin, self.length_px), resample_to(end, self.length_px)
        sweep_px = float(math.hypot(*(end[-1] - begin[-1])))
        tip_sigma_px = math.sqrt(across_sigma_px**2 + self.length_var)
        contrast_ratio = min(contrasts) / (float(np.median(contrasts)) + 1e-9)
        cap_agrees = cap_px**2 < CAP_INNOVATION_GATE**2 * (self.length_var + noise_var)
        # a re-seeded track is not trusted while the searched lines are in the prediction's history: the search
        # bends a known shape at a few joints, and its centreline's error shows in no fit's uncertainty (seed 0,
        # the first frames after a re-seed: tips 0.5-0.9 px, centrelines 1.01-1.06 px)
        fitted_history = not any(self.searched_lines)
        trusted = bool(
            cap_agrees and tip_sigma_px < TIP_SIGMA_GATE_PX and contrast_ratio > CONTRAST_GATE and fitted_history
        )
        mid_line = resample_to(0.5 * (begin + end), self.length0_px)
        locked, reseeded, found_score, tracked_score = True, False, math.nan, math.nan
        if evidence is not None:
            found = searched if searched is not None else search_rope(evidence, self.reference)[0]
            found_score = line_score(evidence, found, LOCK_FROM)
            tracked_score = line_score(evidence, mid_line, LOCK_FROM)
            # a far end at the tip fit's reach: the line ran along the band past its end (a lost tip)
            locked = tracked_score >= LOCK_RATIO * found_score and abs(cap_px) < CAP_REACH_PX - 0.5
            clock = self._lap("search", clock)
            trusted = trusted and locked
            # a far end the length's gate refuses is a doubt like a lost lock: a runaway line keeps its score
            # ratio near 1 (the search turns its own line) while its far end runs out along the band
            doubt = not locked or not in_gate
            self.unlocked = self.unlocked + 1 if doubt else 0
            if self.unlocked >= 2 and self.found is not None:
                reseeded = True
                self.unlocked = 0
            before, self.found = self.found, found
        if locked and in_gate:
            self.reference = mid_line
        result = {
            "begin": begin, "end": end, "cap_px": cap_px, "cap_sigma_px": cap_sigma_px,
            "side_sigma_px": max(sigmas), "trusted": trusted, "across_sigma_px": across_sigma_px,
            "length_sigma_px": math.sqrt(self.length_var), "tip_sigma_px": tip_sigma_px,
            "contrast_ratio": contrast_ratio, "tip_shift_px": float(tip_shift), "sweep_fit_px": sweep_px,
            "locked": locked, "reseeded": reseeded, "score_ratio": tracked_score / found_score, "in_gate": in_gate,
        }  # fmt: skip
        if reseeded:
            self.reseed(before, self.found)
            return result
        self.mids.append(mid_line)
        self.velocities.append(
            (resample_to(end, self.length0_px) - resample_to(begin, self.length0_px)) * self.period_ns / exposure_ns
        )
        signed = float(math.hypot(*sweep[-1])) >= SIGN_SWEEP_PX
        self.velocity_weights.append(VELOCITY_WEIGHT if signed else 0.0)
        self.searched_lines.append(False)
        del self.mids[:-HISTORY], self.velocities[:-HISTORY], self.velocity_weights[:-HISTORY]
        del self.searched_lines[:-HISTORY]
        return result


def track_set(
    path: Path, frames: int = 30, blur_px: float = 0.6, windows: int = 10, seed: str = "truth", search: bool = True,
    tip_fit: bool = True,
) -> list[dict[str, Any]]:  # fmt: skip
    """Track the band over the first `frames` frames of the simulator frame set at `path` from frame 0 (`seed`:
    ``"truth"`` or ``"pipeline"``, see the module's docstring) and return one row per frame from frame 1 on (the
    errors against the truth, the fit's indicators, ``trusted``). With `search`, every frame is also searched
    without the track (against the median of `BACKGROUND_FRAMES` frames of the set) to check the lock and to
    re-seed a lost track.

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
    tracker = BandTracker(line, width_px, blur_px, 1e9 / float(frameset.fps), windows, tip_fit)
    background = median_background(frameset, gamma, BACKGROUND_FRAMES) if search else None
    rows = []
    for index in range(1, count):
        from scipy.ndimage import gaussian_filter

        image = 255.0 * (frameset.read(index).astype(np.float64) / 255.0) ** gamma
        clock = time.process_time()
        evidence = None if background is None else gaussian_filter(image - background, SEARCH_SMOOTH_PX)
        evidence_ms = 1000.0 * (time.process_time() - clock)
        spent = dict(tracker.seconds)
        fitted = tracker.track(image, float(frameset.records[index].exposure_us) * 1000.0, evidence)
        cpu_ms = {part: 1000.0 * (seconds - spent.get(part, 0.0)) for part, seconds in tracker.seconds.items()}
        cpu_ms["evidence"] = evidence_ms
        true_b, true_e = truth["begin_px"][index], truth["end_px"][index]
        tip = max(math.hypot(*(fitted["begin"][-1] - true_b[-1])), math.hypot(*(fitted["end"][-1] - true_e[-1])))
        curve = max(
            float(point_to_polyline(resample(true_b, 100), fitted["begin"]).mean()),
            float(point_to_polyline(resample(true_e, 100), fitted["end"]).mean()),
        )
        rows.append({
            "frame": index, "sweep_px": float(math.hypot(*(truth["tip_end_px"][index] - truth["tip_begin_px"][index]))),
            "tip_px": tip, "curve_px": curve, "cap_px": fitted["cap_px"], "cap_sigma_px": fitted["cap_sigma_px"],
            "side_sigma_px": fitted["side_sigma_px"], "tip_sigma_px": fitted["tip_sigma_px"],
            "across_sigma_px": fitted["across_sigma_px"], "length_sigma_px": fitted["length_sigma_px"],
            "contrast_ratio": fitted["contrast_ratio"], "score_ratio": fitted["score_ratio"],
            "locked": bool(fitted["locked"]), "reseeded": bool(fitted["reseeded"]), "trusted": bool(fitted["trusted"]),
            "in_gate": bool(fitted["in_gate"]),
            "cpu_ms": cpu_ms,
            "silent": bool(fitted["trusted"] and (tip > SILENT_TIP_PX or curve > SILENT_CURVE_PX)),
        })  # fmt: skip
    return rows


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Return the tracked frames' figures: tip mean / p95 and centreline mean over every frame and over the trusted
    ones, the trusted and silent counts, how often the tip lies within three of its own standard errors (every frame
    and the trusted ones), the re-seeds, the frames whose centreline is over `SILENT_CURVE_PX` off (the track lost)
    and the first of them."""
    tips = np.array([r["tip_px"] for r in rows])
    curves = np.array([r["curve_px"] for r in rows])
    trusted = np.array([r["trusted"] for r in rows])
    bounded = tips <= 3.0 * np.array([r["tip_sigma_px"] for r in rows])
    lost = [r["frame"] for r in rows if r["curve_px"] > SILENT_CURVE_PX]
    return {
        "frames": len(rows), "tip_mean_px": float(tips.mean()), "tip_p95_px": float(np.percentile(tips, 95)),
        "curve_mean_px": float(curves.mean()), "trusted": int(trusted.sum()),
        "trusted_tip_mean_px": float(tips[trusted].mean()) if trusted.any() else math.nan,
        "trusted_tip_p95_px": float(np.percentile(tips[trusted], 95)) if trusted.any() else math.nan,
        "trusted_tip_max_px": float(tips[trusted].max()) if trusted.any() else math.nan,
        "trusted_curve_mean_px": float(curves[trusted].mean()) if trusted.any() else math.nan,
        "trusted_curve_max_px": float(curves[trusted].max()) if trusted.any() else math.nan,
        "silent": int(sum(r["silent"] for r in rows)), "lost_from": lost[0] if lost else None,
        "lost_frames": len(lost), "reseeds": int(sum(r.get("reseeded", False) for r in rows)),
        "within_3_sigma": float(bounded.mean()),
        "trusted_within_3_sigma": float(bounded[trusted].mean()) if trusted.any() else math.nan,
    }  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Track one frame set's band from its seed (frame 0's truth or the pipeline's frame 0); print the per-frame
    table and the summary (or JSON)."""
    if args.windows > MAX_WINDOWS:
        raise UsageError(f"--windows {args.windows}: at most {MAX_WINDOWS} (two resampled points per window)")
    if not (args.set / "truth.npz").is_file():
        raise UsageError(f"{args.set}: not a simulator frame set (no truth.npz; make one with `ropecam simulate`)")
    rows = track_set(args.set, args.frames, args.blur_px, args.windows, args.seed, args.search, args.tip_fit)
    summary = summarise(rows)
    if args.json:
        print(json.dumps({"scene": args.set.name, "seed": args.seed, "frames": rows, "summary": summary}, indent=1))
        return 0
    seeded = "frame 0's truth" if args.seed == "truth" else "the pipeline's frame 0, cut where it turns back"
    print(f"{args.set.name} (simulated; seeded with {seeded}): the band tracked without edges")
    print("| frame | sweep (px) | tip (px) | its sigma | centreline (px) | far end vs length (px) | its sigma | locked "
          "| trusted |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        trusted = ("yes" if r["trusted"] else "no") + (" (silent)" if r["silent"] else "")
        locked = ("yes" if r["locked"] else "no") + (" (re-seeded)" if r["reseeded"] else "")
        print(f"| {r['frame']} | {r['sweep_px']:.1f} | {r['tip_px']:.2f} | {r['tip_sigma_px']:.2f} | "
              f"{r['curve_px']:.2f} | {r['cap_px']:+.2f} | {r['cap_sigma_px']:.2f} | {locked} | "
              f"{trusted} |")  # fmt: skip
    s = summary
    print(f"\nall {s['frames']} frames: tip {s['tip_mean_px']:.2f} / p95 {s['tip_p95_px']:.2f} px, centreline "
          f"{s['curve_mean_px']:.2f} px; trusted {s['trusted']} (tip mean {s['trusted_tip_mean_px']:.2f}, p95 "
          f"{s['trusted_tip_p95_px']:.2f}, max {s['trusted_tip_max_px']:.2f} px, centreline mean "
          f"{s['trusted_curve_mean_px']:.2f}, max {s['trusted_curve_max_px']:.2f} px), silent {s['silent']}; tip "
          f"within 3 of its standard errors on {100 * s['within_3_sigma']:.0f} % of the frames "
          f"({100 * s['trusted_within_3_sigma']:.0f} % of the trusted); {s['reseeds']} re-seeds; centreline over "
          f"{SILENT_CURVE_PX:g} px on {s['lost_frames']} frames, the first {s['lost_from']}")  # fmt: skip
    return 0
