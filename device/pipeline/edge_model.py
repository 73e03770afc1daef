"""Where Canny puts the edge of a motion-blurred rope: a 1-D model of the band's cross-section.

A rope of width w that moves sideways by d during the exposure covers each point for a time: across the band the
coverage is a trapezoid with ramps of width min(w, d) and a plateau of min(1, w / d). The camera blurs it (lens,
pixel area), the pipeline smooths it and takes the Sobel gradient; the edge is the gradient's maximum, refined by a
parabola. This module computes, once per rope width, what that chain of operations does to the edge position and
to the gradient's height, so that the splitter can invert it:

* the *inward offset* from the edge to the rope's axis at the start of the exposure, as a function of d (it is the
  half edge spacing m/2 at d = 0, not the half width: blur pushes the edges of a thin rope apart; and it reaches 0
  only when the ramp is wider than the blur, not at d = w);
* the *rope width* w whose edges lie m apart when it does not move (the width read from the image is m);
* the *gradient height* per unit of the rope's full contrast as a function of d (the slope of the ramp is
  contrast / d), to read the local sweep from the image where the band is narrower than the rope plus its blur.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K

__all__ = ["BandEdgeModel", "EdgeTables", "normal_cdf", "shared_model"]

_PHASES = (0.0, 0.25, 0.5, 0.75)

_SHARED: dict[tuple[tuple[float, ...], float, float, float], BandEdgeModel] = {}
"""One model per (smoothing weights, lens blur, sharpening) in the process: its tables depend on nothing else, so a new
pipeline (settings changed, the daemon's restart after a camera loss, offline runs) reuses the ones built."""


def shared_model(
    smooth_weights: NDArray[np.floating], lens_blur_px: float, sharpen_gain: float = 0.0, sharpen_sigma_px: float = 1.0
) -> BandEdgeModel:
    """Return the process-wide `BandEdgeModel` for this smoothing, lens blur and sharpening (built on first use).

    Its tables (~10-20 ms each, one per 0.1 px of edge spacing) are then built once per process, not once per
    pipeline. Safe to call from several threads: at worst a table is built twice, the results are equal.
    """
    weights = np.asarray(smooth_weights, np.float64)
    sigma = float(sharpen_sigma_px) if sharpen_gain > 0.0 else 1.0
    key = (tuple(float(w) for w in weights), float(lens_blur_px), float(sharpen_gain), sigma)
    model = _SHARED.get(key)
    if model is None:
        model = _SHARED.setdefault(key, BandEdgeModel(weights, lens_blur_px, sharpen_gain, sigma))
    return model


@dataclass(frozen=True, slots=True)
class EdgeTables:
    """The model's tables for one rope.

    Attributes
    ----------
    width_px
        The rope's width (unbiased).
    edge_width_px
        The edge spacing of the still rope (what the image shows).
    sweep_step_px
        Spacing of the sweep grid (the tables start at d = 0).
    offset_px
        (k,) float32: inward offset from the edge to the rope's axis, for d = i * sweep_step_px.
    sweeps_px, peak_ratio
        The gradient height per unit contrast against d, sorted by increasing ratio (for `np.interp`).
    slant_px
        How far the half-level crossing along a shape's axis lies beyond its flat end per unit slope of the end's
        track (along per across; `slant_gain`).
    """

    width_px: float
    edge_width_px: float
    sweep_step_px: float
    offset_px: NDArray[np.float32]
    sweeps_px: NDArray[np.float64]
    peak_ratio: NDArray[np.float64]
    slant_px: float


class BandEdgeModel:
    """Tables of the edge of a blurred band for the pipeline's smoothing and an assumed lens blur.

    Parameters
    ----------
    smooth_weights
        The pipeline's Gaussian smoothing kernel (1-D).
    lens_blur_px
        Standard deviation of the camera's blur (lens, focus) in pixels; the pixel's own area is modelled apart.
    sharpen_gain, sharpen_sigma_px
        The camera's sharpening after the pixels: ``p + gain (p - G * p)``, G a Gaussian of `sharpen_sigma_px`
        across the edge (an unsharp mask; 0: none).
    """

    def __init__(
        self,
        smooth_weights: NDArray[np.floating],
        lens_blur_px: float,
        sharpen_gain: float = 0.0,
        sharpen_sigma_px: float = 1.0,
    ) -> None:
        self.weights = np.asarray(smooth_weights, np.float64)
        self.lens_blur_px = float(lens_blur_px)
        self.sharpen_gain = float(sharpen_gain)
        self.sharpen_sigma_px = float(sharpen_sigma_px)
        self._cache: dict[int, EdgeTables] = {}
        self._slants: dict[int, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
        self._spacings: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    def _edges(
        self, widths: float | NDArray[np.float64], sweeps: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Left edge position (relative to the start's outer edge, px) and peak gradient height (per unit of
        contrast), each the mean over four pixel phases, of bands (width, d) for every pair of `widths` (or one
        width) and `sweeps`.

        The coverage trapezoid is piecewise linear, so its convolution with the lens Gaussian and its average over
        each pixel are closed forms (second antiderivative of the Gaussian); then the pipeline's smoothing, the
        central difference (Sobel across a straight edge) and Devernay's parabola, all vectorised.
        """
        d = np.maximum(np.atleast_1d(np.asarray(sweeps, np.float64)), 1e-3)[:, None, None]  # (D, 1, 1)
        width = np.broadcast_to(np.asarray(widths, np.float64), d.shape[:1])[:, None, None]
        sigma = max(self.lens_blur_px, 1e-3)
        half = len(self.weights) // 2
        pad = 6.0 + 4.0 * sigma + half + (3.0 * self.sharpen_sigma_px if self.sharpen_gain > 0.0 else 0.0)
        phases = np.asarray(_PHASES)[None, :, None]
        centres = np.arange(-math.ceil(pad), math.ceil(float((width + d).max()) + pad) + 1)[None, None, :] + phases
        ramp = np.minimum(width, d)
        slope = np.minimum(1.0, width / d) / ramp
        knots = ((0.0, slope), (ramp, -slope), (width + d - ramp, -slope), (width + d, slope))
        pix = np.zeros(np.broadcast_shapes(d.shape, centres.shape))
        # Pixel borders: a pixel's left border is its left neighbour's right one (the centres step by 1 px, and
        # these sums are exact), so each knot's antiderivative is evaluated once per border, not twice per pixel;
        # the knot at 0 is the same for every sweep.
        borders = np.concatenate([centres[..., :1] - 0.5, centres + 0.5], axis=-1)
        for x_k, change in knots:
            g = _second_antiderivative((borders - x_k) / sigma)
            pix += change * sigma**2 * (g[..., 1:] - g[..., :-1])
        count = pix.shape[-1]
        if self.sharpen_gain > 0.0:
            pix = pix + self.sharpen_gain * (pix - _convolved(pix, _gaussian_taps(self.sharpen_sigma_px)))
        smooth = np.zeros_like(pix)
        for k, weight in enumerate(self.weights):
            shift = k - half
            smooth[..., max(0, -shift) : count - max(0, shift)] += (
                weight * pix[..., max(0, shift) : count + min(0, shift)]
            )
        grad = np.full_like(smooth, -np.inf)
        grad[..., 1:-1] = 0.5 * (smooth[..., 2:] - smooth[..., :-2])
        grad[..., : half + 1] = -np.inf
        grad[..., count - half - 1 :] = -np.inf
        grad = np.where(centres < 0.5 * (width + d), grad, -np.inf)
        i = np.clip(np.argmax(grad, axis=-1)[..., None], 1, count - 2)
        mm = np.take_along_axis(grad, i - 1, axis=-1)[..., 0]
        m0 = np.take_along_axis(grad, i, axis=-1)[..., 0]
        mp = np.take_along_axis(grad, i + 1, axis=-1)[..., 0]
        denom = mm - 2.0 * m0 + mp
        ok = np.isfinite(denom) & (denom < 0)
        delta = np.where(ok, 0.5 * (mm - mp) / np.where(ok, denom, -1.0), 0.0)
        position = np.take_along_axis(np.broadcast_to(centres, grad.shape), i, axis=-1)[..., 0] + np.clip(delta, -1, 1)
        peak = 8.0 * m0  # the Sobel kernel's scale across a straight edge: 4 x 2 x central difference
        return position.mean(axis=1), peak.mean(axis=1)

    def edge_spacing(self, width: float) -> float:
        """Edge-to-edge distance (px) the pipeline measures on a still rope of `width` px."""
        left, _ = self._edges(width, np.zeros(1))
        return width - 2.0 * float(left[0])

    def rope_width(self, edge_width_px: float) -> float:
        """The rope width (px) whose still edges lie `edge_width_px` apart (inverse of `edge_spacing`, from a table
        over 0.3-20 px built once; below the blur's own spacing the smallest width)."""
        if self._spacings is None:
            widths = np.arange(0.3, 20.0, 0.1)
            left, _ = self._edges(widths, np.zeros(widths.size))
            self._spacings = (widths, np.maximum.accumulate(widths - 2.0 * left))
        widths, spacings = self._spacings
        return float(np.interp(edge_width_px, spacings, widths))

    def tables(self, edge_width_px: float) -> EdgeTables:
        """Return the tables for a rope whose still edges are `edge_width_px` apart (cached on a 0.1 px grid: a
        table takes ~10 ms, and the offsets change by less than 0.03 px within a grid step)."""
        key = max(1, round(edge_width_px * 10))
        cached = self._cache.get(key)
        if cached is not None:
            return cached
        m = key / 10.0
        width = self.rope_width(m)
        # Beyond a width plus the blur the offset is 0 and the gradient height falls as 1 / d: the tables end
        # there (lookups clamp to the last entry).
        step = 0.1
        blur = math.sqrt(
            self.lens_blur_px**2
            + float(np.sum(self.weights * (np.arange(len(self.weights)) - len(self.weights) // 2) ** 2))
            + 1.0 / 12.0
        )
        sweeps = np.arange(0.0, 2.0 * width + 8.0 * blur + 2.0, step)
        left, peaks = self._edges(width, sweeps)
        offsets = (0.5 * width - left).astype(np.float32)
        ratio = np.minimum.accumulate(peaks)  # per unit of the rope's full contrast; monotone for the inversion
        order = np.argsort(ratio, kind="stable")
        slant = self.slant_gain(width)
        tables = EdgeTables(width, m, step, np.maximum(offsets, 0.0), sweeps[order], ratio[order], slant)
        self._cache[key] = tables
        return tables

    def slant_bias(self, edge_width_px: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return how much shorter a still rope's edge spacing reads across a slanted rope than across an image
        axis: (angles in degrees 0-45 from the nearest axis, spacing there minus across an axis, px; <= 0).

        The model's edge is that of a band across an image axis. `measure_widths` reads the spacing between the
        Sobel magnitude's ridges, each found by a parabola along the image axis nearest the gradient; across a
        slanted band the 3x3 Sobel and that parabola read it shorter (a 2.49 px rope, lens blur 0.4 px,
        smoothing 1 px: -0.01 px at 15 degrees, -0.06 at 30, -0.13 at 45). Computed here by the same
        operations on a still band drawn at each angle (its edge blur the lens's and the pixel's variance, four
        positions of the band on the pixel grid); cached on a 0.1 px grid of the spacing, as `tables`.
        """
        key = max(1, round(edge_width_px * 10))
        cached = self._slants.get(key)
        if cached is not None:
            return cached
        width = self.rope_width(key / 10.0)
        sigma = math.sqrt(self.lens_blur_px**2 + 1.0 / 12.0)
        half = len(self.weights) // 2
        size = 2 * math.ceil(width + 4.0 * sigma + half + 6.0) + 1
        angles = np.arange(0.0, 46.0, 2.5)  # (the suppression changes sectors at 22.5 degrees)
        theta = np.radians(angles)[:, None, None, None]
        shifts = np.asarray(_PHASES)[None, :, None, None]
        rows, cols = np.mgrid[0:size, 0:size].astype(np.float64) - (size - 1) / 2.0
        across = cols[None, None] * np.cos(theta) + rows[None, None] * np.sin(theta) - shifts  # (A, P, S, S)
        image = normal_cdf((0.5 * width - across) / sigma) - normal_cdf((-0.5 * width - across) / sigma)
        count = image.shape[-1] - 2 * half  # the pipeline's separable smoothing (valid part only), on views
        image = sum(w * image[..., k : k + count] for k, w in enumerate(self.weights))
        image = sum(w * image[..., k : k + count, :] for k, w in enumerate(self.weights))
        gx = (image[..., :-2, 2:] + 2.0 * image[..., 1:-1, 2:] + image[..., 2:, 2:]) - (
            image[..., :-2, :-2] + 2.0 * image[..., 1:-1, :-2] + image[..., 2:, :-2]
        )
        gy = (image[..., 2:, :-2] + 2.0 * image[..., 2:, 1:-1] + image[..., 2:, 2:]) - (
            image[..., :-2, :-2] + 2.0 * image[..., :-2, 1:-1] + image[..., :-2, 2:]
        )
        gx, gy = gx.astype(np.float32), gy.astype(np.float32)
        mag = np.hypot(gx, gy)
        edges = _suppressed(mag, gx, gy)
        inner = np.zeros(edges.shape[-2:], bool)
        quarter = edges.shape[-1] // 4
        inner[quarter:-quarter, quarter:-quarter] = True
        height, count = edges.shape[-2:]
        lo, hi = np.zeros(height, np.int32), np.full(height, count - 1, np.int32)
        spacing = np.zeros(angles.size)
        out = np.empty(height * count, np.float32)
        for a in range(angles.size):
            found = []
            for p in range(len(_PHASES)):
                chain = np.ascontiguousarray(np.argwhere(edges[a, p] & inner & (gx[a, p] > 0.0)), np.int32)
                plane, reach = edges[a, p].view(np.uint8), np.float32(3.0 * width + 8.0)
                n = K.measure_widths(
                    plane,
                    lo,
                    hi,
                    mag[a, p],
                    gx[a, p],
                    gy[a, p],
                    chain,
                    np.int32(len(chain)),
                    np.float32(1.0),
                    reach,
                    out,
                )
                found.append(out[:n][np.isfinite(out[:n])])
            spacing[a] = float(np.mean(np.concatenate(found)))
        result = (angles, np.minimum(spacing - spacing[0], 0.0))
        self._slants[key] = result
        return result

    def slant_gain(self, width: float) -> float:
        """Return how far the tip read at the half-level crossing lies beyond the true flat end, per unit slope of
        the end's track (along the axis per unit across: an end that also moves along the rope).

        At lateral position x from a shape's axis (x > 0 into the band) the points are covered while the rope's
        axis passes within half a width, so the band ends, on average, at the end's position when the axis was at
        m(x) = (x + w/2) / 2 on the ramp (|x| < w/2) and m(x) = x beyond. The crossing along the axis averages
        m over the blur (Gaussian of the smoothing, lens and pixel variances) weighted by the coverage ramp.
        """
        x = np.linspace(-12.0, 12.0, 4801)
        grid = np.arange(len(self.weights)) - len(self.weights) // 2
        variance = float(np.sum(self.weights * grid**2)) + self.lens_blur_px**2 + 1.0 / 12.0
        if self.sharpen_gain > 0.0:  # an unsharp mask's share
            variance = max(variance - self.sharpen_gain * self.sharpen_sigma_px**2, 0.25)
        weight = np.exp(-0.5 * x**2 / variance) * np.clip((x + 0.5 * width) / width, 0.0, 1.0)
        m = np.where(x < 0.5 * width, 0.5 * (x + 0.5 * width), x)
        return float(np.sum(weight * m) / np.sum(weight))


def _gaussian_taps(sigma_px: float) -> NDArray[np.float64]:
    """A normalised Gaussian of `sigma_px` on integer offsets -3 sigma..3 sigma (at least -1..1)."""
    radius = max(1, math.ceil(3.0 * sigma_px))
    taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma_px) ** 2)
    return taps / taps.sum()


def _convolved(values: NDArray[np.float64], taps: NDArray[np.float64]) -> NDArray[np.float64]:
    """`values` convolved along the last axis with the centred `taps` (zero beyond the ends)."""
    out = np.zeros_like(values)
    count, half = values.shape[-1], len(taps) // 2
    for k, weight in enumerate(taps):
        shift = k - half
        out[..., max(0, -shift) : count - max(0, shift)] += weight * values[..., max(0, shift) : count + min(0, shift)]
    return out


def _suppressed(mag: NDArray[np.float32], gx: NDArray[np.float32], gy: NDArray[np.float32]) -> NDArray[np.bool_]:
    """Canny's non-maximum suppression (OpenCV's sectors, as the pipeline's `nms_pixel`) over the last two axes;
    the border pixels are not kept."""
    keep = np.zeros(mag.shape, bool)
    m = mag[..., 1:-1, 1:-1]
    ax, ay = np.abs(gx[..., 1:-1, 1:-1]), np.abs(gy[..., 1:-1, 1:-1])
    tan = math.tan(math.pi / 8.0)
    across = m > mag[..., 1:-1, :-2]
    across &= m >= mag[..., 1:-1, 2:]
    down = m > mag[..., :-2, 1:-1]
    down &= m >= mag[..., 2:, 1:-1]
    same = gx[..., 1:-1, 1:-1] * gy[..., 1:-1, 1:-1] >= 0.0  # s = 1: (r - 1, c - 1) and (r + 1, c + 1)
    diagonal = np.where(same, (m > mag[..., :-2, :-2]) & (m > mag[..., 2:, 2:]),
                        (m > mag[..., :-2, 2:]) & (m > mag[..., 2:, :-2]))  # fmt: skip
    keep[..., 1:-1, 1:-1] = np.where(ay < ax * tan, across, np.where(ay > ax * (tan + 2.0), down, diagonal))
    keep[..., 1:-1, 1:-1] &= m > 1e-3 * float(mag.max())
    return keep


def _second_antiderivative(z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Second antiderivative of the standard normal density: ((z^2 + 1) / 2) Phi(z) + (z / 2) phi(z).

    In place on a few buffers: temporaries of this size are fresh mappings (page faults) at every NumPy call."""
    density = np.multiply(z, -0.5)
    density *= z
    np.exp(density, out=density)
    density /= math.sqrt(2.0 * math.pi)
    out = np.multiply(z, z)
    out += 1.0
    out *= 0.5
    out *= normal_cdf(z)
    density *= np.multiply(z, 0.5)
    out += density
    return out


def normal_cdf(z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard normal CDF (erf by Abramowitz and Stegun 7.1.26, |error| < 1.5e-7: far below what matters here;
    NumPy has no erf and the device has no SciPy). In place, as `_second_antiderivative`."""
    x = np.abs(z)
    x /= math.sqrt(2.0)
    t = np.multiply(x, 0.3275911)
    t += 1.0
    np.divide(1.0, t, out=t)
    poly = np.multiply(t, 1.061405429)
    for coefficient in (-1.453152027, 1.421413741, -0.284496736, 0.254829592):
        poly += coefficient
        poly *= t
    x *= x
    np.negative(x, out=x)
    np.exp(x, out=x)
    x *= poly
    np.subtract(1.0, x, out=x)  # erf(|z| / sqrt 2)
    out = np.sign(z)
    out *= x
    out += 1.0
    out *= 0.5
    return out
