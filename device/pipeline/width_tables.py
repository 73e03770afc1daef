"""The blur split's scalars and tables that depend only on the rope width (`WidthTables`), and the index of the
edge model's sweep table (`sweep_index`)."""

from __future__ import annotations

from statistics import NormalDist
from typing import TYPE_CHECKING, Final

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import f32, i32, ro

if TYPE_CHECKING:
    from ropecam.device.pipeline.split import BlurSplitter

__all__ = ["LOCAL_CONTRAST_MAX_BLUR_PX", "WidthTables", "sweep_index"]

LOCAL_CONTRAST_TAIL: Final = 0.03
"""The share of the edge's step a lens blur may put where `contrast_gains` reads the background (from
``MARGIN_PX - BACKGROUND_PX`` = 1 px outside the band's edge)."""
LOCAL_CONTRAST_MAX_BLUR_PX: Final = (K.MARGIN_PX - K.BACKGROUND_PX) / NormalDist().inv_cdf(1.0 - LOCAL_CONTRAST_TAIL)
"""The largest lens blur (the edge model's, px) with which the split reads the rope's own contrast along the band
(0.53 px): above it the blur's tail reaches the background's samples and the readings come out low (simulated, tuning
seed, 60 frames: PSF 1.2 px centreline 0.08 -> 0.30 px with the readings, PSF 2 px 0.10 -> 0.69 px and 8 % of frames
wrong while OK); the rope's contrast is then the frame's, read near the fixed end."""


class WidthTables:
    """The scalars (of the kernels' argument types) and tables of the blur split that depend only on the rope
    width (made once per width, `BlurSplitter`).

    Parameters
    ----------
    splitter
        The split's settings (`corner_scale`, `corner_rad`, `sweep_window`, `tip_cap_ratio`, `smooth_sigma`,
        `static_ratio`), its output spacing and smoothing (`axis`: `step`, `output_smoothing`) and its edge model
        (`model`).
    width
        The rope's edge spacing (px).
    """

    __slots__ = (
        "blur", "cap", "corner", "curves", "group", "keep", "min_gap", "ratios_ro", "rope_px", "scale", "search_px",
        "skip", "span", "sweep_index", "sweep_window", "sweeps_ro", "table_ro", "table_step", "tables", "width",
        "width_scalars",
    )  # fmt: skip

    def __init__(self, splitter: BlurSplitter, width: float) -> None:
        scale = max(splitter.corner_scale, round(0.5 * width))
        self.scale = i32(scale)
        self.min_gap = i32(scale + 1)
        self.search_px = max(3.0 * width, 8.0)
        self.corner = f32(splitter.corner_rad)
        self.sweep_window = i32(splitter.sweep_window)
        self.tables = splitter.model.tables(width)
        self.ratios_ro, self.sweeps_ro = ro(self.tables.peak_ratio), ro(self.tables.sweeps_px)
        self.table_ro = ro(self.tables.offset_px)
        self.table_step = f32(self.tables.sweep_step_px)
        self.width = f32(width)
        # The rope's own width for its contrast read along the band (`contrast_gains`); 0 (no reading: the frame's
        # contrast) under a lens blur above `LOCAL_CONTRAST_MAX_BLUR_PX`.
        local = splitter.model.lens_blur_px <= LOCAL_CONTRAST_MAX_BLUR_PX
        self.rope_px = float(self.tables.width_px) if local else 0.0
        self.cap = f32(splitter.tip_cap_ratio * width)
        # The corner is rounded over the edge ramp (up to a rope width) plus the smoothing on each side.
        self.skip = f32(width + 2.0 * splitter.smooth_sigma)
        self.blur = f32(max(splitter.smooth_sigma, 0.5))
        # The axis is fitted over about 20 edge points: enough to average the edge noise (the fitted line is
        # carried on ~5 px), short enough that a curled rope's bend near the tip stays far below a tenth of a
        # pixel (measured: 3 widths gave 0.17-0.34 px mean tips on rig / dark rig, 8 widths 0.12-0.25, 20 widths
        # let rig-soft's curl in, 0.27).
        self.span = f32(max(8.0 * width, 16.0))
        self.keep = i32(K.dense_end_points(self.skip, self.span))
        curves = np.stack([self.ratios_ro, self.sweeps_ro]).astype(np.float64)
        self.curves = ro(curves)
        self.sweep_index = ro(sweep_index(self.curves[0]))
        # The kernels' group of the width (`split_shapes`, `split_frame`), each scalar of the type they compute
        # with; the corner box's growth as `split` computes it.
        self.group = K.SplitWidth(
            ratios=curves[0], sweeps=curves[1], offsets=np.array(self.tables.offset_px, np.float32),
            half=self.sweep_window, step_px=self.table_step, width_px=self.width, cap_px=self.cap,
            skip_px=self.skip, span_px=self.span, blur_px=self.blur, slant_gain_px=float(self.tables.slant_px),
            width64_px=float(width), out_step_px=splitter.axis.step, smoothing_px=splitter.axis.output_smoothing,
            scale=self.scale, min_gap=self.min_gap, search_px=float(self.search_px), corner_rad=self.corner,
            grow_px=3.0 * float(self.blur) + 6.0 + width, static_ratio=float(splitter.static_ratio),
            rope_px=self.rope_px, through_fixed=float(splitter.axis.through_fixed),
        )  # fmt: skip
        # Its scalars as `steady_frame`'s table holds them (float64, exact), by name.
        self.width_scalars = ro(np.array([float(getattr(self.group, n)) for n in K.SPLIT_WIDTH_SCALARS], np.float64))


