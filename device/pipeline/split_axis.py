"""AxisPolylines: the polylines the blur split returns, finished (tip carried to the band's end, start anchored at
the fixed end, resampled and smoothed), and the centreline of a rope that did not move."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import f32, i32, ro
from ropecam.device.pipeline.result import Method, SplitOutcome
from ropecam.device.pipeline.width_tables import WidthTables
from ropecam.device.pipeline.workspace import SplitBuffers

__all__ = ["AxisPolylines"]

_F32_ZERO = np.float32(0.0)


_VIEW_BLOCK = 16
"""Fewest counts on each side of a count without a view whose views `AxisPolylines.shape` makes with it."""


class AxisPolylines:
    """Finish the axis polylines of `BlurSplitter`'s step-by-step split (side A / side B into out A / out B) and
    make its centreline fallback (`centreline`).

    Owns the output spacing and smoothing and the views of the split's sides (`SplitBuffers.sides`), each made
    once.

    Parameters
    ----------
    buffers
        The split's buffers (the sides, the arc scratch, the turning angles, the indices, the segmentation points).
    output_step_px
        Spacing of the returned polylines.
    output_smoothing_px
        Half-width along the rope of the smoothing of the returned polylines (0: none).
    smooth_sigma_px
        The edge detector's Gaussian smoothing (the fixed end's rounded corners reach a width plus twice it).
    """

    def __init__(
        self, buffers: SplitBuffers, output_step_px: float, output_smoothing_px: float, smooth_sigma_px: float
    ) -> None:
        self.buffers = buffers
        self.step = np.float32(output_step_px)
        self.output_smoothing = np.float32(output_smoothing_px)
        self.smooth_sigma = float(smooth_sigma_px)
        self.through_fixed = False
        """Whether the fixed end is given (a plane calibration, ``fixed_end_uv``), not found: the polylines then start
        at it (`anchor_fixed_end`, `static_shape`), not at the foot of the rope's end there (`Stages` sets it)."""
        sides = buffers.sides
        self.side_a, self.side_b, self.out_a, self.out_b = sides[0], sides[1], sides[2], sides[3]
        # Read-only views made once (a view costs 1-2 us of Python).
        self._side_a_ro, self._side_b_ro = ro(self.side_a), ro(self.side_b)
        self._out_a_ro, self._out_b_ro = ro(self.out_a), ro(self.out_b)
        self._shape_views: tuple[dict[float, NDArray[np.float32]], ...] = ({}, {}, {}, {})
        """Views of the first n points of `side_a`, `side_b`, `out_a`, `out_b` by n, made once, in blocks: a steady
        frame then makes no array object for its shapes (`shape`)."""

    def shape(self, row: int, count: float) -> NDArray[np.float32]:
        """The first `count` points of ``sides[row]`` (0: `side_a`, 1: `side_b`, 2: `out_a`, 3: `out_b`). `count`
        may be the float a kernel wrote (a whole number: it finds the view made for the int, without making one).
        A count without a view makes the views of every count within an eighth of it (at least `_VIEW_BLOCK`) on
        the four rows: a rope's shapes keep their point counts within a few percent (`lab`, 60 frames: 202-206), so
        the next frames' counts find theirs."""
        view = self._shape_views[row].get(count)
        if view is None:
            n = int(count)
            reach = max(_VIEW_BLOCK, n // 8)
            for views, side in zip(self._shape_views, self.buffers.sides, strict=True):
                for k in range(max(0, n - reach), min(n + reach, len(side)) + 1):
                    if k not in views:
                        views[k] = side[:k]
            view = self._shape_views[row][n]
        return view

    def anchor_fixed_end(
        self, poly: NDArray[np.float32], n: np.int32, fixed_rc: tuple[float, float], width_px: float
    ) -> np.int32:
        """Start an axis polyline at the fixed end: the inward offset moved the end cap's contour points along
        the rope (0.8 px into it on the rig), so the polyline is started at the foot of the fixed end (the cap's
        centre, on its edge) on the axis fitted just beyond the cap's rounded corners (`anchor_start`); the rope's
        edge spacing is `width_px`. With `through_fixed` (a fixed end given, not found) the polyline starts at the
        fixed end itself."""
        skip = f32(width_px + 2.0 * self.smooth_sigma)
        span = f32(max(8.0 * width_px, 16.0))
        through = i32(1 if self.through_fixed else 0)
        return i32(K.anchor_start(poly, n, f32(fixed_rc[0]), f32(fixed_rc[1]), skip, span, through))

    def fit_tip(
        self,
        poly: NDArray[np.float32],
        n: int,
        points: NDArray[np.float32],
        n_points: np.int32,
        smooth: NDArray[np.float32],
        tables: WidthTables,
        seg_a: int,
        seg_b: int,
    ) -> int:
        """Put the free end of an axis polyline where the band ends along that axis, less the cap.

        The segmentation point is only as good as the corner of the band, which the smoothing rounds over a few
        pixels: the axis is fitted on the straight side before the corner and carried on to where the band ends
        along it (`extend_to_band_end`, among the contour's `n_points` `points`, on the read-only smoothed image
        `smooth`, with the width's `tables`; the segmentation points ``points[seg_a]``, ``points[seg_b]`` say how
        far the band's far end sweeps across the axis).
        """
        c = tables
        gap_r = points[seg_b, 0] - points[seg_a, 0]
        gap_c = points[seg_b, 1] - points[seg_a, 1]
        return K.extend_to_band_end(
            poly, np.int32(n), points, n_points, smooth, c.width, c.cap, c.skip, c.span, c.blur, gap_r, gap_c
        )

    def resample(self, side: int, n: int, length_px: float) -> NDArray[np.float32]:
        """Resample the first `n` points of side A (`side` 0) or B (1), `length_px` long (`polyline_length` of
        them), at the output step into out A or B, then smooth them across the rope (`smooth_polyline`, with the
        side as scratch: it is overwritten); return the view holding the result."""
        if side == 0:
            poly, out, poly_ro, out_ro = self.side_a, self.out_a, self._side_a_ro, self._out_a_ro
        else:
            poly, out, poly_ro, out_ro = self.side_b, self.out_b, self._side_b_ro, self._out_b_ro
        count = K.resample_polyline_of_length(poly_ro, np.int32(n), length_px, self.step, out)
        if count < 0:
            raise RuntimeError(f"resample_polyline_of_length returned status {count}")
        if self.output_smoothing > 0.0 and count >= 3:
            # After resampling: a quarter of the work of smoothing the dense sides, and as the points only move
            # sideways (by ~0.1 px) their spacing along the rope stays equal to a few thousandths of a pixel.
            K.smooth_polyline(out_ro, np.int32(count), self.output_smoothing, self.buffers.scratch[0], poly)
            return poly[:count]  # the smoothed points (valid until the next split, as `out`)
        return out[:count]

    def centreline(
        self,
        points: NDArray[np.float32],
        chain: NDArray[np.int32],
        n: np.int32,
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        polarity: np.float32,
        width_px: float,
        fixed_rc: tuple[float, float] | None,
        smooth: NDArray[np.float32],
        tables_of: Callable[[float], WidthTables],
    ) -> SplitOutcome | None:
        """Return the centreline of a rope that did not move (or cannot be split): one side of the closed contour
        (`n` read-only `points`, `chain`, on the read-only planes `gx`, `gy`, `smooth`), from rope end to rope
        end, moved half the edge spacing `width_px` into the rope along `polarity` times the gradient. The end
        nearer `fixed_rc` comes first; `tables_of` gives the width's tables (for the tip fit)."""
        if fixed_rc is None:
            fixed, fixed_r, fixed_c = False, _F32_ZERO, _F32_ZERO
        else:
            fixed, fixed_r, fixed_c = True, f32(fixed_rc[0]), f32(fixed_rc[1])
        count = K.static_shape(
            points, chain, n, gx, gy, smooth, polarity, tables_of(width_px).group, fixed, fixed_r, fixed_c,
            self.buffers.group,
        )  # fmt: skip
        if count == K.NOT_FOUND:
            return None
        if count < 0:
            raise RuntimeError(f"resample_polyline returned status {count}")
        shape = self.shape(0 if self.buffers.info[4] else 2, count)
        return SplitOutcome(Method.STATIC_FALLBACK, shape, shape, None, width_px, 0.0)
