"""EdgeThresholds: Canny thresholds relative to the frame's own noise, so that a faint rope on a quiet plate is
found with the same pipeline as a bright one, and a noisy or textured plate does not flood it with edges."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline.edges import EdgeDetector

__all__ = ["HIGH_PER_NOISE", "LOW_PER_NOISE", "EdgeThresholds"]

LOW_PER_NOISE = 2.5
"""Low threshold per median background gradient magnitude: for Gaussian noise the magnitude is Rayleigh
distributed and 1.3 % of the background passes it."""
HIGH_PER_NOISE = 4.0
"""High threshold per median background gradient magnitude: 1.6e-5 of the background passes it (no seeds)."""
_STEP = 4
"""Pixel step of the subsample of the gradient magnitude whose median is taken."""


class EdgeThresholds:
    """Measure the Canny thresholds of a scene from its first frames: the median gradient magnitude of the
    smoothed frame (the rope covers a small part of it, so the median is the background's noise and texture)
    times `LOW_PER_NOISE` and `HIGH_PER_NOISE`, at least `floor_low`/`floor_high` (grey-level quantisation of a
    noise-free frame) and at most the configured `low`/`high`.

    Parameters
    ----------
    height, width
        Image size (px).
    smooth_sigma_px
        The pipeline's Gaussian smoothing before the Sobel gradient.
    low, high
        The configured thresholds: the largest the measured ones may be.
    frames
        Frames to measure on (their medians are averaged); 0: the configured thresholds are kept.
    floor_low, floor_high
        The smallest thresholds.
    """

    def __init__(
        self,
        height: int,
        width: int,
        smooth_sigma_px: float,
        low: float,
        high: float,
        frames: int,
        floor_low: float = 4.0,
        floor_high: float = 10.0,
    ) -> None:
        if frames < 0:
            raise ValueError(f"frames must be >= 0, got {frames}")
        self.low, self.high = float(low), float(high)
        self.frames = int(frames)
        self.floor_low, self.floor_high = min(floor_low, self.low), min(floor_high, self.high)
        self._medians: list[float] = []
        self._detector: EdgeDetector | None = None
        self._shape = (height, width)
        self._sigma = smooth_sigma_px
        # The median needs the magnitude on every `_STEP`-th row only: edges detected on those rows' spans give
        # the same values there (the smoothing and Sobel spans grow around them) for a fraction of a whole frame.
        self._lo = np.ones(height, np.int32)
        self._hi = np.zeros(height, np.int32)
        self._lo[::_STEP], self._hi[::_STEP] = 0, width - 1

    @property
    def measuring(self) -> bool:
        """Whether frames are still being measured."""
        return len(self._medians) < self.frames

    def prepare(self) -> None:
        """Build the detector of the measured frames and run it once on a blank frame (its buffers touched, the
        median's code paths run), so that the first measured frame pays only its measurement; nothing is
        measured. Does nothing when no frame is to be measured."""
        if self.measuring:
            self._median(np.zeros(self._shape, np.uint8))

    def measure(self, frame: NDArray[np.uint8]) -> tuple[float, float] | None:
        """Measure one frame (the gradient on every `_STEP`-th row: only the first `frames` frames); returns the
        thresholds (low, high) after the last of them, else None."""
        self._medians.append(self._median(frame))
        if self.measuring:
            return None
        self._detector = None  # its planes are not needed any more
        noise = float(np.mean(self._medians))
        low = min(max(LOW_PER_NOISE * noise, self.floor_low), self.low)
        high = min(max(HIGH_PER_NOISE * noise, self.floor_high), self.high)
        return low, max(high, low)

    def _median(self, frame: NDArray[np.uint8]) -> float:
        """The median gradient magnitude of `frame`'s smoothed image on a grid of `_STEP` px."""
        if self._detector is None:
            self._detector = EdgeDetector(*self._shape, self._sigma, self.low, self.high)
        d = self._detector
        d.detect(frame, self._lo, self._hi)
        return float(np.median(d.mag[::_STEP, ::_STEP]))

    @property
    def noise(self) -> float | None:
        """The mean of the measured medians (None before the first frame)."""
        return float(np.mean(self._medians)) if self._medians else None
