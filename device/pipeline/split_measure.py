"""The blur splitter's measuring on the first frames: the rope's polarity and width, its contrast, and the tip
sweep read from the edge slope (`SplitMeasuring`, a part of `BlurSplitter`)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import f32

__all__ = ["SplitMeasuring"]


class SplitMeasuring:
    """The measuring methods of `BlurSplitter` (they read the contour, planes and buffers it stores)."""

    def _whole_spans(self, shape: tuple[int, ...]) -> tuple[NDArray[np.int32], NDArray[np.int32]]:
        """Row spans covering an image of `shape` (planes valid everywhere: a `split` without an edge stage)."""
        whole = self._whole
        if whole is None or whole[0].shape[0] != shape[0] or int(whole[1][0]) != shape[1] - 1:
            whole = self._whole = (np.zeros(shape[0], np.int32), np.full(shape[0], shape[1] - 1, np.int32))
        return whole

    def _measure_polarity_and_width(
        self,
        width_px: float | None,
        edges: NDArray[np.uint8],
        polarity: float,
        mag: NDArray[np.float32],
        fixed_rc: tuple[float, float] | None,
    ) -> None:
        """Set `polarity_used` (decided from the gradients when `polarity` is 0) and `width` (measured when
        `width_px` is None) for the contour stored by `_prepare`."""
        pol = float(polarity)
        edges_ro = self._ro(edges)
        if pol == 0.0:
            # The rope is on the side where the opposite edge is near: compare the typical distance to the
            # opposite edge looking along +gradient (bright rope) and along -gradient (dark rope).
            medians = []
            for sign in (1.0, -1.0):
                K.measure_widths(
                    edges_ro, *self._spans, mag, self._gx, self._gy, self._chain, self._n, f32(sign), f32(64.0),
                    self.dist,
                )  # fmt: skip
                found = self.dist[: self._n][np.isfinite(self.dist[: self._n])]
                medians.append(float(np.median(found)) if found.size > self._n // 4 else np.inf)
            pol = 1.0 if medians[0] <= medians[1] else -1.0
        self.polarity_used = np.float32(pol)
        self.width_measured = float("nan")
        if width_px is None:
            self._measure_width(edges_ro, mag, fixed_rc)
        if width_px is not None:
            self.width = float(width_px)
        elif np.isfinite(self.width_measured):
            self.width = self.width_measured
        else:
            self.width = 4.0

    def _sweep_from_gradient(
        self, i_fix: np.int32, seg_a: np.int32, seg_b: np.int32, fixed_rc: tuple[float, float]
    ) -> float:
        """Estimate the tip sweep from the gradient magnitude along the sides.

        Across the band the intensity rises with slope contrast / d (each pixel is covered for a time in proportion
        to 1/d), whatever the rope width; the smoothed Sobel magnitude at the edge, divided by the contrast, is
        therefore a decreasing function of the local sweep d, tabulated for this rope width and smoothing by
        `BandEdgeModel`. The contrast is read from the image near the fixed end, where the rope hardly moved; d(s) is
        taken as proportional to the arc length s (rotation about the fixed end) and extrapolated to the tip.
        Returns nan when it cannot be measured.
        """
        contrast = self._contrast(fixed_rc)
        if not contrast >= 5.0:
            return float("nan")
        consts = self._constants(self.width)
        ratios, sweeps = consts.ratios_ro, consts.sweeps_ro
        estimates = []
        if contrast != self._contrast_key:  # it settles after ten frames
            # NumPy divided the float32 samples by the Python float in float32
            self._contrast_key, self._contrast32 = contrast, np.float32(contrast)
        contrast32 = self._contrast32
        for seg, direction in ((seg_a, self._plus), (seg_b, self._minus)):
            median = K.slope_sweep_median(
                self._chain, self._n, i_fix, seg, direction, self._mag_ro, self._slope_low, self._slope_high,
                contrast32, ratios, sweeps, self.slope_work,
            )  # fmt: skip
            if math.isfinite(median):
                estimates.append(median)
        if not estimates:
            return float("nan")
        return estimates[0] if len(estimates) == 1 else (estimates[0] + estimates[1]) / 2.0

    def _contrast(self, fixed_rc: tuple[float, float]) -> float:
        """Rope contrast (rope minus background, grey levels) near the fixed end; the median of the first 10
        frames' values is kept (the lighting does not change).

        Across the band the time-averaged coverage integrates to the rope's width whatever the sweep and the blur,
        so the contrast is the integral of the smoothed image across the band (background removed: a line through
        the levels on both sides) divided by the unbiased width (`BandEdgeModel`). Read near the fixed end, where
        the band is narrow and nothing else is likely to lie within it.
        """
        if len(self._contrasts) >= 10:
            return self._contrast_cache
        n = int(self._n)
        chain = self._chain
        smooth = self._smooth
        pol = float(self.polarity_used)
        width = self.width
        pts = self._points
        dist = np.hypot(pts[:n, 0] - fixed_rc[0], pts[:n, 1] - fixed_rc[1])
        r_far = float(dist.max())
        near = np.flatnonzero((dist > 2.0 * width + 2.0) & (dist < 2.0 * width + 2.0 + 0.1 * r_far))
        if near.size < 4:
            return float("nan")
        rc = chain[near]
        g = np.stack([self._gy[rc[:, 0], rc[:, 1]], self._gx[rc[:, 0], rc[:, 1]]], axis=1) * pol
        g /= np.maximum(np.hypot(*g.T), 1e-6)[:, None]
        step = 0.5
        t = np.arange(-(width + 3.0), 3.0 * width + 8.0, step)
        where = pts[near][:, None, :].astype(np.float64) + t[None, :, None] * g[:, None, :]
        height, width_img = smooth.shape
        ok = np.all((where[..., 0] >= 0) & (where[..., 0] <= height - 1), axis=1)
        ok &= np.all((where[..., 1] >= 0) & (where[..., 1] <= width_img - 1), axis=1)
        if np.count_nonzero(ok) < 4:
            return float("nan")
        where = where[ok]
        if self._refresh is not None:  # the samples reach past the band: smooth them from this frame
            low, high = np.floor(where.min(axis=(0, 1))), np.ceil(where.max(axis=(0, 1)))
            self._refresh(
                int(low[0]), int(min(high[0] + 1, height - 1)), int(low[1]), int(min(high[1] + 1, width_img - 1))
            )
        r0 = np.minimum(np.floor(where[..., 0]).astype(int), height - 2)
        c0 = np.minimum(np.floor(where[..., 1]).astype(int), width_img - 2)
        fr, fc = where[..., 0] - r0, where[..., 1] - c0
        values = (smooth[r0, c0] * (1 - fr) * (1 - fc) + smooth[r0, c0 + 1] * (1 - fr) * fc
                  + smooth[r0 + 1, c0] * fr * (1 - fc) + smooth[r0 + 1, c0 + 1] * fr * fc)  # fmt: skip
        first = np.median(values[:, :4], axis=1)
        last = np.median(values[:, -4:], axis=1)
        frac = (t - t[0]) / (t[-1] - t[0])
        background = first[:, None] + (last - first)[:, None] * frac[None, :]
        area = pol * (values - background).sum(axis=1) * step
        value = float(np.median(area)) / self.model.tables(width).width_px
        if not value > 0:
            return float("nan")
        self._contrasts.append(value)
        self._contrast_cache = float(np.median(self._contrasts))
        return self._contrast_cache

    def _measure_width(
        self, edges: NDArray[np.uint8], mag: NDArray[np.float32], fixed_rc: tuple[float, float] | None
    ) -> None:
        """Measure the rope's edge spacing: the distance to the opposite edge, near the fixed end if known.

        Motion only widens the band (for a sweep beyond the rope's width the spacing is the sweep), so the
        spacing is read where the rope moved least: first the lower quartile over the whole contour, then the
        median just beyond the fixed end's cap (within a tenth of the rope's extent).
        """
        K.measure_widths(
            edges, *self._spans, mag, self._gx, self._gy, self._chain, self._n, self.polarity_used, f32(64.0), self.dist
        )
        widths = self.dist[: self._n]
        finite = np.isfinite(widths)
        valid = widths[finite]
        self.width_measured = float(np.percentile(valid, 25)) if valid.size else float("nan")
        if fixed_rc is not None and valid.size:
            pts = self._points[: self._n]
            dist = np.hypot(pts[:, 0] - fixed_rc[0], pts[:, 1] - fixed_rc[1])
            start = 2.0 * self.width_measured + 2.0
            near = finite & (dist > start) & (dist < start + 0.1 * dist.max())
            if np.count_nonzero(near) >= 4:
                self.width_measured = float(np.median(widths[near]))