_MAX_BUCKETS = 1 << 13
"""The largest `sweep_index` (64 KB): past it the table's close ratios are walked (`side_sweeps`)."""


def sweep_index(ratios: NDArray[np.float64]) -> NDArray[np.int32]:
    """Index the sweep table's `ratios` (non-decreasing) for `side_sweeps_indexed`.

    The range of `ratios` is cut into ``nb`` equal buckets (the fewest power of two, 64 or more, for which no
    bucket holds two distinct ratios), a value's bucket computed as the kernel computes it, ``int(clip((x -
    ratios[0]) * scale, 0, nb - 1))`` with ``scale = nb / (ratios[-1] - ratios[0])`` (the same float64
    operations, so the same buckets). For bucket b, ``index[2 b]`` is the number of ratios in lower buckets less
    one (at least 0), ``index[2 b + 1]`` the index of the last ratio in it or below (at most ``len(ratios) - 2``).

    Parameters
    ----------
    ratios
        (m,) float64: the edge model's ratios (`EdgeTables.peak_ratio`).

    Returns
    -------
    NDArray[np.int32]
        (2 nb,) the index, or (0,) when none fits `_MAX_BUCKETS` (fewer than two ratios, a flat or non-finite
        table, ratios too close): the kernels then walk the table.
    """
    r = np.ascontiguousarray(ratios, np.float64)
    m = r.shape[0]
    if m < 2 or not np.all(np.isfinite(r)) or not r[m - 1] > r[0] or np.any(np.diff(r) < 0.0):
        return np.zeros(0, np.int32)
    buckets = 64
    while buckets <= _MAX_BUCKETS:
        scale = buckets / (r[m - 1] - r[0])
        where = (r - r[0]) * scale
        keys = np.where(where < buckets - 1.0, np.where(where > 0.0, where, 0.0), buckets - 1.0).astype(np.int64)
        if not np.any((keys[1:] == keys[:-1]) & (r[1:] != r[:-1])):
            grid = np.arange(buckets)
            index = np.empty(2 * buckets, np.int32)
            index[0::2] = np.maximum(np.searchsorted(keys, grid, side="left") - 1, 0)
            index[1::2] = np.minimum(np.searchsorted(keys, grid, side="right") - 1, m - 2)
            return index
        buckets *= 2
    return np.zeros(0, np.int32)
