"""EdgeDetector: Canny edges of a frame inside a region of interest given as row spans."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import as_ro, cell_property, ro
from ropecam.device.pipeline.workspace import EdgeBuffers, expose

__all__ = ["EdgeDetector", "gaussian_weights"]


def gaussian_weights(sigma_px: float) -> NDArray[np.float32]:
    """Return the normalised 1-D Gaussian of standard deviation `sigma_px` (radius ceil(2 sigma)); ``[1]`` for 0."""
    if sigma_px <= 0:
        return np.ones(1, np.float32)
    radius = max(1, math.ceil(2.0 * sigma_px))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    w = np.exp(-0.5 * (x / sigma_px) ** 2)
    return (w / w.sum()).astype(np.float32)


@expose("buffers", EdgeBuffers)
class EdgeDetector:
    """Canny edge detection (Gaussian, Sobel, non-maximum suppression, hysteresis) with buffers owned per image size.

    Parameters
    ----------
    height, width
        Image size in pixels.
    smooth_sigma_px
        Gaussian smoothing (0: none, then the edges equal ``cv2.Canny(frame, low, high, L2gradient=True)``).
    low, high
        Hysteresis thresholds on the L2 Sobel magnitude.
    """

    def __init__(
        self,
        height: int,
        width: int,
        smooth_sigma_px: float,
        low: float,
        high: float,
        buffers: EdgeBuffers | None = None,
    ) -> None:
        if height < 3 or width < 3:
            raise ValueError(f"image must be at least 3x3 pixels, got {width}x{height}")
        if not 0 < low <= high:
            raise ValueError(f"need 0 < low <= high, got low={low}, high={high}")
        self.shape = (height, width)
        self.low = np.float32(low)
        self.high = np.float32(high)
        if buffers is None:
            buffers = EdgeBuffers.make(height, width, gaussian_weights(smooth_sigma_px))
        elif buffers.edges.shape != self.shape:
            raise ValueError(f"buffers are for {buffers.edges.shape} images, expected {self.shape}")
        self.buffers = buffers
        """The planes, edge map and list, spans (`EdgeBuffers`; each also a read-only attribute: ``self.gx``)."""
        self._own_counts = np.zeros(4, np.int32)
        self.counts = self._own_counts
        """The cells whose ``[3]`` is `count`: this detector's own after `detect`, the contour tracer's after a
        `detect_and_trace` call, which writes it there (`ContourTracer.adopt`)."""
        self.count = 0
        # Read-only views made once: a view per kernel call costs microseconds of Python.
        self.weights_ro = self.weights
        self.edges_ro, self.mag_ro, self.gx_ro, self.gy_ro = (ro(a) for a in (self.edges, self.mag, self.gx, self.gy))
        self.stack_ro = ro(self.stack)
        self.static_mask_ro, self.static_low_ro, self.static_high_ro = (
            ro(a) for a in (self.static_mask, self.static_low, self.static_high)
        )
        self.full_lo_ro, self.full_hi_ro = ro(self.full_lo), ro(self.full_hi)
        self.spans: tuple[NDArray[np.int32], NDArray[np.int32]] = (
            ro(np.ones(height, np.int32)), ro(np.zeros(height, np.int32))
        )  # fmt: skip
        """The row spans (lo, hi) of the last `detect` (read-only views; none before the first)."""
        self.frame: NDArray[np.uint8] = self.edges
        """The frame of the last `detect` (what `refresh` smooths)."""

    count = cell_property(
        "counts",
        3,
        "Edge pixels found by the last detection; their flat indices are ``stack[:count]`` (the strong "
        "pixels in raster order, then the weak pixels joined to them).",
    )

    def set_thresholds(self, low: float, high: float) -> None:
        """Set the hysteresis thresholds (``0 < low <= high``); the stages that pass them to a kernel made once
        (`ContourTracer.detect_args`, `SteadyFrame.args`) must make it again."""
        if not 0 < low <= high:
            raise ValueError(f"need 0 < low <= high, got low={low}, high={high}")
        self.low = np.float32(low)
        self.high = np.float32(high)

    def detect(self, frame: NDArray[np.uint8], lo: NDArray[np.int32], hi: NDArray[np.int32]) -> int:
        """Detect edges of `frame` inside the row spans `lo`/`hi`; returns the number of edge pixels.

        Parameters
        ----------
        frame
            (height, width) uint8, C-contiguous.
        lo, hi
            (height,) int32 first and last column of each row to process (empty when ``hi < lo``).

        Returns
        -------
        int
            Edge pixel count; the edge map is `edges` (1 = edge, valid inside the spans until the next call),
            gradients `gx`, `gy`, `mag`; ``stack[:count]`` lists the edge pixels (flat indices, not sorted).

        Raises
        ------
        ValueError
            Wrong shape, dtype or layout.
        """
        if frame.shape != self.shape or frame.dtype != np.uint8 or not frame.flags.c_contiguous:
            raise ValueError(f"frame must be C-contiguous uint8 of shape {self.shape}, got {frame.dtype} {frame.shape}")
        if lo.shape != (self.shape[0],) or hi.shape != (self.shape[0],) or lo.dtype != np.int32:
            raise ValueError(f"lo/hi must be int32 of shape ({self.shape[0]},)")
        lo, hi = as_ro(lo), as_ro(hi)
        self.spans = (lo, hi)
        self.frame = frame
        count = K.detect_edges(
            as_ro(frame), self.weights_ro, lo, hi, self.low, self.high, self.work_spans, self.tmp,
            self.smooth, self.gx, self.gy, self.mag, self.edges, self.stack,
        )  # fmt: skip
        if count < 0:
            raise RuntimeError(f"detect_edges returned status {count}")
        self.counts = self._own_counts
        self.count = int(count)
        return int(count)

    def smooth_box(self, frame: NDArray[np.uint8], r0: int, r1: int, c0: int, c1: int) -> int:
        """Make `smooth` hold this frame's smoothed image over rows `r0`..`r1` and columns `c0`..`c1` (inclusive,
        inside the image); returns the pixels smoothed (0 when the last `detect`'s spans covered the box).

        `detect` writes its planes inside its spans only; outside, `smooth` holds what earlier bands left there.
        Readers of the smoothed image just beyond the band (the contrast across it, the background past the tip)
        call this first: rows the spans cover keep their values, the box is smoothed again otherwise (the same
        kernels and arithmetic as `detect`). `frame` must be the one `detect` last saw.
        """
        lo, hi = self.spans
        return K.smooth_box(
            frame, self.weights_ro, lo, hi, r0, r1, c0, c1, self.box_lo, self.box_hi, self.tmp, self.smooth
        )

    def refresh(self, r0: int, r1: int, c0: int, c1: int) -> int:
        """`smooth_box` of the frame the last `detect` saw (`frame`): a bound method made once serves every frame
        (a `functools.partial` per frame costs ~1 us)."""
        lo, hi = self.spans
        return K.smooth_box(
            self.frame, self.weights_ro, lo, hi, r0, r1, c0, c1, self.box_lo, self.box_hi, self.tmp, self.smooth
        )
