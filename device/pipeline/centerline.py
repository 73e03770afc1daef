"""CenterlineExtractor: the centreline of the blurred band (the paper's comparison method, ``method = "centerline"``).

The closed contour is cut at the fixed end and at the band's far end (the contour point farthest from the fixed
end); the two sides run from the fixed end to the far end and the centreline is the midpoint of each point of one
side and its nearest point on the other. Where the rope moved, this line runs down the middle of the blurred band,
not along the rope at either instant, and its end sits in the middle of the tip's track: the error the paper's
segmentation removes (its Fig. 9-11).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import f32, i32, ro

__all__ = ["CenterlineExtractor"]


class CenterlineExtractor:
    """Extract the centreline of a blurred rope band from its closed subpixel contour.

    Parameters
    ----------
    capacity
        Maximum number of contour points.
    output_step_px
        Spacing of the returned polyline (px).
    """

    def __init__(self, capacity: int, output_step_px: float = 2.0) -> None:
        if capacity < 8:
            raise ValueError(f"capacity must be >= 8 contour points, got {capacity}")
        if not output_step_px > 0:
            raise ValueError(f"output_step_px must be > 0, got {output_step_px}")
        self.step = f32(output_step_px)
        self.side_a = np.zeros((capacity, 2), np.float32)
        self.side_b = np.zeros((capacity, 2), np.float32)
        self.mid = np.zeros((capacity, 2), np.float32)
        self.dist = np.zeros(capacity, np.float32)
        self.out = np.zeros((capacity, 2), np.float32)
        self.count = 0
        self.band_width_px = float("nan")

    def extract(self, points: NDArray[np.float32], n: int, i_fix: int, i_far: int) -> NDArray[np.float32] | None:
        """Return the centreline from the fixed end to the far end of the band.

        Parameters
        ----------
        points
            (capacity, 2) float32 (row, col) closed contour; the first `n` points are used (read only).
        n
            Number of contour points.
        i_fix, i_far
            Contour indices of the fixed end and of the band's far end.

        Returns
        -------
        ndarray or None
            (k, 2) float32 (row, col) polyline at `output_step_px` spacing, fixed end first, ending at the far end
            of the band (a view into this stage's buffer, valid until the next call); None when the contour is too
            short. `band_width_px` is then the widest distance between the two sides (px): rope width plus sweep.
        """
        self.count = 0
        self.band_width_px = float("nan")
        if n < 8 or not (0 <= i_fix < n and 0 <= i_far < n) or i_fix == i_far:
            return None
        pts = ro(points)
        zero = f32(0.0)
        na = K.offset_side(pts, i32(n), i32(i_fix), i32(i_far), i32(1), f32(1.0), zero, zero, i32(2), self.side_a)
        nb = K.offset_side(pts, i32(n), i32(i_fix), i32(i_far), i32(-1), f32(1.0), zero, zero, i32(2), self.side_b)
        if na < 2 or nb < 2:
            return None
        # Pair from the longer side: every point of the shorter side then has a partner.
        a, b, n_a, n_b = (self.side_a, self.side_b, na, nb) if na >= nb else (self.side_b, self.side_a, nb, na)
        nm = K.midline(ro(a), i32(n_a), ro(b), i32(n_b), self.mid, self.dist)
        if nm < 2:
            return None
        self.band_width_px = float(self.dist[:nm].max())
        count = K.resample_polyline(ro(self.mid), i32(nm), self.step, self.out)
        if count < 2:
            return None
        self.count = int(count)
        return self.out[:count]
