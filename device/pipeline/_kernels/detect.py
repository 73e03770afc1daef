"""The edge and contour stages' kernels in one call (`detect_and_trace`).

Each call from Python costs a dispatch (type matching of every argument, ~0.1 us per array) and a return to the
interpreter with caches the kernels have filled with image data: a stream's frames call these instead of the
stages' kernels one by one."""

from __future__ import annotations

from typing import Final

from numba import float32, int32

from ropecam.device.pipeline._kernels._common import INVALID, f4_1d_ro
from ropecam.device.pipeline._kernels.canny import detect_edges
from ropecam.device.pipeline._kernels.contour import trace_rope
from ropecam.device.pipeline._kernels.groups import CONTOUR, EDGE_WORK, PLANES, STATIC
from ropecam.device.pipeline._kernels.static_mask import drop_static_edges, seal_cut_ends
from ropecam.shared.jit import i4_1d_ro, kernel, u1_2d_ro

# The frame is declared read-only (a mapped capture buffer); a writable one (a frame a reader made) is taken through
# Numba's safe mutable-to-read-only conversion, at the dispatch cost of an exact match: no view per frame, and no
# second signature to compile.
_DETECT_AND_TRACE_ARGS: Final = (
    i4_1d_ro,
    i4_1d_ro,
    f4_1d_ro,
    float32,
    float32,
    int32,
    STATIC,
    EDGE_WORK,
    PLANES,
    CONTOUR,
)
"""The arguments after the frame."""


@kernel(int32(u1_2d_ro, *_DETECT_AND_TRACE_ARGS))
def detect_and_trace(frame, lo, hi, weights, low, high, min_pixels, static, work, planes, contour):
    """`detect_edges` inside the spans `lo`/`hi`, then `trace_rope` on its edges (the edge pixels it lists in
    ``work.stack``, `ring_clear` true: `detect_edges` leaves the edge map 0 next to its spans) after
    `drop_static_edges` with `static` (`Static`: ``mask``, ``low``, ``high``, 1x1 each: no mask; ``near``) and
    `seal_cut_ends` (the rope's sides cut at a masked clamp joined across its exit; with a mask, an open outline
    is walked once): the edge and contour stages in one call, with the same outputs as those calls.

    `weights`, `low`, `high` are `detect_edges`' arguments, `min_pixels` `trace_rope`'s. Writes `work`
    (`EdgeWork`: ``work_spans``, ``tmp``, ``edges``, ``stack``) and `planes` (`Planes`: ``smooth``, ``gx``,
    ``gy``, ``mag``) as `detect_edges` writes its outputs, and `contour` (`Contour`) as `trace_rope`.
    ``contour.counts`` needs 4 slots: `trace_rope`'s three (component pixels, ROI contacts, chain pixels on the
    image border), then the number of edge pixels `detect_edges` returned (or its status).
    Returns `trace_rope`'s result (chain length, NOT_FOUND or FULL), or INVALID when ``contour.counts`` is too
    short or `detect_edges` refused its arguments (its status is then in ``counts[3]``, the other slots 0).
    """
    counts = contour.counts
    if counts.shape[0] < 4:
        return INVALID
    edges = work.edges
    edge_list = work.stack
    count = detect_edges(
        frame, weights, lo, hi, low, high, work.work_spans, work.tmp, planes.smooth, planes.gx, planes.gy,
        planes.mag, edges, edge_list,
    )  # fmt: skip
    counts[3] = count
    if count < 0:
        counts[0] = 0
        counts[1] = 0
        counts[2] = 0
        return INVALID
    count = drop_static_edges(frame, static.mask, static.low, static.high, static.near, edges, edge_list, count)
    count = seal_cut_ends(static.mask, static.near, lo, hi, edges, edge_list, count)
    counts[3] = count
    return trace_rope(
        edges, lo, hi, edge_list, count, min_pixels, True, static.mask, planes.mag, planes.gx, planes.gy, contour
    )
