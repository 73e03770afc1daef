"""CenterlineExtractor: the centreline of the blurred band (the paper's comparison method, ``method = "centerline"``).

The closed contour is cut into its two sides at the fixed end and at the middle of the band's far end, the point
halfway round the contour (`band_sides`: each side is the rope's edge at one instant plus half of the tip's
track, so both are equally long; the search keeps to the far end of the band). Each point of one side is paired
with the point at the same fraction of the other side's length (`midline`) and the midpoints, resampled, are the
centreline. Where the rope moved, this line runs down the middle of the blurred band, not along the rope at either
instant, and its end sits in the middle of the tip's track, half the tip's sweep from both true tips: the error
the paper's segmentation removes (its Fig. 9-11).
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import f32, i32, ro

__all__ = ["END_ZONE_PX", "END_ZONE_RATIO", "CenterlineExtractor"]

END_ZONE_RATIO: Final = 0.2
"""The band's free end is searched among the contour points at least ``R_far - zone`` from the fixed end, with
zone = max(`END_ZONE_PX`, `END_ZONE_RATIO` R_far) (R_far: the far point's distance). The tip's track is about
R_far from the fixed end everywhere (a rotation about it); the zone only keeps the cut at the far end when one
side of the contour is much longer than the other (a fringe or the image border on one side)."""
END_ZONE_PX: Final = 12.0


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
        # Each side holds up to n + 1 contour points and the interpolated free end.
        self.side_a = np.zeros((capacity + 2, 2), np.float32)
        self.side_b = np.zeros((capacity + 2, 2), np.float32)
        self.mid = np.zeros((capacity + 2, 2), np.float32)
        self.dist = np.zeros(capacity + 2, np.float32)
        self.out = np.zeros((capacity + 2, 2), np.float32)
        self._side_a_ro, self._side_b_ro, self._mid_ro = ro(self.side_a), ro(self.side_b), ro(self.mid)
        self.count = 0
        self.band_width_px = float("nan")

    def extract(self, points: NDArray[np.float32], n: int, i_fix: int, i_far: int) -> NDArray[np.float32] | None:
        """Return the centreline from the fixed end to the middle of the band's far end.

        Parameters
        ----------
        points
            (capacity, 2) float32 (row, col) closed contour; the first `n` points are used (read only).
        n
            Number of contour points.
        i_fix, i_far
            Contour indices of the fixed end and of the band's far point (the contour point farthest from the
            fixed end: where the search for the middle of the band's far end starts).

        Returns
        -------
        ndarray or None
            (k, 2) float32 (row, col) polyline at `output_step_px` spacing, fixed end first, ending in the middle
            of the band's far end (a view into this stage's buffer, valid until the next call); None when the
            contour is too short or has no far end. `band_width_px` is then the widest distance between the two
            sides (px): rope width plus sweep.

        Raises
        ------
        ValueError
            When `n` exceeds the capacity given to the constructor.
        """
        self.count = 0
        self.band_width_px = float("nan")
        if n > self.side_a.shape[0] - 2:
            raise ValueError(f"n must be <= capacity {self.side_a.shape[0] - 2} contour points, got {n}")
        if n < 8 or not (0 <= i_fix < n and 0 <= i_far < n) or i_fix == i_far:
            return None
        pts = ro(points)
        reach = float(np.hypot(*(points[i_far] - points[i_fix])))
        zone = f32(max(END_ZONE_PX, END_ZONE_RATIO * reach))
        na = K.band_sides(pts, i32(n), i32(i_fix), i32(i_far), zone, self.side_a, self.side_b)
        if na < 3 or n + 3 - na < 3:
            return None
        nb = n + 3 - na
        # Pair from the side with more points: the midline is then at least as dense as the denser side.
        a, b, n_a, n_b = (
            (self._side_a_ro, self._side_b_ro, na, nb) if na >= nb else (self._side_b_ro, self._side_a_ro, nb, na)
        )
        nm = K.midline(a, i32(n_a), b, i32(n_b), self.mid, self.dist)
        if nm < 2:
            return None
        self.band_width_px = float(self.dist[:nm].max())
        count = K.resample_polyline(self._mid_ro, i32(nm), self.step, self.out)
        if count < 2:
            return None
        self.count = int(count)
        return self.out[:count]
