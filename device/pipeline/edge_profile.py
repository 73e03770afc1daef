"""The camera's blur read off the image: the rope's own cross-section near the fixed end on the first frames.

The band edge model (`ropecam.device.pipeline.edge_model`) converts measured edge positions into the rope's
positions for a camera blur (a Gaussian `lens_blur_px`) and sharpening (an unsharp mask). A wrong blur biases every
shape where the rope moves less than its width plus the blur (a 2 px lens blur assumed 0.5 put the simulated
centreline 0.8 px off), and sharpening steepens the edges as a still rope's are, so a moving rope read as still.
Both are therefore measured where the rope hardly moves: across the rope just beyond the fixed end, on frames
whose sweep there is below a pixel. The grey levels of the raw frame's pixels around a stretch of the rope, against
their distance from its axis (the midline of the band's two edges, a quadratic over the stretch), are fitted with a
level (a line across) plus the rope's contrast times a bar of width w blurred by a Gaussian of sigma s and
sharpened by an unsharp mask of gain a and sigma u:
``b0 + b1 x + C ((1 + a) bar(x; s) - a bar(x; sqrt(s^2 + u^2)))``,
``bar(x; s) = Phi((x - x0 + w/2) / s) - Phi((x - x0 - w/2) / s)``. The pixel's own area adds 1/12 px^2 to s^2 and
the sweep d there d^2/12 (the ramp of a bar moving by d is a uniform of width d); both are taken off, the rest is
the lens blur. Pooling the pixels of a stretch over all their positions on the pixel grid samples the profile
finely (the slanted-edge method of MTF measurement). A camera's gamma makes the profile other than this; the fit
then gives the blur and sharpening nearest to it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline.edge_model import normal_cdf

__all__ = [
    "BLUR_READINGS", "EdgeBlur", "LensBlurEstimate", "ProfileFit", "fit_bar_profile", "read_cross_section"
]  # fmt: skip

BLUR_READINGS = 5
"""Frames whose readings (median) give the lens blur."""
MAX_LOCAL_SWEEP_PX = 1.0
"""Largest sweep of the rope over the stretch read (from the frame's tip sweep, in proportion to the distance from
the fixed end) for a reading to count: the correction d^2/12 is then below 0.09 px^2."""
MIN_SHARPEN_VARIANCE_PX2 = 0.3
"""Sharpening whose share of the edge's variance (gain x sigma^2) is below this is taken as none: the fit finds up
to 0.12 px^2 on a plain blurred bar (the pixel's area is a box, not a Gaussian; simulated rig scenes); a camera's
sharpening at gain 0.5 and sigma 1 px reads 0.5."""
_PIXEL_VARIANCE = 1.0 / 12.0
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


@dataclass(frozen=True, slots=True)
class ProfileFit:
    """A blurred, sharpened bar fitted to a rope's cross-section (`fit_bar_profile`).

    Attributes
    ----------
    width_px
        The bar's width w.
    sigma_px
        The Gaussian's sigma s (all blur the profile shows: lens, pixel area, motion).
    sharpen_gain, sharpen_sigma_px
        The unsharp mask's gain a and sigma u (a = 0: none; u is then meaningless).
    contrast
        The bar's level above the background (grey levels; negative for a dark rope).
    centre_px
        The bar's centre x0 relative to the given axis.
    rms
        The residual's root mean square (grey levels).
    count
        Pixels fitted.
    """

    width_px: float
    sigma_px: float
    sharpen_gain: float
    sharpen_sigma_px: float
    contrast: float
    centre_px: float
    rms: float
    count: int


def _bars(
    x: NDArray[np.float64], centre: float, width: float, sigmas: tuple[float, ...]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``Phi((x - x0 + w/2) / s) - Phi((x - x0 - w/2) / s)`` and its derivatives in x0, w and s, one row per
    sigma s of `sigmas`, each (len(sigmas), k).

    Every bar and edge goes through one call of each NumPy function (on arrays of a few hundred pixels their calls
    cost more than their arithmetic); each element's operations are those of one bar at a time, to the bit."""
    inv = np.array([1.0 / s for s in sigmas])[:, None]
    offset = x - centre
    upper = (offset + 0.5 * width) * inv
    lower = (offset - 0.5 * width) * inv
    both = np.concatenate([upper, lower])
    count = len(sigmas)
    cdf = normal_cdf(both)
    density = np.exp(-0.5 * both * both) * _INV_SQRT_2PI
    density_u, density_l = density[:count], density[count:]
    d_centre = inv * (density_l - density_u)
    d_width = (inv * 0.5) * (density_u + density_l)
    d_sigma = inv * (lower * density_l - upper * density_u)
    return cdf[:count] - cdf[count:], d_centre, d_width, d_sigma


def _model(
    x: NDArray[np.float64], params: NDArray[np.float64], plain: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The profile ``b0 + b1 x + C ((1 + a) bar(x; x0, w, s) - a bar(x; x0, w, sqrt(s^2 + u^2)))`` at `x` for
    `params` (b0, b1, C, x0, w, s, a, u), and its Jacobian (k, 8); `plain`: a = 0 and neither a nor u is fitted
    (their columns are 0)."""
    level, slope, contrast, centre, width, sigma, gain, radius = params
    wide = math.sqrt(sigma * sigma + radius * radius)
    bars, dcs, dws, dss = _bars(x, centre, width, (sigma,) if plain else (sigma, wide))
    bar, dc, dw, ds = bars[0], dcs[0], dws[0], dss[0]
    jac = np.empty((x.size, 8))
    jac[:, 0] = 1.0
    jac[:, 1] = x
    if plain:
        # Without the second bar: with a = 0 its terms are exactly 0 ((1 + 0) b - 0 b2 is b to the bit), and it
        # was half the time of the first frames' plain fits.
        jac[:, 2] = bar
        jac[:, 3] = contrast * dc
        jac[:, 4] = contrast * dw
        jac[:, 5] = contrast * ds
        jac[:, 6:] = 0.0
        return level + slope * x + contrast * jac[:, 2], jac
    bar2, dc2, dw2, ds2 = bars[1], dcs[1], dws[1], dss[1]
    jac[:, 2] = (1.0 + gain) * bar - gain * bar2
    jac[:, 3] = contrast * ((1.0 + gain) * dc - gain * dc2)
    jac[:, 4] = contrast * ((1.0 + gain) * dw - gain * dw2)
    jac[:, 5] = contrast * ((1.0 + gain) * ds - gain * ds2 * (sigma / wide))
    jac[:, 6] = contrast * (bar - bar2)
    jac[:, 7] = -contrast * gain * ds2 * (radius / wide)
    return level + slope * x + contrast * jac[:, 2], jac


_LOWER = np.array([-np.inf, -np.inf, -np.inf, -np.inf, 0.05, 0.05, 0.0, 0.5])
_UPPER = np.array([np.inf, np.inf, np.inf, np.inf, 30.0, 30.0, 5.0, 4.0])
_LOWER_PLAIN = np.array([-np.inf, -np.inf, -np.inf, -np.inf, 0.05, 0.05, 0.0, 1.0])
_UPPER_PLAIN = np.array([np.inf, np.inf, np.inf, np.inf, 30.0, 30.0, 0.0, 1.0])


def fit_bar_profile(
    x_px: NDArray[np.floating],
    values: NDArray[np.floating],
    width_guess_px: float,
    sharpened: bool = True,
    start: ProfileFit | None = None,
    iterations: int = 25,
) -> ProfileFit | None:
    """Fit a blurred, sharpened bar to grey levels `values` at distances `x_px` from a rope's axis:
    ``b0 + b1 x + C ((1 + a) bar(x; s) - a bar(x; sqrt(s^2 + u^2)))`` with
    ``bar(x; s) = Phi((x - x0 + w/2) / s) - Phi((x - x0 - w/2) / s)`` (a camera's unsharp mask of gain a and
    sigma u after the blur).

    Levenberg-Marquardt with the analytic Jacobian, within bounds (w and s 0.05-30 px, a 0-5, u 0.5-4 px: a
    narrower mask only reshapes the pixel's area), from (x0, w, s, a, u) = (0, `width_guess_px`, 0.8, 0.1, 1)
    and the level, slope and contrast solved linearly for them.

    Parameters
    ----------
    x_px, values
        (k,) signed distances (px) and the pixels' grey levels.
    width_guess_px
        Starting width (the band's edge spacing).
    sharpened
        Fit the unsharp mask too (False: a = 0).
    start
        A fit to start from (its x0, w, s; None: 0, `width_guess_px`, 0.8).
    iterations
        Most Levenberg-Marquardt steps.

    Returns
    -------
    ProfileFit or None
        None when there are too few pixels or the fit ends on a bound of w or s.
    """
    x = np.asarray(x_px, np.float64)
    v = np.asarray(values, np.float64)
    if x.size < 16:
        return None
    params = np.array([0.0, 0.0, 1.0, 0.0, max(float(width_guess_px), 0.5), 0.8, 0.1 if sharpened else 0.0, 1.0])
    if start is not None:
        params[3:6] = (start.centre_px, start.width_px, start.sigma_px)
    lower, upper = (_LOWER, _UPPER) if sharpened else (_LOWER_PLAIN, _UPPER_PLAIN)
    free = 8 if sharpened else 6  # the plain bar's steps leave a and u out of the normal equations
    plain = not sharpened
    _, jac = _model(x, params, plain)
    coef, *_ = np.linalg.lstsq(jac[:, :3], v, rcond=None)
    params[:3] = coef
    model, jac = _model(x, params, plain)
    residual = v - model
    cost = float(residual @ residual)
    damping = 1e-3
    for _ in range(iterations):
        normal = jac[:, :free].T @ jac[:, :free]
        gradient = jac[:, :free].T @ residual
        diagonal = np.diag(np.diag(normal) + 1e-9 * float(np.max(np.diag(normal))))
        improved = converged = False
        while damping < 1e10:
            delta = np.zeros(8)
            delta[:free] = np.linalg.solve(normal + damping * diagonal, gradient)
            trial = np.clip(params + delta, lower, upper)
            trial_model, trial_jac = _model(x, trial, plain)
            trial_residual = v - trial_model
            trial_cost = float(trial_residual @ trial_residual)
            if trial_cost <= cost:
                converged = cost - trial_cost <= 1e-7 * cost or float(np.max(np.abs(trial - params)[3:])) < 1e-4
                params, residual, jac, cost = trial, trial_residual, trial_jac, trial_cost
                damping = max(damping / 4.0, 1e-9)
                improved = True
                break
            damping *= 4.0
        if not improved or converged:
            break
    contrast, centre, width, sigma, gain, radius = (float(p) for p in params[2:])
    if not (0.05 < width < 30.0 and 0.05 < sigma < 30.0 and math.isfinite(cost)):
        return None
    return ProfileFit(width, sigma, gain, radius, contrast, centre, math.sqrt(cost / x.size), int(x.size))


def read_cross_section(
    frame: NDArray[np.uint8],
    points: NDArray[np.float32],
    n: int,
    fixed_rc: tuple[float, float],
    edge_width_px: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float] | None:
    """Return the pixels across the rope's stretch just beyond the fixed end: (distances from the axis in px,
    grey levels, the stretch's middle distance from the fixed end over the contour's farthest), or None.

    The stretch is the contour between 2 m + 4 and 2 m + 4 + max(12, min(40, a tenth of the contour's reach)) px
    beyond its point nearest the fixed end (past the cap's rounded corners, or past a clamp the contour starts
    at; m = `edge_width_px`); its axis is a quadratic fitted to both sides' edge points (a still rope's edges lie
    symmetric about it), in the frame of their principal direction. Pixels within max(m/2 + 6, 2 m + 3) px of
    the axis and within the stretch's length are returned. None when the stretch does not have both sides.
    """
    pts = np.asarray(points[:n], np.float64)
    if pts.shape[0] < 16:
        return None
    dist = np.hypot(pts[:, 0] - fixed_rc[0], pts[:, 1] - fixed_rc[1])
    reach = float(dist.max())
    start = float(dist.min()) + 2.0 * edge_width_px + 4.0
    length = max(12.0, min(40.0, 0.1 * reach))
    near = pts[(dist > start) & (dist < start + length)]
    if near.shape[0] < 12:
        return None
    centre = near.mean(axis=0)
    rel = near - centre
    _, vectors = np.linalg.eigh(rel.T @ rel)
    along_dir, across_dir = vectors[:, 1], vectors[:, 0]
    t, y = rel @ along_dir, rel @ across_dir
    axis = np.polyfit(t, y, 2)
    side = y - np.polyval(axis, t)
    two_sides = min(np.count_nonzero(side > 0), np.count_nonzero(side < 0)) >= 0.3 * side.size
    if not (two_sides and float(np.median(np.abs(side))) > 0.25 * edge_width_px):
        return None  # one edge only: not a band of two edges here
    half = max(0.5 * edge_width_px + 6.0, 2.0 * edge_width_px + 3.0)  # the tails of a blur that widens the spacing
    low = np.floor(near.min(axis=0) - half).astype(int)
    high = np.ceil(near.max(axis=0) + half).astype(int)
    height, width = frame.shape
    r0, c0 = max(low[0], 0), max(low[1], 0)
    r1, c1 = min(high[0], height - 1), min(high[1], width - 1)
    if r1 <= r0 or c1 <= c0:
        return None
    rows, cols = np.mgrid[r0 : r1 + 1, c0 : c1 + 1]
    rel_px = np.stack([rows.ravel() - centre[0], cols.ravel() - centre[1]], axis=1)
    t_px, y_px = rel_px @ along_dir, rel_px @ across_dir
    x_px = y_px - np.polyval(axis, t_px)
    keep = (t_px >= t.min()) & (t_px <= t.max()) & (np.abs(x_px) <= half)
    values = frame[r0 : r1 + 1, c0 : c1 + 1].ravel()[keep].astype(np.float64)
    return x_px[keep], values, (start + 0.5 * length) / max(reach, 1e-6)


class EdgeBlur(NamedTuple):
    """What the edge model needs of the camera: its lens blur and sharpening (`BandEdgeModel`)."""

    lens_blur_px: float
    """Gaussian sigma (px) of the lens, the pixel's area apart."""
    sharpen_gain: float
    """Gain of the camera's unsharp mask (0: none)."""
    sharpen_sigma_px: float
    """Its Gaussian's sigma (px)."""


class LensBlurEstimate:
    """The camera's blur and sharpening (`EdgeBlur`) from the first frames' cross-sections.

    Parameters
    ----------
    readings
        Frames whose readings' median is the estimate.
    decoded
        Whether the frames were mapped back through the camera's gamma curve before they are read (`gamma` set):
        a camera sharpens the encoded image, so its halos in the decoded frame are no unsharp mask (a dark rope's
        bright halo grows, its dark one shrinks). The edge model cannot describe them, and the sharpened fit
        then takes a gain that makes the model expect steeper still edges than the frame shows: every still rope
        read as sweeping, and its two shapes lay on the band's edges (simulated `lab-dark` through the paper's
        camera, 1 ms, tuning seed: 2.12 at sigma 0.76 read, the model's still edge 2.56 x the contrast against
        1.69 seen; 65 % of the frames OK with a centreline 1.2 px off). A decoded frame's reading has no
        sharpening. Its blur is, for a bright rope, the sharpened fit's (its halos apart), and for a dark rope the
        plain bar's: decoding stretches the bright side, so a dark rope's bright halo, on the plate, steepens its
        edges beyond the lens's blur, and the model with the lens's blur expects gentler still edges than the frame
        shows: it reads a sweep of a few pixels as less and pulls both shapes towards the band's middle
        (simulated `lab-dark`, tuning seed, 60 frames: the sharpened fit's 0.50 px against the plain bar's
        0.30; 0.05-0.3 px inwards on every frame, centreline 0.17 -> 0.15 px, seed 3 0.26 -> 0.17 px). A bright
        rope's plain bar takes the halo on the rope for a narrower, blurrier bar (`lab late swing`: 0.76 px and a
        1.1 px rope against the sharpened fit's 0.41 px and 2.1 px).
    """

    def __init__(self, readings: int = BLUR_READINGS, decoded: bool = False) -> None:
        self.readings = int(readings)
        self.decoded = bool(decoded)
        self.read_values: list[EdgeBlur] = []
        """Each frame's reading."""

    @property
    def done(self) -> bool:
        """Whether enough frames were read."""
        return len(self.read_values) >= self.readings

    @property
    def value(self) -> EdgeBlur | None:
        """The median of the readings (None before the first); sharpening below `MIN_SHARPEN_VARIANCE_PX2` taken
        as none."""
        if not self.read_values:
            return None
        lens, gain, radius = (float(v) for v in np.median(np.asarray(self.read_values), axis=0))
        if gain * radius * radius < MIN_SHARPEN_VARIANCE_PX2:
            return EdgeBlur(lens, 0.0, 1.0)
        return EdgeBlur(lens, gain, radius)

    def read(
        self,
        frame: NDArray[np.uint8],
        points: NDArray[np.float32],
        n: int,
        fixed_rc: tuple[float, float],
        edge_width_px: float,
        tip_sweep_px: float,
        explains: Callable[[EdgeBlur, float, float], bool] | None = None,
    ) -> EdgeBlur | None:
        """Read one frame (its contour, fixed end, the rope's edge spacing and the frame's tip sweep); return the
        frame's reading, or None when the frame does not count (the rope moves more than `MAX_LOCAL_SWEEP_PX`
        over the stretch, no stretch with two sides, no plausible fit, or `explains` (the reading, the bar width
        the fit read, `edge_width_px`) says the reading's edge model does not explain the edge spacing the contour
        shows by that bar: `LensBlur` checks it)."""
        if self.done or not (math.isfinite(edge_width_px) and edge_width_px > 0.0 and math.isfinite(tip_sweep_px)):
            return None
        section = read_cross_section(frame, points, n, fixed_rc, edge_width_px)
        if section is None:
            return None
        x, values, where = section
        sweep = tip_sweep_px * where
        if sweep > MAX_LOCAL_SWEEP_PX:
            return None
        fit = fit_bar_profile(x, values, edge_width_px, sharpened=False)
        if fit is None or abs(fit.centre_px) > 0.5 * edge_width_px or abs(fit.contrast) < 4.0 * fit.rms:
            return None
        # The sharpened bar has two more parameters, which a plain blurred bar's noise and pixel shape also use a
        # little of (trading blur for sharpening): it is taken only when it explains more, by a sharpening that
        # changes the edge's variance clearly. A decoded dark rope keeps the plain bar (`decoded`).
        sharp = None if self.decoded and fit.contrast < 0.0 else fit_bar_profile(x, values, edge_width_px, start=fit)
        if (
            sharp is not None
            and sharp.sharpen_gain * sharp.sharpen_sigma_px**2 >= MIN_SHARPEN_VARIANCE_PX2
            and sharp.rms < fit.rms
        ):
            fit = sharp
        variance = fit.sigma_px**2 - _PIXEL_VARIANCE - sweep**2 / 12.0
        if self.decoded:
            reading = EdgeBlur(math.sqrt(max(variance, 0.0)), 0.0, 1.0)
        else:
            reading = EdgeBlur(math.sqrt(max(variance, 0.0)), fit.sharpen_gain, fit.sharpen_sigma_px)
        if explains is not None and not explains(reading, fit.width_px, edge_width_px):
            return None
        self.read_values.append(reading)
        return reading
