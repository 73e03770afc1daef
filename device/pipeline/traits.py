"""RopeTraits: what does not change between frames (the rope's width, its polarity, the fixed end), configured or
learned over the first frames."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.fixed_end import FixedEndFinder
from ropecam.device.pipeline.workspace import FixedEndBuffers

__all__ = ["POLARITY_FRAMES", "WIDTH_FRAMES", "RopeTraits", "Settled"]

WIDTH_FRAMES = 15
"""Frames whose measured rope width (median) is used afterwards, when the config gives none."""
POLARITY_FRAMES = 5
"""Frames whose polarity votes decide the polarity afterwards, when the config says auto."""


class Settled(NamedTuple):
    """The traits once none of them changes any more."""

    width_px: float | None
    """The rope's edge spacing (px; None when neither configured nor measured)."""
    fixed_rc: tuple[float, float]
    """The fixed end (row, col)."""
    exclude_px: float
    """Border contacts nearer the fixed end than this do not mean a clipped rope."""
    polarity: float
    """+1 bright rope, -1 dark rope."""


class RopeTraits:
    """The rope's width, polarity and fixed end: configured, or learned over the first frames, then `settled`.

    Parameters
    ----------
    config
        The pipeline's settings (`rope_width_px`, `polarity`, `fixed_end_uv`).
    shape
        (height, width) of the frames.
    buffers
        The fixed end's buffers (`FixedEndBuffers`).
    edge_spacing
        The spacing of a still rope's blurred edges for a rope width (px -> px; `BandEdgeModel.edge_spacing`).
    """

    def __init__(
        self,
        config: PipelineConfig,
        shape: tuple[int, int],
        buffers: FixedEndBuffers,
        edge_spacing: Callable[[float], float],
    ) -> None:
        self.fixed_end = FixedEndFinder(config.fixed_end_uv, shape, buffers)
        self._rope_width_px = config.rope_width_px
        self._edge_spacing = edge_spacing
        self._widths: list[float] = []
        self._width_cache: float | None = None
        self._polarity = {"auto": 0.0, "bright": 1.0, "dark": -1.0}[config.polarity]
        self._polarity_votes: list[float] = []
        self.settled: Settled | None = None
        """The traits once none of them changes any more (None before)."""

    def restart(self) -> None:
        """Forget what the first frames taught (found fixed end, widths, polarity votes; configured values stay):
        they were measured on contours the static mask did not yet clean."""
        self.fixed_end.restart()
        self._widths.clear()
        self._width_cache = None
        self._polarity_votes.clear()
        self.settled = None

    @property
    def measuring_width(self) -> bool:
        """Whether the split is to measure the rope's width on this frame (not configured, not enough seen)."""
        return self._rope_width_px is None and len(self._widths) < WIDTH_FRAMES

    def find_fixed_end(self, points: NDArray[np.float32], n: int, width_px: float | None) -> bool:
        """Update the fixed end (``fixed_end.fixed``) from a contour (`FixedEndFinder.find`); a wrong first guess
        also forgets the widths measured relative to it. Returns whether the guess was corrected (the caller
        forgets what else it measured relative to it)."""
        restarted = self.fixed_end.find(points, n, width_px)
        if restarted:
            self._widths.clear()
            self._width_cache = None
        return restarted

    def learn(self, measured: bool, width_measured: float, polarity_used: float) -> None:
        """Keep a frame's width (when `measured`) and polarity readings; once the width, the fixed end and the
        polarity are all settled (they do not change afterwards), keep them (`settled`)."""
        if measured and math.isfinite(width_measured) and width_measured > 0:
            self._widths.append(width_measured)
            self._width_cache = None
        if self._polarity == 0.0 and len(self._polarity_votes) < POLARITY_FRAMES:
            self._polarity_votes.append(float(polarity_used))
        width_settled = self._rope_width_px is not None or len(self._widths) >= WIDTH_FRAMES
        polarity_settled = self._polarity != 0.0 or len(self._polarity_votes) >= POLARITY_FRAMES
        if self.fixed_end.settled and width_settled and polarity_settled:
            width_px = self.width()
            fixed = self.fixed_end.fixed
            fixed_rc = (float(fixed[0]), float(fixed[1]))
            self.settled = Settled(width_px, fixed_rc, 3.0 * (width_px or 4.0) + 10.0, self.polarity())

    def polarity(self) -> float:
        """The configured polarity, or the majority of the first frames' once they are in (0 = decide now)."""
        if self._polarity != 0.0 or len(self._polarity_votes) < POLARITY_FRAMES:
            return self._polarity
        return 1.0 if sum(self._polarity_votes) >= 0 else -1.0

    def width(self) -> float | None:
        """The rope's edge spacing (px): from the configured width, or the first frames' measurements (None
        before the first)."""
        if self._rope_width_px is not None:
            # The configured width is the rope's; the splitter works with the spacing its blurred edges show.
            if self._width_cache is None:
                self._width_cache = self._edge_spacing(self._rope_width_px)
            return self._width_cache
        if self._widths and self._width_cache is None:
            # Motion only widens the band: the lower quartile of the first frames' spacings is the still rope's.
            self._width_cache = float(np.percentile(self._widths, 25))
        return self._width_cache
