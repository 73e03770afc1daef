"""StaticMask: the static structures of the view (clamp, rod, plate edge, brackets, scratches, dust), learned over
the first frames and optionally given as a mask image, whose edges the contour stage drops."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import as_ro
from ropecam.device.pipeline.edges import EdgeDetector
from ropecam.device.pipeline.structure import grow
from ropecam.device.pipeline.workspace import EdgeBuffers

if TYPE_CHECKING:
    from ropecam.device.pipeline.config import PipelineConfig

__all__ = ["StaticMask"]

EARLY_FRAMES = 2
"""Frames learned before the still structures are looked at early (`StaticMask.early`), when the stream's first
outline showed none."""
_SAMPLE_STEP = 7
"""Pixel step of the subsample whose median learned range is the noise level (one pixel in 49)."""


class StaticMask:
    """Learn each pixel's range of grey levels over the first `frames` frames and mark the pixels that stay
    within the noise and lie on a structure as static; the edge stage then drops their edges while the frame
    there looks as learned (`drop_static_edges`). A given `mask` (True: never the rope) is applied from the
    first frame.

    A structure is where the edge detector, at the pipeline's thresholds, finds an edge in the learned scene
    (the middle of each pixel's range), grown by a pixel: the clamp, its rod, a plate edge, a scratch, a static
    cable. The plain plate around them stays free, so that the mask marks only what can hide or join the rope
    (the ``tip_masked`` self-check reads it: a flat plate marked static would end every free tip "at the mask").

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
    detector
        The pipeline's edge detector: its smoothing and its thresholds when the learning ends find the
        structures (None: every still pixel is static).
    """

    def __init__(
        self,
        buffers: EdgeBuffers,
        frames: int,
        margin_dn: int,
        relative: float,
        mask: NDArray[np.bool_] | None = None,
        detector: EdgeDetector | None = None,
        smooth_sigma_px: float = 1.0,
    ) -> None:
        if frames < 0:
            raise ValueError(f"frames must be >= 0, got {frames}")
        if not 0 <= margin_dn <= 255:
            raise ValueError(f"margin_dn must be in [0, 255], got {margin_dn}")
        self.buffers = buffers
        self.frames = int(frames)
        self.margin_dn = int(margin_dn)
        self.relative = float(relative)
        self.detector = detector
        self.smooth_sigma_px = float(smooth_sigma_px)
        self.seen = 0
        """Frames learned from so far."""
        self.marked = False
        """Whether the learned mask is marked (on the frame after the learned ones)."""
        self.static_px = 0
        """Pixels marked static when the learning ended (0 before)."""
        self.base_dn = 0.0
        """The range a still pixel spans from noise alone (2 x the median learned range + 2), once learned."""
        self.structure_px = 0
        """Pixels of the structure found from the rope's first outline (`add_structure`; 0: none)."""
        self.structure_tried = False
        """Whether the stream's first outline was searched for a structure (`Stages.mask_structure`)."""
        self.first_ends: list[NDArray[np.float32]] = []
        """The two ends of the stream's first outline (`Stages.mask_structure`)."""
        self.swinging = False
        """Whether the rope swung between the stream's first two outlines (`Stages.mask_structure`)."""
        self.early_tried = False
        """Whether the still structures of the first frames were searched early (`Stages.mask_structure`)."""
        self.learned_due = False
        """Whether the learned mask was just marked and its structures are still to be searched for the one the
        rope is fixed in (`Stages.mask_structure`, on the next outline traced step by step)."""
        self._finder: EdgeDetector | None = None  # the structures' detector, made ahead by `prepare`
        self._low_ro, self._high_ro = as_ro(buffers.static_low), as_ro(buffers.static_high)  # (`shows_end`)
        buffers.static_mask[:] = K.MASK_FREE
        buffers.static_low[:] = 255
        buffers.static_high[:] = 0
        if mask is not None:
            if mask.shape != buffers.static_mask.shape:
                raise ValueError(f"mask is {mask.shape}, expected {buffers.static_mask.shape}")
            buffers.static_mask[mask] = K.MASK_ALWAYS
        self.mark_near()

    @classmethod
    def from_config(
        cls,
        buffers: EdgeBuffers,
        config: PipelineConfig,
        shape: tuple[int, int],
        detector: EdgeDetector | None = None,
    ) -> StaticMask:
        """Make the static mask of `config` (``static_mask_png``, read now, and the learning settings) for frames
        of `shape` (height, width) in the edge stage's `buffers`; `detector` finds the structures (see the
        class)."""
        given = None
        if config.static_mask_png:
            from ropecam.device.capture.mask_file import read_mask_png  # a file read once, at construction

            given = read_mask_png(config.static_mask_png, shape)
        return cls(
            buffers, config.static_frames, config.static_margin_dn, config.static_relative, given, detector,
            config.smooth_sigma_px,
        )  # fmt: skip

    def prepare(self) -> None:
        """Make the detector that finds the structures when the learning ends, and run it once on a blank frame,
        now rather than on that frame (its buffers: ~15 ms, their first whole-frame pass: ~30 ms more than a warm
        one; the daemon calls this before the camera starts, `Pipeline.warm_up`). Its results are the same."""
        if self.detector is None or not self.learning or self._finder is not None:
            return
        height, width = self.buffers.static_low.shape
        finder = self._make_finder()
        finder.detect(
            np.zeros((height, width), np.uint8), np.zeros(height, np.int32), np.full(height, width - 1, np.int32)
        )
        self._finder = finder

    def _make_finder(self) -> EdgeDetector:
        """The whole-frame detector that finds the structures, at the rope detector's thresholds."""
        d = self.detector
        assert d is not None
        height, width = self.buffers.static_low.shape
        return EdgeDetector(height, width, self.smooth_sigma_px, float(d.low), float(d.high))

    @property
    def learning(self) -> bool:
        """Whether frames are still being learned from (or the mask is still to be marked on the next frame)."""
        return self.frames > 0 and not self.marked

    def learn(self, frame: NDArray[np.uint8]) -> None:
        """Learn from one frame (a whole-frame pass: only the first `frames` frames); the frame after them marks
        the mask without being learned from. The frame that is measured first with the mask must not be in the
        learned ranges: its moving rope's faint edges (the border of the area the rope swept so far) would look
        as learned, and be dropped."""
        b = self.buffers
        if self.seen < self.frames:
            if K.learn_static_range(as_ro(frame), b.static_low, b.static_high) < 0:
                raise ValueError(f"frame is {frame.shape}, expected {b.static_low.shape}")
            self.seen += 1
            return
        if frame.shape != b.static_low.shape:
            raise ValueError(f"frame is {frame.shape}, expected {b.static_low.shape}")
        self.marked = True
        if self.seen == self.frames:
            self.learned_due = True
            self.base_dn = self._noise_dn()
            structure = self._structure(self.base_dn) if self.detector is not None else None
            self.static_px = int(
                K.mark_static(b.static_low, b.static_high, self.base_dn, self.relative, self.margin_dn, b.static_mask)
            )
            if structure is not None:
                off = (b.static_mask == K.MASK_STATIC) & ~structure
                b.static_mask[off] = K.MASK_FREE
                self.static_px -= int(off.sum())
            self.mark_near()

    def early(self) -> NDArray[np.uint8] | None:
        """Return the still structures of the frames learned so far (at least `EARLY_FRAMES`), as a mask
        (`K.MASK_STATIC` where still on a structure, as the learned mask would mark them now), or None (fewer
        frames, or no detector). The learned mask itself is not written: a rope already swinging when the stream
        starts is not still over a few frames, but its part held next to the clamp may be (`Stages.mask_structure`
        takes only a block-like structure at the rope's end from this)."""
        b = self.buffers
        if self.detector is None or self.seen < EARLY_FRAMES:
            return None
        base_dn = self._noise_dn()
        low, high = b.static_low.astype(np.int16), b.static_high.astype(np.int16)
        still = (high >= low) & (high - low <= base_dn + self.relative * high)
        early = np.full(b.static_mask.shape, K.MASK_FREE, np.uint8)
        early[still & self._structure(base_dn, keep=True)] = K.MASK_STATIC
        return early

    def _noise_dn(self) -> float:
        """The range a still pixel spans from noise alone over the frames learned so far: 2 x the median range of a
        subsample (one pixel in `_SAMPLE_STEP` squared) + 2."""
        b = self.buffers
        spread = b.static_high[::_SAMPLE_STEP, ::_SAMPLE_STEP].astype(np.int16)
        spread -= b.static_low[::_SAMPLE_STEP, ::_SAMPLE_STEP]
        return 2.0 * float(np.median(spread)) + 2.0

    def _structure(self, base_dn: float, keep: bool = False) -> NDArray[np.bool_]:
        """The pixels on or next to a static edge of the learned scene: an edge of the middle of each pixel's
        range, found by an edge detector with the pipeline's smoothing and current thresholds over the whole
        frame (once, when the learning ends), whose 3x3 neighbourhood stayed still. The border of the area the
        rope swept while the mask was learned is an edge of the middle image too, with moving pixels on one
        side: it is not a structure."""
        b, d = self.buffers, self.detector
        assert d is not None
        height, width = b.static_low.shape
        low, high = b.static_low.astype(np.int16), b.static_high.astype(np.int16)
        still = (high >= low) & (high - low <= base_dn + self.relative * high)
        middle = ((low + high) // 2).astype(np.uint8)
        finder = self._finder  # made ahead by `prepare`, or now; needed once (and by `early` before)
        self._finder = finder if keep else None
        if finder is None:
            finder = self._make_finder()
            if keep:
                self._finder = finder
        else:
            finder.set_thresholds(float(d.low), float(d.high))
        finder.detect(middle, np.zeros(height, np.int32), np.full(height, width - 1, np.int32))
        edge = (finder.edges != 0) & _spread(~still, invert=True)
        return _spread(edge)  # noise moves a static edge by a pixel now and then

    def add_structure(self, region: NDArray[np.bool_]) -> None:
        """Take the edges in `region` ((height, width) bool: a structure found from the rope's outline,
        `FixedEndFinder.structure`) out from now on, as those of a given mask (`MASK_ALWAYS`: kept after the
        learning too, see `ropecam.device.pipeline.structure`)."""
        if region.shape != self.buffers.static_mask.shape:
            raise ValueError(f"region is {region.shape}, expected {self.buffers.static_mask.shape}")
        self.buffers.static_mask[region] = K.MASK_ALWAYS
        self.structure_px = int(np.count_nonzero(region))
        self.mark_near()

    def shows_end(self, shape: NDArray[np.float32], frame: NDArray[np.uint8], width_px: float, reach_px: float) -> bool:
        """Return whether `frame` shows the free tip of `shape` ((n, 2) float32 row, col, the tip last) as the rope's
        end (`K.tip_end_seen`): the rope at the tip, and beyond it, within `reach_px` and two rope widths
        (`width_px`) more, every pixel as the learned still scene had it. False until the mask is learned (nothing
        to compare with): a ``tip_masked`` verdict then stands."""
        if not self.marked or self.frames == 0:
            return False
        if frame.shape != self.buffers.static_low.shape:
            return False
        still_dn, relative = self.still_range()
        low, high = self._low_ro, self._high_ro
        return bool(K.tip_end_seen(shape, as_ro(frame), low, high, width_px, reach_px, still_dn, relative))

    def still_range(self) -> tuple[float, float]:
        """The range a learned still pixel may span, (grey levels, part of its high level): `shows_end`'s, and
        `steady_frame`'s (its ``still_dn``, ``still_relative``). Meaningful once the mask is learned."""
        return self.base_dn + 2.0 * self.margin_dn, self.relative  # the still range, widened by the margin each side

    def mark_near(self) -> None:
        """Summarise the mask again after a write (`mark_near_blocks`: the per-frame kernels read the mask only
        in the blocks it marks). Every write of ``static_mask`` is followed by this."""
        if K.mark_near_blocks(as_ro(self.buffers.static_mask), self.buffers.static_near) < 0:
            raise ValueError(f"static_near holds {self.buffers.static_near.shape[0]} blocks, fewer than the mask's")

    def static(self) -> NDArray[np.bool_]:
        """Return the pixels whose edges are dropped (given, or learned static), True where dropped."""
        return self.buffers.static_mask != K.MASK_FREE


def _spread(pixels: NDArray[np.bool_], invert: bool = False) -> NDArray[np.bool_]:
    """`pixels` grown over their 3x3 neighbourhoods (with `invert`: the pixels whose 3x3 neighbourhood holds
    none of `pixels`)."""
    grown = grow(pixels)
    return ~grown if invert else grown
