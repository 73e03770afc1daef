"""StaticMask: the static structures of the view (clamp, rod, plate edge, brackets, scratches, dust), learned over
the first frames and optionally given as a mask image, whose edges the contour stage drops."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import as_ro
from ropecam.device.pipeline.workspace import EdgeBuffers

if TYPE_CHECKING:
    from ropecam.device.pipeline.config import PipelineConfig

__all__ = ["StaticMask"]

_SAMPLE_STEP = 7
"""Pixel step of the subsample whose median learned range is the noise level (one pixel in 49)."""


class StaticMask:
    """Learn each pixel's range of grey levels over the first `frames` frames and mark the pixels that stay
    within the noise as static; the edge stage then drops their edges while the frame there looks as learned
    (`drop_static_edges`). A given `mask` (True: never the rope) is applied from the first frame.

    Parameters
    ----------
    buffers
        The edge stage's buffers, whose ``static_mask``, ``static_low`` and ``static_high`` this fills.
    frames
        Frames to learn from (0: no learned mask).
    margin_dn
        Grey levels allowed beyond the learned range before a pixel counts as changed.
    relative
        Part of a pixel's grey level its range may span and still be static (flicker, shot noise).
    mask
        (height, width) bool: pixels whose edges are never the rope's, or None.
    """

    def __init__(
        self,
        buffers: EdgeBuffers,
        frames: int,
        margin_dn: int,
        relative: float,
        mask: NDArray[np.bool_] | None = None,
    ) -> None:
        if frames < 0:
            raise ValueError(f"frames must be >= 0, got {frames}")
        if not 0 <= margin_dn <= 255:
            raise ValueError(f"margin_dn must be in [0, 255], got {margin_dn}")
        self.buffers = buffers
        self.frames = int(frames)
        self.margin_dn = int(margin_dn)
        self.relative = float(relative)
        self.seen = 0
        """Frames learned from so far."""
        self.static_px = 0
        """Pixels marked static when the learning ended (0 before)."""
        self.base_dn = 0.0
        """The range a still pixel spans from noise alone (2 x the median learned range + 2), once learned."""
        buffers.static_mask[:] = K.MASK_FREE
        buffers.static_low[:] = 255
        buffers.static_high[:] = 0
        if mask is not None:
            if mask.shape != buffers.static_mask.shape:
                raise ValueError(f"mask is {mask.shape}, expected {buffers.static_mask.shape}")
            buffers.static_mask[mask] = K.MASK_ALWAYS

    @classmethod
    def from_config(cls, buffers: EdgeBuffers, config: PipelineConfig, shape: tuple[int, int]) -> StaticMask:
        """Make the static mask of `config` (``static_mask_png``, read now, and the learning settings) for frames
        of `shape` (height, width) in the edge stage's `buffers`."""
        given = None
        if config.static_mask_png:
            from ropecam.device.capture.mask_file import read_mask_png  # a file read once, at construction

            given = read_mask_png(config.static_mask_png, shape)
        return cls(buffers, config.static_frames, config.static_margin_dn, config.static_relative, given)

    @property
    def learning(self) -> bool:
        """Whether frames are still being learned from."""
        return self.seen < self.frames

    def learn(self, frame: NDArray[np.uint8]) -> None:
        """Learn from one frame (a whole-frame pass: only the first `frames` frames); the last one marks the mask."""
        b = self.buffers
        if K.learn_static_range(as_ro(frame), b.static_low, b.static_high) < 0:
            raise ValueError(f"frame is {frame.shape}, expected {b.static_low.shape}")
        self.seen += 1
        if self.seen == self.frames:
            spread = b.static_high[::_SAMPLE_STEP, ::_SAMPLE_STEP].astype(np.int16)
            spread -= b.static_low[::_SAMPLE_STEP, ::_SAMPLE_STEP]
            self.base_dn = 2.0 * float(np.median(spread)) + 2.0
            self.static_px = int(
                K.mark_static(b.static_low, b.static_high, self.base_dn, self.relative, self.margin_dn, b.static_mask)
            )

    def static(self) -> NDArray[np.bool_]:
        """Return the pixels whose edges are dropped (given, or learned static), True where dropped."""
        return self.buffers.static_mask != K.MASK_FREE
