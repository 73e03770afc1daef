"""The blur splitter's other shapes: the centreline of a rope that did not move and the comparison methods
(`SplitFallbacks`, a part of `BlurSplitter`)."""

from __future__ import annotations

import numpy as np

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import f32, i32, ro
from ropecam.device.pipeline.result import Method
from ropecam.device.pipeline.split_outcome import SplitOutcome

__all__ = ["SplitFallbacks"]


class SplitFallbacks:
    """The single-shape methods of `BlurSplitter` (they read the contour and buffers it stores)."""

    def static(self, fixed_rc: tuple[float, float] | None = None) -> SplitOutcome | None:
        """Return the centreline of a rope that did not move (or cannot be split): one side of the contour, from
        rope end to rope end, moved half a rope width into the rope along the gradient. The end nearer
        `fixed_rc` comes first. Call after `split` (or `_prepare`) on the same contour."""
        points, chain, n = self._points, self._chain, self._n
        if n < 8:
            return None
        K.turning_angles(points, n, i32(max(3, round(self.width))), self.turn)
        if K.find_caps(ro(self.turn), n, i32(max(4, n // 8)), self.idx) < 0:
            return None
        e1, e2 = np.int32(self.idx[0]), np.int32(self.idx[1])
        if fixed_rc is not None:
            d1 = np.hypot(points[e1, 0] - fixed_rc[0], points[e1, 1] - fixed_rc[1])
            d2 = np.hypot(points[e2, 0] - fixed_rc[0], points[e2, 1] - fixed_rc[1])
            if d2 < d1:
                e1, e2 = e2, e1
        w = np.float32(self.width)
        count = K.offset_by_gradient(
            points, chain, n, e1, e2, i32(1), self._gx, self._gy, self.polarity_used, w, f32(0.0), self.side_a
        )
        if count < 2:
            return None
        # The cap's edge was moved half a width back along the axis with the gradient: carry the axis on to the
        # band's end instead, as for the split shapes.
        count = self._fit_tip(self.side_a, i32(count))
        if fixed_rc is not None:
            count = self._anchor_fixed_end(self.side_a, count, fixed_rc)
        shape = self._resample(self.side_a, i32(count), self.out_a)
        self.seg[0] = points[e2]
        self.seg[1] = points[e2]
        return SplitOutcome(Method.STATIC_FALLBACK, shape, shape, None, self.width, 0.0)

    def _comparison(self, fixed_rc: tuple[float, float]) -> SplitOutcome | None:
        """The comparison methods (`centerline.py`, `paper_method.py`) on the contour stored by `_prepare`.

        ``paper`` scores the knots against the centreline's ends (Feature 3); where it finds no two segmentation
        points (slow motion: the blur is too narrow to split) it reports the centreline, as the paper does.
        """
        n = int(self._n)
        points = self._points
        dist = np.hypot(points[:n, 0] - fixed_rc[0], points[:n, 1] - fixed_rc[1])
        i_fix, i_far = int(np.argmin(dist)), int(np.argmax(dist))
        line = self.centerline.extract(points, n, i_fix, i_far)
        if line is None:
            return None
        # The band is a rope width plus the sweep wide at its widest: the sweep sizes the next frame's ROI.
        self.sweep_px = max(0.0, self.centerline.band_width_px - self.width)
        centre = SplitOutcome(Method.CENTERLINE, line, line, None, self.width, self.sweep_px)
        if self.method == "centerline":
            return centre
        e1 = (float(line[0, 0]), float(line[0, 1]))
        e2 = (float(line[-1, 0]), float(line[-1, 1]))
        found = self.paper.segment(self._chain, n, fixed_rc, e1, e2, self.centerline.band_width_px, self.width)
        if found is None:
            return centre
        self.sweep_px = found.sweep_px
        return SplitOutcome(
            Method.PAPER, found.shape_a, found.shape_b, found.segmentation_points, self.width, found.sweep_px
        )
