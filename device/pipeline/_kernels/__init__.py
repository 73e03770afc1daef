"""Numba kernels of the rope pipeline: Canny on row spans, component selection, contour tracing, the paper's
segmentation operator and scoring, subpixel refinement, the blur split, the band's centreline and material point
tracking.

Conventions: images are (row, col); image points are float32 (row, col) with (0, 0) the centre of the top-left
pixel; a region of interest is one column span ``[lo[r], hi[r]]`` per row (empty when ``hi[r] < lo[r]``).
Kernels never allocate: every output is passed in (``out_*``, last) and the return value is a count or a negative
`KernelStatus`.

One module per job; this package re-exports every kernel and constant so that stages use ``_kernels.NAME``.
Kernels call kernels of other modules here, which Numba's per-file cache does not track: the package's caches are
dropped whenever any of its sources changed (`ropecam.shared.jit.drop_stale_caches`).
"""

from pathlib import Path

from ropecam.shared.jit import drop_stale_caches

drop_stale_caches(Path(__file__).parent)

# ruff: noqa: E402 (the stale caches go before the kernel modules are imported)

from ropecam.device.pipeline._kernels._common import (
    DIR_COL,
    DIR_ROW,
    EDGE_NONE,
    EDGE_STRONG,
    EDGE_WEAK,
    FULL,
    INVALID,
    NOT_FOUND,
    TAN_22_5,
    TWO,
    ZERO,
    f4_1d_ro,
)
from ropecam.device.pipeline._kernels.canny import (
    detect_edges,
    finish_edges,
    grow_edges,
    grow_spans_inplace,
    grow_spans_once,
    nms_pixel,
    padded_end,
    smooth_columns,
    smooth_replicated,
    smooth_rows,
    sobel_rows,
    suppress_rows,
)
from ropecam.device.pipeline._kernels.centerline import band_sides
from ropecam.device.pipeline._kernels.contour import (
    count_border_contacts,
    count_roi_contacts,
    keep_largest_closed,
    keep_largest_component,
    keep_largest_listed,
    trace_closed,
    trace_contour,
    trace_rope,
)
from ropecam.device.pipeline._kernels.geometry import (
    axis_offset,
    chain_length,
    find_segmentation_points,
    midline,
    offset_side,
    refine_subpixel,
    sample_bilinear,
    signed_area,
    split_contour,
    turning_angles,
    turning_angles_far,
)
from ropecam.device.pipeline._kernels.offsets import (
    SPLIT_PARAMS,
    dense_end_points,
    find_caps,
    interp_sorted,
    measure_widths,
    offset_by_gradient,
    offset_by_table,
    offset_by_table_thinned,
    place_along_gradient,
    side_slope_samples,
    side_sweeps,
    slope_sweep_median,
    split_shapes_local,
    split_shapes_packed,
)
from ropecam.device.pipeline._kernels.paper import OPERATOR, apply_operator, score_knots, thin_chain
from ropecam.device.pipeline._kernels.polylines import (
    anchor_start,
    extend_to_band_end,
    half_level_crossing,
    polyline_length,
    resample_polyline,
    resample_polyline_of_length,
    track_material_points,
    track_material_points_of_length,
    trim_polyline_end,
)
from ropecam.device.pipeline._kernels.smoothing import smooth_polyline
from ropecam.device.pipeline._kernels.spans import (
    coarse_spans,
    grow_spans,
    in_spans,
    spans_around_points,
    union_spans,
)
from ropecam.device.pipeline._kernels.tracking import (
    HISTORY,
    MOTION_COUNT,
    MOTION_EXPOSURE,
    MOTION_FRAMES,
    ORDER_COUNT,
    ORDER_ORDERED,
    ORDER_REJECTS,
    observe_motion,
    order_shapes,
    predict_motion,
    predict_tips,
    remember_tips,
    shape_length,
    track_frame,
    track_shapes,
)

__all__ = [
    "DIR_COL",
    "DIR_ROW",
    "EDGE_NONE",
    "EDGE_STRONG",
    "EDGE_WEAK",
    "FULL",
    "HISTORY",
    "INVALID",
    "MOTION_COUNT",
    "MOTION_EXPOSURE",
    "MOTION_FRAMES",
    "NOT_FOUND",
    "OPERATOR",
    "ORDER_COUNT",
    "ORDER_ORDERED",
    "ORDER_REJECTS",
    "SPLIT_PARAMS",
    "TAN_22_5",
    "TWO",
    "ZERO",
    "anchor_start",
    "apply_operator",
    "axis_offset",
    "band_sides",
    "chain_length",
    "coarse_spans",
    "count_border_contacts",
    "count_roi_contacts",
    "dense_end_points",
    "detect_edges",
    "extend_to_band_end",
    "f4_1d_ro",
    "find_caps",
    "find_segmentation_points",
    "finish_edges",
    "grow_edges",
    "grow_spans",
    "grow_spans_inplace",
    "grow_spans_once",
    "half_level_crossing",
    "in_spans",
    "interp_sorted",
    "keep_largest_closed",
    "keep_largest_component",
    "keep_largest_listed",
    "measure_widths",
    "midline",
    "nms_pixel",
    "observe_motion",
    "offset_by_gradient",
    "offset_by_table",
    "offset_by_table_thinned",
    "offset_side",
    "order_shapes",
    "padded_end",
    "place_along_gradient",
    "polyline_length",
    "predict_motion",
    "predict_tips",
    "refine_subpixel",
    "remember_tips",
    "resample_polyline",
    "resample_polyline_of_length",
    "sample_bilinear",
    "score_knots",
    "shape_length",
    "side_slope_samples",
    "side_sweeps",
    "signed_area",
    "slope_sweep_median",
    "smooth_columns",
    "smooth_polyline",
    "smooth_replicated",
    "smooth_rows",
    "sobel_rows",
    "spans_around_points",
    "split_contour",
    "split_shapes_local",
    "split_shapes_packed",
    "suppress_rows",
    "thin_chain",
    "trace_closed",
    "trace_contour",
    "trace_rope",
    "track_frame",
    "track_material_points",
    "track_material_points_of_length",
    "track_shapes",
    "trim_polyline_end",
    "turning_angles",
    "turning_angles_far",
    "union_spans",
]
