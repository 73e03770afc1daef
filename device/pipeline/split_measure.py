"""BandMeasure: what the blur split reads off the band on the first frames: the rope's polarity and edge spacing,
its contrast, and the tip sweep from the edge slope."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import f32
from ropecam.device.pipeline.edge_model import BandEdgeModel
from ropecam.device.pipeline.width_tables import WidthTables

__all__ = ["CONTRAST_FRAMES", "GAIN_READINGS", "MAX_CONTRAST", "MAX_RATIO_GAIN", "BandMeasure"]

CONTRAST_FRAMES = 10
"""Frames whose contrast readings (median) are kept afterwards: the lighting does not change."""
MAX_CONTRAST = 3.0 * 255.0
"""The largest contrast (grey levels) kept as the rope's (larger: nan, `BandMeasure.contrast_rejected`). An 8-bit
frame has 255 levels between black and white (a gamma-decoded one too: the tone curve maps 0-255 onto 0-255); the
readings are divided by a modelled rope width that can be a third of the rope's where the width table is steep
(`lab-dark`: 0.5-1.5 px for edge spacings 2.90-2.98 px, 163 levels read as up to 480). A larger one comes from a
width that is not the rope's at all: an edge model made of a lens blur read across a clamp's edges (`clamp on`:
1.15 px for 0.4, a 2.4 px rope read as 0.30 px, 1516 levels)."""
MAX_RATIO_GAIN = 1.5
"""The largest `BandMeasure.ratio_gain` kept (a still rope's edge slope at most this much above the model's)."""
GAIN_READINGS = 3
"""The fewest contrast readings whose median gives `BandMeasure.ratio_gain` (1 before): one reading scatters by
5 % (simulated `lab-dark`, tuning seed: frame 0 read 1.175 where the ten read 1.08-1.16; session 18, dark18)."""
_PLUS, _MINUS = np.int32(1), np.int32(-1)
_SLOPE_LOW, _SLOPE_HIGH = np.float32(0.5), np.float32(0.85)
"""The arc fractions of each side whose edge slope gives the sweep (as `split_frame`)."""
_TO_TIP = np.int32(1)

Spans = tuple[NDArray[np.int32], NDArray[np.int32]]


class BandMeasure:
    """Read the rope's polarity, edge spacing, contrast and tip sweep off one contour's band.

    The arrays each method takes are the contour (`points`, `chain`, `n` points) and the planes it came from
    (read-only `gx`, `gy`, `mag`, `edges`, `smooth`), valid inside the row `spans`. The contrast is kept over
    the first `CONTRAST_FRAMES` frames (`contrast`), then fixed.

    Parameters
    ----------
    model
        The band edge model (its tables per rope width).
    dist, slope_work
        Scratch (capacity,) float32 and float64 (the split's buffers).
    """

    def __init__(self, model: BandEdgeModel, dist: NDArray[np.float32], slope_work: NDArray[np.float64]) -> None:
        self.model = model
        self.dist = dist
        self.slope_work = slope_work
        self.contrasts: list[float] = []
        """The first frames' contrast readings: integrals across the band (grey levels x px)."""
        self._width_px = math.nan
        """The edge spacing in use at the last call, whose rope width divides the integrals (`rescale`)."""
        self.contrast_px = float("nan")
        """The median of `contrasts` over the rope width of the edge spacing in use (the rope's contrast once
        `CONTRAST_FRAMES` are in); nan when larger than `MAX_CONTRAST` (that width is not the rope's)."""
        self._contrast_key = math.nan
        self._contrast32 = np.float32(0.0)
        self._whole: Spans | None = None
        self.slopes: list[float] = []
        """The gradient magnitudes (median) where each of `contrasts` was read: the still rope's edge slope."""
        self.ratio_applies = False
        """Whether `ratio_gain` is read (a dark rope in gamma-decoded frames: set by the splitter before
        `contrast`)."""
        self.ratio_gain = 1.0
        """How much steeper the still rope's edges are than the edge model's, per unit of the contrast read (1-1.5;
        1 unless `ratio_applies`): the split/static decision reads its sweeps from the edge slope with the contrast
        times it (`decision_contrast`); the local sweeps of a split are the model's own.

        A camera sharpens the gamma-encoded frame; decoded, the bright halo beside a dark rope is stretched, so its
        edges are steeper, and the integral across the band (the contrast) smaller, than the model's blurred bar:
        the still rope's slope over the contrast stands 1.08-1.19 times above the model's largest, where every
        sweep reads 0 (session 18, dark18). Sweeps of 2-5 px were then read as none and the frames fell back to
        the band's middle, half a sweep off (simulated `lab-dark`, setup on 240 frames, the swing's turn, frames
        72-84 and 208-212: tips 0.7-2.7 px off). Read where the contrast is read, near the fixed end, where the rope
        moves least: the median magnitude over the contrast (medians over the first `CONTRAST_FRAMES` readings)
        over the model's still rope's. The local sweeps keep the model's heights: with the gain there too (tried,
        session 18) short exposures' small sweeps read 0.5-1.5 px too large (the paper camera at 1 ms)."""

    def forget(self) -> None:
        """Forget the contrast readings and what they gave (`BlurSplitter.restart`)."""
        self.contrasts.clear()
        self.slopes.clear()
        self.contrast_px = float("nan")
        self.ratio_gain = 1.0

    def keep_readings(self, count: int) -> None:
        """Drop the contrast readings after the first `count`, and what they gave: a frame's contour split again
        (`ResultFinisher._rejoined`: the joined outline, then the frame's own once more) is read once, by the
        frame's own split, so that the first `CONTRAST_FRAMES` readings (and `GAIN_READINGS`) are as many frames."""
        if len(self.contrasts) <= count:
            return
        del self.contrasts[count:]
        del self.slopes[count:]
        if self.contrasts:
            self.rescale()
        else:
            self.forget()

    def decision_contrast(self, width_px: float) -> float:
        """The contrast the split/static decision reads the sweep from the edge slope with: `contrast_for` times
        `ratio_gain`."""
        return self.contrast_for(width_px) * self.ratio_gain

    def rescale(self, width_px: float | None = None) -> None:
        """Divide the contrast readings' integrals by the rope width of the current `model` (it changed) and of
        the edge spacing `width_px` (None: the one in use)."""
        if width_px is not None:
            self._width_px = width_px
        if self.contrasts and math.isfinite(self._width_px):
            tables = self.model.tables(self._width_px)
            contrast = float(np.median(self.contrasts)) / tables.width_px
            self.contrast_px = contrast if contrast <= MAX_CONTRAST else math.nan
            gain = 1.0
            if self.ratio_applies and len(self.slopes) >= GAIN_READINGS and math.isfinite(self.contrast_px):
                gain = float(np.median(self.slopes)) / self.contrast_px / float(tables.peak_ratio[-1])
                gain = min(max(gain, 1.0), MAX_RATIO_GAIN) if math.isfinite(gain) else 1.0
            self.ratio_gain = gain

    def contrast_for(self, width_px: float) -> float:
        """The rope's contrast over the rope width of the edge spacing `width_px` in use (`contrast`'s readings;
        nan before the first)."""
        if width_px != self._width_px:
            self.rescale(width_px)
        return self.contrast_px

    @property
    def contrast_rejected(self) -> bool:
        """Whether the contrast readings over the rope width in use exceed `MAX_CONTRAST`: that width, and the edge
        model it came from (the lens blur read on the first frames), are not the rope's."""
        return bool(self.contrasts) and math.isfinite(self._width_px) and not math.isfinite(self.contrast_px)

    @property
    def contrast_settled(self) -> bool:
        """Whether the contrast no longer changes (and is large enough for the sweep from the edge slope)."""
        return len(self.contrasts) >= CONTRAST_FRAMES and self.contrast_px >= 5.0

    def whole_spans(self, shape: tuple[int, ...]) -> Spans:
        """Row spans covering an image of `shape` (planes valid everywhere: a split without an edge stage)."""
        whole = self._whole
        if whole is None or whole[0].shape[0] != shape[0] or int(whole[1][0]) != shape[1] - 1:
            whole = self._whole = (np.zeros(shape[0], np.int32), np.full(shape[0], shape[1] - 1, np.int32))
        return whole

    def polarity_and_width(
        self,
        points: NDArray[np.float32],
        chain: NDArray[np.int32],
        n: np.int32,
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        mag: NDArray[np.float32],
        edges: NDArray[np.uint8],
        spans: Spans,
        width_px: float | None,
        polarity: float,
        fixed_rc: tuple[float, float] | None,
    ) -> tuple[np.float32, float, float]:
        """Return the polarity (`polarity`, or decided from the gradients when it is 0), the edge spacing measured
        on this contour (nan when `width_px` is given or nothing is measured) and the width to split with
        (`width_px`, else the measured spacing, else 4 px)."""
        pol = float(polarity)
        if pol == 0.0:
            # The rope is on the side where the opposite edge is near: compare the typical distance to the
            # opposite edge looking along +gradient (bright rope) and along -gradient (dark rope).
            medians = []
            for sign in (1.0, -1.0):
                K.measure_widths(edges, *spans, mag, gx, gy, chain, n, f32(sign), f32(64.0), self.dist)
                found = self.dist[:n][np.isfinite(self.dist[:n])]
                medians.append(float(np.median(found)) if found.size > n // 4 else np.inf)
            pol = 1.0 if medians[0] <= medians[1] else -1.0
        polarity_used = np.float32(pol)
        measured = float("nan")
        if width_px is None:
            measured = self._width(points, chain, n, gx, gy, mag, edges, spans, polarity_used, fixed_rc)
        if width_px is not None:
            width = float(width_px)
        elif np.isfinite(measured):
            width = measured
        else:
            width = 4.0
        return polarity_used, measured, width

    def _width(
        self,
        points: NDArray[np.float32],
        chain: NDArray[np.int32],
        n: np.int32,
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        mag: NDArray[np.float32],
        edges: NDArray[np.uint8],
        spans: Spans,
        polarity: np.float32,
        fixed_rc: tuple[float, float] | None,
    ) -> float:
        """Measure the rope's edge spacing: the distance to the opposite edge, near the fixed end if known.

        Motion only widens the band (for a sweep beyond the rope's width the spacing is the sweep), so the
        spacing is read where the rope moved least: first the lower quartile over the whole contour, then the
        median just beyond the fixed end's cap (within a tenth of the rope's extent).

        Each point's spacing is first corrected for the slant of the rope to the image axes
        (`BandEdgeModel.slant_bias`: the model's spacing is that across an axis; across a slanted rope the
        pipeline reads it up to 0.14 px shorter, and the model's width, contrast and sweep tables built on such a
        spacing read sweeps below the rope's width wrongly: on the simulated rig-soft demo, whose rope near the
        fixed end turns through 45 degrees on the first frames, the begin and end shapes were 0.4-0.7 mm too
        close where the sweep is 0.5-2 px).
        """
        K.measure_widths(edges, *spans, mag, gx, gy, chain, n, polarity, f32(64.0), self.dist)
        widths = self.dist[:n]
        finite = np.isfinite(widths)
        if np.any(finite):
            across = np.abs(gx[chain[:n, 0], chain[:n, 1]])
            down = np.abs(gy[chain[:n, 0], chain[:n, 1]])
            slant = np.degrees(np.arctan2(np.minimum(across, down), np.maximum(across, down)))
            angles, bias = self.model.slant_bias(float(np.percentile(widths[finite], 25)))
            widths = widths - np.interp(slant, angles, bias)
        valid = widths[finite]
        measured = float(np.percentile(valid, 25)) if valid.size else float("nan")
        if fixed_rc is not None and valid.size:
            pts = points[:n]
            dist = np.hypot(pts[:, 0] - fixed_rc[0], pts[:, 1] - fixed_rc[1])
            start = 2.0 * measured + 2.0
            near = finite & (dist > start) & (dist < start + 0.1 * dist.max())
            if np.count_nonzero(near) >= 4:
                measured = float(np.median(widths[near]))
        return measured

    def sweep_from_gradient(
        self,
        chain: NDArray[np.int32],
        n: np.int32,
        mag: NDArray[np.float32],
        i_fix: np.int32,
        seg_a: np.int32,
        seg_b: np.int32,
        contrast: float,
        tables: WidthTables,
    ) -> float:
        """Estimate the tip sweep from the gradient magnitude along the sides of a rope of `contrast`.

        Across the band the intensity rises with slope contrast / d (each pixel is covered for a time in proportion
        to 1/d), whatever the rope width; the smoothed Sobel magnitude at the edge, divided by the contrast, is
        therefore a decreasing function of the local sweep d, tabulated for this rope width and smoothing by
        `BandEdgeModel` (`tables`). d(s) is taken as proportional to the arc length s (rotation about the fixed
        end) and extrapolated to the tip. Returns nan when it cannot be measured.
        """
        if not contrast >= 5.0:
            return float("nan")
        estimates = []
        if contrast != self._contrast_key:  # it settles after ten frames
            # NumPy divided the float32 samples by the Python float in float32
            self._contrast_key, self._contrast32 = contrast, np.float32(contrast)
        for seg, direction in ((seg_a, _PLUS), (seg_b, _MINUS)):
            median = K.slope_sweep_median(
                chain, n, i_fix, seg, direction, mag, _SLOPE_LOW, _SLOPE_HIGH, self._contrast32, tables.ratios_ro,
                tables.sweeps_ro, _TO_TIP, self.slope_work,
            )  # fmt: skip
            if math.isfinite(median):
                estimates.append(median)
        if not estimates:
            return float("nan")
        return estimates[0] if len(estimates) == 1 else (estimates[0] + estimates[1]) / 2.0

    def body_sweep(
        self,
        chain: NDArray[np.int32],
        n: np.int32,
        mag: NDArray[np.float32],
        i_fix: np.int32,
        seg_a: np.int32,
        seg_b: np.int32,
        contrast: float,
        tables: WidthTables,
    ) -> float:
        """Return the body's own sweep (px): the largest median local sweep read from the edge slope over the
        stretches of both sides between the arc fractions `K.BODY_WINDOWS` (`K.body_sweep`, as `split_frame`
        decides with it); nan without a contrast reading or samples.

        The arguments and the contrast floor are `sweep_from_gradient`'s: both read the edge slope of the same two
        sides (`K.slope_sweep_median`), the tip's sweep extrapolated there, the body's own here. Two calls because
        `BlurSplitter._split` wants this one only when the tip's sweep is below ``static_ratio`` widths (as
        `split_frame`)."""
        if not contrast >= 5.0:
            return float("nan")
        return float(
            K.body_sweep(
                chain, n, i_fix, seg_a, seg_b, mag, np.float32(contrast), K.BODY_WINDOWS, tables.ratios_ro,
                tables.sweeps_ro, self.slope_work,
            )
        )  # fmt: skip

    def contrast(
        self,
        points: NDArray[np.float32],
        chain: NDArray[np.int32],
        n: int,
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        smooth: NDArray[np.float32],
        refresh: Callable[[int, int, int, int], object] | None,
        polarity: float,
        width: float,
        fixed_rc: tuple[float, float],
    ) -> float:
        """Return the rope's contrast (rope minus background, grey levels) near the fixed end: from the first
        `CONTRAST_FRAMES` readings (then this contour is not read); nan when not readable.

        Across the band the time-averaged coverage integrates to the rope's width whatever the sweep and the blur,
        so the contrast is the integral of the smoothed image across the band (background removed: a line through
        the levels on both sides; the median of the readings) divided by the unbiased width (`BandEdgeModel`) of
        the edge spacing `width` in use. Read near the fixed end, where
        the band is narrow and nothing else is likely to lie within it. `refresh` (r0, r1, c0, c1) makes
        `smooth` this frame's over a box first (None: it is valid everywhere).
        """
        if len(self.contrasts) >= CONTRAST_FRAMES:
            return self.contrast_for(width)  # the spacing settles after the readings: the integrals over its width
        pts = points
        dist = np.hypot(pts[:n, 0] - fixed_rc[0], pts[:n, 1] - fixed_rc[1])
        r_far = float(dist.max())
        near = np.flatnonzero((dist > 2.0 * width + 2.0) & (dist < 2.0 * width + 2.0 + 0.1 * r_far))
        if near.size < 4:
            return float("nan")
        rc = chain[near]
        g = np.stack([gy[rc[:, 0], rc[:, 1]], gx[rc[:, 0], rc[:, 1]]], axis=1) * polarity
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
        if refresh is not None:  # the samples reach past the band: smooth them from this frame
            low, high = np.floor(where.min(axis=(0, 1))), np.ceil(where.max(axis=(0, 1)))
            refresh(int(low[0]), int(min(high[0] + 1, height - 1)), int(low[1]), int(min(high[1] + 1, width_img - 1)))
        r0 = np.minimum(np.floor(where[..., 0]).astype(int), height - 2)
        c0 = np.minimum(np.floor(where[..., 1]).astype(int), width_img - 2)
        fr, fc = where[..., 0] - r0, where[..., 1] - c0
        values = (smooth[r0, c0] * (1 - fr) * (1 - fc) + smooth[r0, c0 + 1] * (1 - fr) * fc
                  + smooth[r0 + 1, c0] * fr * (1 - fc) + smooth[r0 + 1, c0 + 1] * fr * fc)  # fmt: skip
        first = np.median(values[:, :4], axis=1)
        last = np.median(values[:, -4:], axis=1)
        frac = (t - t[0]) / (t[-1] - t[0])
        background = first[:, None] + (last - first)[:, None] * frac[None, :]
        area = polarity * (values - background).sum(axis=1) * step
        integral = float(np.median(area))
        if not integral > 0:
            return float("nan")
        # The median integral divided by the rope width of the edge spacing in use: under a strong blur the
        # width read from a spacing changes steeply with it (2.3 px at 4.21, 2.74 at 4.27 for a 1.5 px blur), so
        # readings divided each by its own frame's width scatter by 10 % and more. The spacing in use is that of
        # this frame until the width settles, and the settled one afterwards (see the return above): dividing
        # for good by the last reading's spacing froze the contrast at whatever that frame measured (a contour
        # that took the clamp's rod in, 6-12 px: `lab-dark` read 38 instead of about 190 grey levels, and every
        # later sweep from the edge slope was 0: static centrelines half a sweep off, reported OK).
        self.contrasts.append(integral)
        self.slopes.append(float(np.median(np.hypot(gx[rc[:, 0], rc[:, 1]], gy[rc[:, 0], rc[:, 1]])[ok])))
        self.rescale(width)
        return self.contrast_px
