"""Numba kernels of the rope pipeline: Canny on row spans, component selection, contour tracing, the paper's
segmentation operator and scoring, subpixel refinement, the blur split and material point tracking.

Conventions: images are (row, col); image points are float32 (row, col) with (0, 0) the centre of the top-left
pixel; a region of interest is one column span ``[lo[r], hi[r]]`` per row (empty when ``hi[r] < lo[r]``).
Kernels never allocate: every output is passed in (``out_*``, last) and the return value is a count or a negative
`KernelStatus`.

One module per job; this package re-exports every kernel and constant so that stages use ``_kernels.NAME``.
"""

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
from ropecam.device.pipeline._kernels.canny import detect_edges
from ropecam.device.pipeline._kernels.contour import (
    count_border_contacts,
    count_roi_contacts,
    keep_largest_component,
    keep_largest_listed,
    trace_contour,
)
from ropecam.device.pipeline._kernels.geometry import (
    axis_offset,
    chain_length,
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
    find_caps,
    interp_sorted,
    measure_widths,
    offset_by_gradient,
    offset_by_table,
    side_slope_samples,
    side_sweeps,
    slope_sweep_median,
    split_shapes_local,
)
from ropecam.device.pipeline._kernels.paper import OPERATOR, apply_operator, score_knots, thin_chain
from ropecam.device.pipeline._kernels.polylines import (
    extend_to_band_end,
    half_level_crossing,
    polyline_length,
    resample_polyline,
    resample_polyline_of_length,
    smooth_polyline,
    track_material_points,
    track_material_points_of_length,
    trim_polyline_end,
)
from ropecam.device.pipeline._kernels.spans import (
    coarse_spans,
    grow_spans,
    in_spans,
    spans_around_points,
    union_spans,
)

__all__ = [
    "DIR_COL",
    "DIR_ROW",
    "EDGE_NONE",
    "EDGE_STRONG",
    "EDGE_WEAK",
    "FULL",
    "INVALID",
    "NOT_FOUND",
    "OPERATOR",
    "TAN_22_5",
    "TWO",
    "ZERO",
    "apply_operator",
    "axis_offset",
    "chain_length",
    "coarse_spans",
    "count_border_contacts",
    "count_roi_contacts",
    "detect_edges",
    "extend_to_band_end",
    "f4_1d_ro",
    "find_caps",
    "grow_spans",
    "half_level_crossing",
    "in_spans",
    "interp_sorted",
    "keep_largest_component",
    "keep_largest_listed",
    "measure_widths",
    "midline",
    "offset_by_gradient",
    "offset_by_table",
    "offset_side",
    "polyline_length",
    "refine_subpixel",
    "resample_polyline",
    "resample_polyline_of_length",
    "sample_bilinear",
    "score_knots",
    "side_slope_samples",
    "side_sweeps",
    "signed_area",
    "slope_sweep_median",
    "smooth_polyline",
    "spans_around_points",
    "split_contour",
    "split_shapes_local",
    "thin_chain",
    "trace_contour",
    "track_material_points",
    "track_material_points_of_length",
    "trim_polyline_end",
    "turning_angles",
    "turning_angles_far",
    "union_spans",
]
