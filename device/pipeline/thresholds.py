"""EdgeThresholds: Canny thresholds relative to the frame's own noise, so that a faint rope on a quiet plate is
found with the same pipeline as a bright one, and a noisy or textured plate does not flood it with edges; then
followed slowly over the stream (a lamp warming up, a cloud, a gain change)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import FrameSlot, array_layout_known, buffer_table, ro
from ropecam.device.pipeline.edges import EdgeDetector, gaussian_weights

__all__ = ["FOLLOW_WEIGHT", "HIGH_PER_NOISE", "LOW_PER_NOISE", "EdgeThresholds"]

LOW_PER_NOISE = 2.5
"""Low threshold per median background gradient magnitude: for Gaussian noise the magnitude is Rayleigh
distributed and 1.3 % of the background passes it."""
HIGH_PER_NOISE = 4.0
"""High threshold per median background gradient magnitude: 1.6e-5 of the background passes it (no seeds)."""
_STEP = 4
"""Pixel step of the subsample of the gradient magnitude whose median is taken."""
FOLLOW_SAMPLES = 2048
"""Samples of the gradient magnitude per following cycle: the grid's step is chosen for it (16 px on a 1024x544
frame), and a cycle's slices share them out (~130 per frame at 16 frames per cycle)."""
FOLLOW_WEIGHT = 0.25
"""Weight of a cycle's median in the followed noise level (an exponential average: a step change is 90 % followed
after 8 cycles)."""
FOLLOW_CHANGE = 0.05
"""Relative change of the followed thresholds below which the pipeline keeps the ones it uses (setting them makes
the kernels' argument lists again)."""


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
    update_frames
        After the first `frames`, the slices of one following cycle (`follow`): each samples a slice of a sparse
        grid of the gradient magnitude, the cycle's median is averaged into the noise level (`FOLLOW_WEIGHT`) and
        the thresholds follow it. 0: the first measurement is kept.
    sample_every
        The frames `follow` takes per slice: it samples one of them (the first), so a cycle is `update_frames` x
        `sample_every` frames and the slice's cost (~30-45 us on 1024x544) is paid on one frame in `sample_every`.
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
        update_frames: int = 0,
        sample_every: int = 1,
    ) -> None:
        if frames < 0:
            raise ValueError(f"frames must be >= 0, got {frames}")
        if update_frames < 0:
            raise ValueError(f"update_frames must be >= 0, got {update_frames}")
        if sample_every < 1:
            raise ValueError(f"sample_every must be >= 1, got {sample_every}")
        self.low, self.high = float(low), float(high)
        self.frames = int(frames)
        self.floor_low, self.floor_high = min(floor_low, self.low), min(floor_high, self.high)
        self._medians: list[float] = []
        self.update_frames = int(update_frames)
        self.sample_every = int(sample_every)
        self._wait = 0  # frames `follow` skips before its next slice
        self._weights = ro(gaussian_weights(smooth_sigma_px))
        self._hist = np.zeros(4096, np.int32)  # magnitudes to 1024 in 1 / HIST_PER_UNIT bins
        self._hist_ro = ro(self._hist)
        self._work = np.zeros((len(self._weights) + 2, 3), np.float32)
        # `follow`'s kernel reads the frame and these buffers through a table (`K.sample_slice`: no array argument,
        # no Python allocation per call), where NumPy's array layout is the one it reads.
        self._slot = FrameSlot(height, width)
        self._table = buffer_table(
            {"frame_slot": self._slot, "weights": self._weights, "work": self._work, "hist": self._hist},
            K.SAMPLE_BUFFERS,
        )
        self._table_address = int(self._table.ctypes.data) if array_layout_known() else 0
        self._step = max(2, int(math.sqrt(height * width / FOLLOW_SAMPLES)))  # the following grid's step (px)
        self._phase = 0
        self._level: float | None = None  # the followed noise level (median gradient magnitude)
        self.used: tuple[float, float] | None = None
        """The thresholds last handed out (`measure` or `follow`)."""
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
        self._level = float(np.mean(self._medians))
        self.used = self._from_level(self._level)
        return self.used

    def _from_level(self, noise: float) -> tuple[float, float]:
        low = _clamp(LOW_PER_NOISE * noise, self.floor_low, self.low)
        high = _clamp(HIGH_PER_NOISE * noise, self.floor_high, self.high)
        return low, low if low > high else high  # max(high, low)

    def _median(self, frame: NDArray[np.uint8]) -> float:
        """The median gradient magnitude of `frame`'s smoothed image on a grid of `_STEP` px."""
        if self._detector is None:
            self._detector = EdgeDetector(*self._shape, self._sigma, self.low, self.high)
        d = self._detector
        d.detect(frame, self._lo, self._hi)
        return float(np.median(d.mag[::_STEP, ::_STEP]))

    @property
    def following(self) -> bool:
        """Whether the thresholds follow the frames (measured first, `update_frames` > 0)."""
        return self.update_frames > 0 and self._level is not None

    def update(self, frame: NDArray[np.uint8]) -> tuple[float, float] | None:
        """The frame's turn, one call per frame (the pipeline's): `measure` it while frames are being measured,
        else `follow` when following; returns new thresholds (low, high), else None. The usual frame (following,
        not its slice's) returns at once, without the calls of the properties or of `follow`."""
        if len(self._medians) < self.frames:  # `measuring`
            return self.measure(frame)
        if self.update_frames == 0 or self._level is None:  # not `following`
            return None
        if self._wait:  # a frame `follow` skips
            self._wait -= 1
            return None
        return self.follow(frame)

    def follow(self, frame: NDArray[np.uint8]) -> tuple[float, float] | None:
        """On one frame in `sample_every` (the others return None at once), sample the next slice of the grid
        (every `update_frames`-th row of it, in turn); at the end of a cycle, average its median into the noise
        level. Returns new thresholds when they moved by more than `FOLLOW_CHANGE` from the ones last handed out,
        else None. One kernel call per sampled frame, no Python allocation."""
        if self._wait:
            self._wait -= 1
            return None
        self._wait = self.sample_every - 1
        cycle, phase, step = self.update_frames, self._phase, self._step
        if phase == 0:
            self._hist.fill(0)
        sampled = K.INVALID
        if self._table_address:
            self._slot.hold(frame)
            try:
                sampled = K.sample_slice(self._table_address, step * phase, step * cycle, step)
            finally:
                self._slot.release()
        if sampled == K.INVALID:  # not of the size the table was made for: as an argument
            K.sample_gradient_histogram(frame, self._weights, step * phase, step * cycle, step, self._work, self._hist)
        self._phase = phase = phase + 1
        if phase < cycle:
            return None
        self._phase = 0
        # The histogram through the table too where it can (an array argument costs a MemInfo of Python allocation).
        median = float(
            K.sample_median(self._table_address) if self._table_address else K.histogram_median(self._hist_ro)
        )
        if median < 0.0 or self._level is None:
            return None
        self._level += FOLLOW_WEIGHT * (median - self._level)
        low, high = self._from_level(self._level)
        used = self.used
        if (
            used is not None
            and abs(low - used[0]) <= FOLLOW_CHANGE * used[0]
            and (abs(high - used[1]) <= FOLLOW_CHANGE * used[1])
        ):
            return None
        self.used = (low, high)
        return self.used

    @property
    def noise(self) -> float | None:
        """The noise level: the mean of the measured medians, then followed (None before the first frame)."""
        if self._level is not None:
            return self._level
        return float(np.mean(self._medians)) if self._medians else None


def _clamp(value: float, floor: float, ceiling: float) -> float:
    """``min(max(value, floor), ceiling)`` by comparisons: `min` and `max` of two values make an iterator of their
    arguments (48 bytes of Python allocation, on the steady frame that ends a followed-threshold cycle)."""
    value = floor if floor > value else value
    return ceiling if ceiling < value else value
