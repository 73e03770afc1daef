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

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["BandEdgeModel", "EdgeTables"]

_FINE_PX = 0.02
_PHASES = (0.0, 0.25, 0.5, 0.75)


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
    """

    def __init__(self, smooth_weights: NDArray[np.floating], lens_blur_px: float) -> None:
        self.weights = np.asarray(smooth_weights, np.float64)
        self.lens_blur_px = float(lens_blur_px)
        self._cache: dict[int, EdgeTables] = {}

    def _edge(self, width: float, sweep: float) -> tuple[float, float]:
        """Mean over pixel phases of the left edge's position (relative to the start's outer edge, px) and of the
        peak gradient height (per unit of contrast) of a band (width, sweep)."""
        pad = 6.0 + 4.0 * self.lens_blur_px + len(self.weights)
        x = np.arange(-pad, width + sweep + pad, _FINE_PX)
        if sweep > 1e-6:
            cover = np.clip((np.minimum(x, sweep) - np.maximum(x - width, 0.0)) / sweep, 0.0, None)
            cover[(x < 0.0) | (x > width + sweep)] = 0.0
        else:
            cover = ((x >= 0.0) & (x < width)).astype(np.float64)
        if self.lens_blur_px > 0:
            k = np.arange(-4.0 * self.lens_blur_px, 4.0 * self.lens_blur_px + _FINE_PX, _FINE_PX)
            g = np.exp(-0.5 * (k / self.lens_blur_px) ** 2)
            cover = np.convolve(cover, g / g.sum(), mode="same")
        step = round(1.0 / _FINE_PX)
        positions, peaks = [], []
        half = len(self.weights) // 2
        for phase in _PHASES:
            start = round(phase / _FINE_PX)
            count = (len(x) - start) // step
            pix = cover[start : start + count * step].reshape(count, step).mean(axis=1)
            centres = x[start] + (np.arange(count) + 0.5) * step * _FINE_PX - 0.5 * _FINE_PX
            sm = np.convolve(pix, self.weights[::-1], mode="same")
            grad = np.zeros_like(sm)
            grad[1:-1] = 0.5 * (sm[2:] - sm[:-2])
            grad[: half + 1] = 0.0
            grad[-half - 1 :] = 0.0
            left = centres < 0.5 * (width + sweep)
            i = int(np.argmax(np.where(left, grad, -np.inf)))
            mm, m0, mp = grad[i - 1], grad[i], grad[i + 1]
            denom = mm - 2.0 * m0 + mp
            delta = 0.5 * (mm - mp) / denom if denom < 0 else 0.0
            positions.append(centres[i] + float(np.clip(delta, -1.0, 1.0)))
            peaks.append(4.0 * 2.0 * m0)  # the Sobel kernel's scale: 4 x 2 x central difference
        return float(np.mean(positions)), float(np.mean(peaks))

    def edge_spacing(self, width: float) -> float:
        """Edge-to-edge distance (px) the pipeline measures on a still rope of `width` px."""
        left, _ = self._edge(width, 0.0)
        return width - 2.0 * left

    def tables(self, edge_width_px: float) -> EdgeTables:
        """Return the tables for a rope whose still edges are `edge_width_px` apart (cached on a 0.05 px grid)."""
        key = max(1, round(edge_width_px * 20))
        cached = self._cache.get(key)
        if cached is not None:
            return cached
        m = key / 20.0
        # Invert m(w) (increasing in w) by bisection; below the blur's own spacing no width fits: take the smallest.
        lo, hi = 0.05, max(2.0 * m, 1.0)
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if self.edge_spacing(mid) < m:
                lo = mid
            else:
                hi = mid
        width = 0.5 * (lo + hi)
        step = 0.05
        sweeps = np.arange(0.0, 3.0 * width + 6.0 * (1.0 + self.lens_blur_px), step)
        offsets = np.empty(len(sweeps), np.float32)
        peaks = np.empty(len(sweeps))
        for k, d in enumerate(sweeps):
            left, peak = self._edge(width, float(d))
            offsets[k] = 0.5 * width - left
            peaks[k] = peak
        ratio = np.minimum.accumulate(peaks)  # per unit of the rope's full contrast; monotone for the inversion
        order = np.argsort(ratio, kind="stable")
        slant = self.slant_gain(width)
        tables = EdgeTables(width, m, step, np.maximum(offsets, 0.0), sweeps[order], ratio[order], slant)
        self._cache[key] = tables
        return tables

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
        weight = np.exp(-0.5 * x**2 / variance) * np.clip((x + 0.5 * width) / width, 0.0, 1.0)
        m = np.where(x < 0.5 * width, 0.5 * (x + 0.5 * width), x)
        return float(np.sum(weight * m) / np.sum(weight))
