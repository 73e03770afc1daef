"""FixedEndFinder: where the rope is fixed (row, col), configured or found over the first frames."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import i32, ro
from ropecam.device.pipeline.workspace import FixedEndBuffers

__all__ = ["FIXED_END_FRAMES", "FixedEndFinder"]

FIXED_END_FRAMES = 10
"""Frames over which a fixed end that is not configured is averaged; it does not change afterwards."""


class FixedEndFinder:
    """Find the rope's fixed end (row, col) in its first contours, or keep the configured one.

    Parameters
    ----------
    fixed_end_uv
        The configured fixed end (u, v) = (col, row) px, or None to find it.
    shape
        (height, width) of the frames.
    buffers
        The fixed end and the contour's turning angles (`FixedEndBuffers`).
    """

    def __init__(
        self, fixed_end_uv: tuple[float, float] | None, shape: tuple[int, int], buffers: FixedEndBuffers
    ) -> None:
        self.configured = fixed_end_uv is not None
        self.shape = shape
        self.buffers = buffers
        self.fixed = buffers.fixed
        """The fixed end (row, col) float32: valid once `known`."""
        self.known = self.configured
        """Whether `fixed` holds a fixed end (configured, or guessed on a first contour)."""
        self.frames = 0
        """Contours the found fixed end is averaged over."""
        self._first_ends: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None
        if fixed_end_uv is not None:
            self.fixed[:] = (fixed_end_uv[1], fixed_end_uv[0])

    def restart(self) -> None:
        """Forget a found fixed end (a configured one stays): the next contours find it again."""
        self.known = self.configured
        self.frames = 0
        self._first_ends = None

    @property
    def settled(self) -> bool:
        """Whether the fixed end no longer changes (configured, or averaged over `FIXED_END_FRAMES` contours)."""
        return self.known and (self.configured or self.frames >= FIXED_END_FRAMES)

    def find(self, points: NDArray[np.float32], n: int, width_px: float | None) -> bool:
        """Update the fixed end from a contour (`n` (row, col) `points`) of a rope `width_px` wide (None: 4 px).

        The first contour gives a guess: of the band's two ends the narrower one (the fixed end hardly moves, so
        its end of the band stays one rope wide), or on a tie (a rope at rest) the one nearer the top centre of
        the image (a pendulum hangs below its support, and a rig centres the support so the swing stays in view).
        Over the next contours the end that stays where it was is the fixed end: the guess is corrected as soon
        as one end has moved away and the other has not, and the position is averaged over those contours.

        Returns
        -------
        bool
            True when the guess was wrong and the fixed end starts again from the other end: what was measured
            relative to the wrong end (the rope width, the time order's history) is to be forgotten.
        """
        if self.settled:
            return False
        w = width_px or 4.0
        turn = self.buffers.turn
        K.turning_angles(ro(points), i32(n), i32(max(3, round(w))), turn)
        e1 = int(np.argmax(turn[:n]))
        e2 = int(np.argmax(np.hypot(points[:n, 0] - points[e1, 0], points[:n, 1] - points[e1, 1])))
        ends = [self._cap_centre(points, n, e, w) for e in (e1, e2)]
        if not self.known:
            m = max(4, round(2 * w))
            widths = [np.hypot(*(points[(e - m) % n] - points[(e + m) % n])) for e in (e1, e2)]
            if abs(widths[0] - widths[1]) <= 0.25 * min(widths):
                top_centre = np.array([0.0, 0.5 * (self.shape[1] - 1)])
                far = [float(np.hypot(*(end - top_centre))) for end in ends]
                k = 0 if far[0] <= far[1] else 1
            else:
                k = 0 if widths[0] < widths[1] else 1
            self.fixed[:] = ends[k]
            self._first_ends = (ends[k].copy(), ends[1 - k].copy())
            self.known = True
            self.frames = 1
            return False
        restarted = False
        if self._first_ends is not None and not self.configured:
            guess, other = self._first_ends
            moved_guess = min(float(np.hypot(*(end - guess))) for end in ends)
            moved_other = min(float(np.hypot(*(end - other))) for end in ends)
            if max(moved_guess, moved_other) > max(2.0 * w, 5.0) and min(moved_guess, moved_other) < w:
                self._first_ends = None  # decided
                if moved_guess > moved_other:
                    # The guessed end moved: it is the free end. Start again from the other one.
                    self.fixed[:] = other
                    self.frames = 0
                    restarted = True
        d = [float(np.hypot(*(end - self.fixed))) for end in ends]
        chosen = ends[0] if d[0] <= d[1] else ends[1]
        if min(d) > 3.0 * w + 5.0:
            return restarted  # not the rope seen so far (another object, a clipped view): no update
        k = self.frames
        self.fixed[:] = (self.fixed * k + chosen) / (k + 1)
        self.frames += 1
        return restarted

    def _cap_centre(self, points: NDArray[np.float32], n: int, e: int, w: float) -> NDArray[np.float32]:
        """The contour point in the middle of the rope end around contour index `e`: the turning-weighted centroid
        of the points within a width and a half of it, snapped to the contour (a flat end has two corners, its
        largest turning angle is at one of them)."""
        m = max(3, round(1.5 * w))
        idx = np.arange(e - m, e + m + 1) % n
        weights = self.buffers.turn[idx].astype(np.float64) ** 2
        if not weights.sum() > 0:
            return points[e].copy()
        centre = (points[idx].astype(np.float64) * weights[:, None]).sum(axis=0) / weights.sum()
        k = idx[int(np.argmin(np.hypot(points[idx, 0] - centre[0], points[idx, 1] - centre[1])))]
        return points[k].copy()
