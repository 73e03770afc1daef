"""A steady frame in one kernel call: the band, the edges and the contour, the split, the time order and the
material points.

Once a stream is steady (the rope's width, polarity, contrast, fixed end and Lc0 are known and the last frame was
found in its band), a frame is five kernel calls (`band_stage`, `detect_and_trace`, `split_frame`,
`count_revisits`, `track_frame`) with a little Python between them. Each call from Python pays a dispatch: a
fixed cost, then the type matching and unboxing of every argument, ~0.1 us per array warm and ~0.2-0.3 us after
the frame's kernels have evicted the dispatcher's data, ~80 arguments in all. `steady_frame` makes the five calls
from compiled code, and takes the buffers, which are the same every frame, as one table of their addresses and
shapes (`STEADY_BUFFERS`, made once by `ropecam.device.pipeline._views.buffer_table`), passed as its address; in
the table are its constant scalars as one named record (`STEADY_CONSTANTS`), its results as another
(`STEADY_OUT`), its per-frame scalars as a third (`STEADY_ARGS`) and the frame, through a slot that holds it
during the call (`tables.slot_frame_address`): one int argument, no array (an array argument costs a MemInfo of
Python allocation per call). It stops where the
stages' Python would have taken another turn (a contour that leaves the band, a split that is not two shapes, a
contour that is no band outline, shapes `track_frame` does not take), so that Python goes on from there with the
same state as after the same calls made one by one.

The table holds raw addresses: whoever makes it keeps its arrays alive and unchanged in shape while it is used
(the pipeline keeps them with the table, and makes a new table when one of them is replaced; see `tables`).
"""

from __future__ import annotations

import math
from typing import Final, NamedTuple

import numpy as np
from numba import int64

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.device.pipeline._kernels.band_stage import band_stage
from ropecam.device.pipeline._kernels.cells import CLOCK, CLOCK_CELLS, CONTOUR_POINTS, LOCATE, LOCATE_CELLS, clock_tick
from ropecam.device.pipeline._kernels.checks import (
    CHECK_QUALITY,
    CHECK_THRESHOLDS,
    CHECK_TIP_MASKED,
    check_frame,
    predict_tips,
    tip_end_seen,
)
from ropecam.device.pipeline._kernels.detect import detect_and_trace
from ropecam.device.pipeline._kernels.groups import (
    BAND_STATE,
    SPLIT_WIDTH_SCALARS,
    Band,
    Contour,
    EdgeWork,
    Motion,
    Order,
    Planes,
    SplitWork,
    Static,
    Track,
)
from ropecam.device.pipeline._kernels.plane import place_on_plane
from ropecam.device.pipeline._kernels.revisits import count_revisits
from ropecam.device.pipeline._kernels.split_frame import FRAME_INFO, FRAME_STATE, FRAME_STATES, split_frame
from ropecam.device.pipeline._kernels.split_shapes import split_width
from ropecam.device.pipeline._kernels.tables import buffer1, buffer2, buffer3, slot_frame, slot_frame_address, table_at
from ropecam.device.pipeline._kernels.tracking import track_frame
from ropecam.shared.jit import kernel

STEADY_DONE: Final = 0
"""`steady_frame` made the frame's two shapes, put them in time order and tracked them (all four calls)."""
STEADY_AFTER_CONTOUR: Final = 1
"""It stopped after `detect_and_trace`: no contour, or one that touches the band's border or the image's (the
stage widens the band, searches elsewhere or checks the clipping)."""
STEADY_AFTER_SPLIT: Final = 2
"""It stopped after `split_frame`, which did not make two shapes (its status is in ``out["status"]``)."""
STEADY_AFTER_SHAPES: Final = 3
"""It stopped after the split's two shapes, which `track_frame` refused (nothing written by it)."""
STEADY_BROKEN: Final = 4
"""It stopped after the split's two shapes (of a known exposure) because the contour walks more than
``broken_outline`` of its pixels twice (``out["revisits"]``): it is no band outline (`track_frame` not called)."""

STEADY_OUT: Final = np.dtype(
    [
        ("motion_px", np.float64),
        ("points", np.int64),
        ("status", np.int64),
        ("revisits", np.int64),
        ("swap", np.int64),
        ("confidence", np.float64),
        ("stretch_begin", np.float64),
        ("stretch_end", np.float64),
        ("check", np.int64),
        ("placed", np.int64),
    ]
)
"""`steady_frame`'s results, one record, each written as far as the calls went: the band's uncertainty at the
farthest point (px, `band_stage`), the contour's point count (`detect_and_trace`), `split_frame`'s status, the
contour pixels walked twice (`count_revisits`; -1: not counted), then `track_frame`'s four results: the swap (0 or
1), the order confidence, the stretch of the begin shape and of the end shape; then the self-checks' code
(`check_frame`; -1: not checked in the call, the stages' Python checks the frame); last 1 when the call placed the
material points on the plane (`place_on_plane`, whatever it returned), -1 when it did not."""
STEADY_ARGS: Final = np.dtype(
    [
        ("measure", np.int64),
        ("predict", np.int64),
        ("t_ns", np.int64),
        ("exposure_ns", np.int64),
        ("t_end_ns", np.int64),
        ("last_sweep_px", np.float64),
        ("predict_tips_now", np.int64),
        ("check_width_px", np.float64),
        ("learned_width_px", np.float64),
    ]
)
"""`steady_frame`'s per-frame scalars, one record (the flags 0 or 1; every field 8 bytes wide, so that Python writes
them through two memoryviews, `_views.RecordCells`): passed in the table rather than as arguments, the call's
dispatch is one int (a call of ten scalar arguments took ~5 us more after `cv2.Canny` than one of one: the
dispatcher types each argument)."""
STEADY_CONSTANTS: Final = np.dtype(
    [
        ("margin_px", np.int64),
        ("height", np.int64),
        ("width", np.int64),
        ("gain", np.float64),
        ("floor_px", np.float64),
        ("floor_share", np.float64),
        ("low", np.float32),
        ("high", np.float32),
        ("min_pixels", np.int32),
        ("length0_px", np.float64),
        ("broken_outline", np.float64),
        ("on_plane", np.int64),
        ("still_dn", np.float64),
        ("still_relative", np.float64),
        ("rope_width_px", np.float64),
    ]
)
"""`steady_frame`'s `constants`, one record: the scalars of its kernels that do not change between frames (the band's
margin, the image size, the band's need model, the Canny thresholds, the smallest component, Lc0), the largest
part of the contour's pixels walked twice before it is no band outline, whether the material points are placed
on a plane (1: ``plane`` holds its `plane_params`; 0: in pixels), and the learned static scene's still range
(``still_dn`` + ``still_relative`` x the high level, as `StaticMask.shows_end` reads it; ``still_dn`` negative:
no learned scene, a ``tip_masked`` verdict stands), and the rope's width that `track_frame` takes (the edge model's
width for the edge spacing, as the step-by-step path gives it: `SplitOutcome.width_px`)."""

_SHAPES: Final = 2
"""`split_frame`'s return when it made the two shapes."""
_INFO_COUNT_A: Final = 0
_INFO_COUNT_B: Final = 1
_INFO_SMOOTHED_A: Final = 4
_INFO_SMOOTHED_B: Final = 5
_INFO_SWEEP: Final = 6


STEADY_BUFFERS: Final = (
    # band_stage's
    ("prev_points", np.float32, 2), ("fixed", np.float32, 1), ("motion_state", np.int64, 1),
    ("motion_log", np.float64, 2), ("need_hist", np.float64, 2), ("profile", np.float64, 1),
    ("band_state", BAND_STATE, 1), ("lo", np.int32, 1), ("hi", np.int32, 1), ("moved", np.float32, 2),
    # detect_and_trace's
    ("weights", np.float32, 1), ("static_mask", np.uint8, 2), ("static_low", np.uint8, 2),
    ("static_high", np.uint8, 2), ("static_near", np.uint8, 1), ("work_spans", np.int32, 2),
    ("tmp", np.float32, 2), ("smooth", np.float32, 2),
    ("gx", np.float32, 2), ("gy", np.float32, 2), ("mag", np.float32, 2), ("edges", np.uint8, 2),
    ("edge_stack", np.int32, 1), ("labels", np.int32, 2), ("stack", np.int32, 1), ("start", np.int32, 1),
    ("chain", np.int32, 2), ("codes", np.int32, 1), ("points", np.float32, 2), ("counts", np.int32, 1),
    # split_frame's
    ("box_lo", np.int32, 1), ("box_hi", np.int32, 1), ("width_scalars", np.float64, 1), ("split_state", np.float64, 1),
    ("curves", np.float64, 2), ("table", np.float32, 1), ("sweep_index", np.int32, 1), ("lines", np.float32, 2),
    ("sides", np.float32, 3), ("scratch", np.float64, 2), ("turn", np.float32, 1), ("idx", np.int32, 1),
    ("out_seg", np.float32, 2), ("split_info", np.float64, 1),
    # track_frame's
    ("order_state", np.int64, 1), ("hist_rc", np.float64, 2), ("prev_end", np.float32, 2), ("splice", np.float32, 3),
    ("fraction", np.float64, 1),
    ("out_points", np.float32, 3), ("out_lengths", np.float64, 1), ("work_seg", np.float64, 1),
    # predict_tips' and check_frame's
    ("predicted", np.float64, 1), ("check_thresholds", CHECK_THRESHOLDS, 1), ("check_quality", CHECK_QUALITY, 1),
    # place_on_plane's
    ("plane", np.float64, 1),
    # steady_frame's own: the frame slot (`FrameSlot`: its row is address, 1, height, width), the constants, the results
    ("frame_slot", np.int64, 1), ("constants", STEADY_CONSTANTS, 1), ("out", STEADY_OUT, 1),
    ("args", STEADY_ARGS, 1),
    # the frame clock's and the locator's cells (`cells`)
    ("clock", np.int64, 1), ("locate", np.int64, 1),
)  # fmt: skip
"""The buffers of `steady_frame`'s table, in its row order: (name, dtype, dimensions), C-contiguous; each is the
argument of that name of the kernel it is listed under, the last four `steady_frame`'s own."""

STEADY_ROW: Final = NamedTuple("SteadyRows", [(name, int) for name, _, _ in STEADY_BUFFERS])(
    *range(len(STEADY_BUFFERS))
)
"""The row of each buffer in `steady_frame`'s table (``STEADY_ROW.lo``), made from `STEADY_BUFFERS`: the one list
of the table's buffers, kept in this file so that an edit of it recompiles the kernel (Numba freezes the rows)."""


# No array argument (each would cost a MemInfo of Python allocation per call): the table by its address, the frame
# through the table's frame slot (`tables.slot_frame_address`). Its callees run from its own object (`own_callees`:
# 11-20 us per `rig` frame, docs/speed.md row speed17 (17)).
@kernel(int64(int64), own_callees=True)
def steady_frame(table_address):
    """One steady frame, its per-frame scalars the fields of the table's record ``args`` (`STEADY_ARGS`: `measure`,
    `predict`, `t_ns`, `exposure_ns`, `t_end_ns`, `last_sweep_px`, `predict_tips_now`, `check_width_px`,
    `learned_width_px`; the flags 0 or 1), exposed from `t_ns` to `t_end_ns` (`exposure_ns`): its start taken into
    the frame clock (`clock_tick` of ``clock``); `band_stage` around the last contour (``locate``'s ``prev_count``
    points of ``prev_points``, `measure` and `predict` as its arguments, its `use_profile` whether twice the time gap
    from ``locate``'s ``prev_t_ns`` is at most three times its ``need_gap_ns``; the gap goes to its ``gap_ns``) into the
    spans ``lo``/``hi``; `detect_and_trace` of `frame` in them (the point count, 0 for none, to ``counts``'s
    `CONTOUR_POINTS`); when it found a contour (``points``, ``chain``) that touches neither the band's border nor
    the image's, it is the frame's kept contour (``locate``: as `RopeLocator.found_in_band` and `keep`, the frame
    counted in ``frames_roi``) and `split_frame` of it (``split_state``'s
    ``last_sweep_px`` set to `last_sweep_px`, its ``n`` to the point count; the width's group made by
    `split_width` of ``width_scalars``, ``curves``, ``table``) with the same planes, frame, weights and spans; when
    that made the two shapes (views of ``sides``, smoothed or not as ``split_info`` says), `track_frame` of them
    with the new sweep, ``fixed``, the band's motion state and `max_age_ns` (first, for a known exposure, the
    contour's pixels walked twice are counted: more than ``broken_outline`` of them stop it); `max_age_ns` is
    ``clock``'s.

    The self-checks' two calls are made here too: first, when `predict_tips_now`, `predict_tips` into
    ``predicted`` (as `SelfChecks.predict` before the frame); last, on shapes of a known exposure that
    `track_frame` took and with a prediction (``predicted``'s error not nan: the contour's area is not needed),
    `check_frame` of them in time order (`check_width_px` the width the split used, `learned_width_px` the learned
    one, ``check_thresholds``, the measures into ``check_quality``, the mask ``static_mask``, the corners
    ``out_seg``) as `ResultFinisher.check` makes it, a ``tip_masked`` verdict withdrawn as `SelfChecks.check`
    withdraws it (`tip_end_seen` of both tips on ``static_low``/``static_high`` with ``constants``' still range,
    then `check_frame` again without the mask); its code goes to ``out["check"]`` (-1: not checked here). Before the
    checks, on a plane (``constants["on_plane"]``), the tracked shapes' material points are placed on it
    (`place_on_plane` with ``plane``, ``fraction``, ``out_points``, ``work_seg``, as `ResultFinisher` places them;
    not when a shape is longer than ``work_seg``: ``out["placed"]`` is then -1 and the stages' Python places them).

    The buffers (names in ``double backquotes``) are the rows of the table at `table_address` (int64,
    (len(STEADY_BUFFERS), 4): address, then the sizes of up to three dimensions; `buffer_table` makes it), the
    constant scalars the fields of the one record ``constants`` (`STEADY_CONSTANTS`), `frame` the (height, width)
    uint8 array the ``frame_slot`` holds (its row: the slot's address, 1, height, width). The record ``out``
    (`STEADY_OUT`) gets the band's uncertainty, the contour's point count, the split's status, the pixels walked
    twice and `track_frame`'s four results, each as far as the calls went.

    Returns STEADY_DONE, or where it stopped (STEADY_AFTER_CONTOUR, STEADY_AFTER_SPLIT, STEADY_BROKEN,
    STEADY_AFTER_SHAPES): everything before that point is done and written exactly as the calls one by one write
    it, nothing after it; or INVALID, before any call, when ``constants``, ``out`` or ``args`` holds no record, the
    frame slot no C-contiguous (height, width) array, or ``split_state``, ``split_info``, ``width_scalars``,
    ``curves``, ``predicted``, ``check_thresholds``, ``check_quality``, ``counts``, ``clock`` or ``locate`` is too
    short.
    """
    table = table_at(table_address, len(STEADY_BUFFERS))
    constants = buffer1(table, STEADY_ROW.constants, STEADY_CONSTANTS)
    out = buffer1(table, STEADY_ROW.out, STEADY_OUT)
    frame_args = buffer1(table, STEADY_ROW.args, STEADY_ARGS)
    frame_address = slot_frame_address(table, STEADY_ROW.frame_slot)
    if constants.shape[0] < 1 or out.shape[0] < 1 or frame_args.shape[0] < 1 or frame_address == 0:
        return INVALID
    a = frame_args[0]
    measure = a["measure"] != 0
    predict = a["predict"] != 0
    t_ns = a["t_ns"]
    exposure_ns = a["exposure_ns"]
    t_end_ns = a["t_end_ns"]
    last_sweep_px = a["last_sweep_px"]
    predict_tips_now = a["predict_tips_now"] != 0
    check_width_px = a["check_width_px"]
    learned_width_px = a["learned_width_px"]
    frame = slot_frame(table, STEADY_ROW.frame_slot, frame_address)
    c = constants[0]
    result = out[0]
    split_state = buffer1(table, STEADY_ROW.split_state, np.float64)
    split_info = buffer1(table, STEADY_ROW.split_info, np.float64)
    width_scalars = buffer1(table, STEADY_ROW.width_scalars, np.float64)
    curves = buffer2(table, STEADY_ROW.curves, np.float64)
    predicted = buffer1(table, STEADY_ROW.predicted, np.float64)
    thresholds = buffer1(table, STEADY_ROW.check_thresholds, CHECK_THRESHOLDS)
    quality = buffer1(table, STEADY_ROW.check_quality, CHECK_QUALITY)
    counts = buffer1(table, STEADY_ROW.counts, np.int32)
    clock = buffer1(table, STEADY_ROW.clock, np.int64)
    cells = buffer1(table, STEADY_ROW.locate, np.int64)
    if (
        split_state.shape[0] < len(FRAME_STATES)
        or split_info.shape[0] < FRAME_INFO
        or width_scalars.shape[0] < len(SPLIT_WIDTH_SCALARS)
        or curves.shape[0] < 2
        or predicted.shape[0] < 3
        or thresholds.shape[0] < 1
        or quality.shape[0] < 1
        or counts.shape[0] <= CONTOUR_POINTS
        or clock.shape[0] < len(CLOCK_CELLS)
        or cells.shape[0] < len(LOCATE_CELLS)
    ):
        return INVALID
    clock_tick(clock, t_ns)
    max_age_ns = clock[CLOCK.max_age_ns]
    gap_ns = t_ns - cells[LOCATE.prev_t_ns]
    cells[LOCATE.gap_ns] = gap_ns
    lo = buffer1(table, STEADY_ROW.lo, np.int32)
    hi = buffer1(table, STEADY_ROW.hi, np.int32)
    fixed = buffer1(table, STEADY_ROW.fixed, np.float32)
    motion = Motion(
        buffer1(table, STEADY_ROW.motion_state, np.int64),
        buffer2(table, STEADY_ROW.motion_log, np.float64),
        buffer2(table, STEADY_ROW.need_hist, np.float64),
        buffer1(table, STEADY_ROW.profile, np.float64),
        buffer1(table, STEADY_ROW.band_state, BAND_STATE),
    )
    result["revisits"] = -1
    result["check"] = -1
    result["placed"] = -1
    if predict_tips_now:
        predict_tips(t_ns, exposure_ns, motion.state, motion.log, fixed, predicted)
    result["motion_px"] = band_stage(
        buffer2(table, STEADY_ROW.prev_points, np.float32),
        cells[LOCATE.prev_count],
        measure,
        2 * gap_ns <= 3 * cells[LOCATE.need_gap_ns],
        predict,
        t_ns,
        exposure_ns,
        c["margin_px"],
        c["height"],
        c["width"],
        c["gain"],
        c["floor_px"],
        c["floor_share"],
        fixed,
        motion,
        Band(lo, hi, buffer2(table, STEADY_ROW.moved, np.float32)),
    )
    low = c["low"]
    high = c["high"]
    min_pixels = c["min_pixels"]
    weights = buffer1(table, STEADY_ROW.weights, np.float32)
    tmp = buffer2(table, STEADY_ROW.tmp, np.float32)
    smooth = buffer2(table, STEADY_ROW.smooth, np.float32)
    gx = buffer2(table, STEADY_ROW.gx, np.float32)
    gy = buffer2(table, STEADY_ROW.gy, np.float32)
    mag = buffer2(table, STEADY_ROW.mag, np.float32)
    chain = buffer2(table, STEADY_ROW.chain, np.int32)
    edges = buffer2(table, STEADY_ROW.edges, np.uint8)
    points = buffer2(table, STEADY_ROW.points, np.float32)
    planes = Planes(smooth, gx, gy, mag)
    n = detect_and_trace(
        frame,
        lo,
        hi,
        weights,
        low,
        high,
        min_pixels,
        Static(
            buffer2(table, STEADY_ROW.static_mask, np.uint8),
            buffer2(table, STEADY_ROW.static_low, np.uint8),
            buffer2(table, STEADY_ROW.static_high, np.uint8),
            buffer1(table, STEADY_ROW.static_near, np.uint8),
        ),
        EdgeWork(
            buffer2(table, STEADY_ROW.work_spans, np.int32),
            tmp,
            edges,
            buffer1(table, STEADY_ROW.edge_stack, np.int32),
        ),
        planes,
        Contour(
            buffer2(table, STEADY_ROW.labels, np.int32),
            buffer1(table, STEADY_ROW.stack, np.int32),
            buffer1(table, STEADY_ROW.start, np.int32),
            chain,
            buffer1(table, STEADY_ROW.codes, np.int32),
            points,
            counts,
        ),
    )
    result["points"] = n
    counts[CONTOUR_POINTS] = max(n, 0)  # FULL: a contour longer than the buffers is not a rope
    if n <= 0 or counts[1] != 0 or counts[2] != 0:
        return STEADY_AFTER_CONTOUR
    cells[LOCATE.need_gap_ns] = gap_ns
    cells[LOCATE.frames_roi] += 1
    cells[LOCATE.prev_count] = n
    cells[LOCATE.prev_t_ns] = t_ns
    split_state[FRAME_STATE.last_sweep_px] = last_sweep_px
    split_state[FRAME_STATE.n] = n
    sides = buffer3(table, STEADY_ROW.sides, np.float32)
    status = split_frame(
        points,
        chain,
        planes,
        frame,
        weights,
        lo,
        hi,
        buffer1(table, STEADY_ROW.box_lo, np.int32),
        buffer1(table, STEADY_ROW.box_hi, np.int32),
        tmp,
        split_width(width_scalars, curves, buffer1(table, STEADY_ROW.table, np.float32)),
        buffer1(table, STEADY_ROW.sweep_index, np.int32),
        split_state,
        SplitWork(
            buffer2(table, STEADY_ROW.lines, np.float32),
            sides,
            buffer2(table, STEADY_ROW.scratch, np.float64),
            buffer1(table, STEADY_ROW.turn, np.float32),
            buffer1(table, STEADY_ROW.idx, np.int32),
            buffer2(table, STEADY_ROW.out_seg, np.float32),
            split_info,
        ),
    )
    result["status"] = status
    if status != _SHAPES:
        return STEADY_AFTER_SPLIT
    if exposure_ns > 0:
        # `ResultFinisher.finish`'s test of a split of a known exposure, before the time order and the material
        # points take the shapes: a contour that went out along the pieces of a broken edge and back.
        revisits = count_revisits(chain, n, edges)
        result["revisits"] = revisits
        if revisits > c["broken_outline"] * n:
            return STEADY_BROKEN
    shape_a = sides[0 if split_info[_INFO_SMOOTHED_A] != 0.0 else 2, : int(split_info[_INFO_COUNT_A])]
    shape_b = sides[1 if split_info[_INFO_SMOOTHED_B] != 0.0 else 3, : int(split_info[_INFO_COUNT_B])]
    fraction = buffer1(table, STEADY_ROW.fraction, np.float64)
    out_points = buffer3(table, STEADY_ROW.out_points, np.float32)
    work_seg = buffer1(table, STEADY_ROW.work_seg, np.float64)
    swap, confidence, stretch_begin, stretch_end = track_frame(
        shape_a,
        shape_b,
        False,
        t_ns,
        t_end_ns,
        max_age_ns,
        Order(
            buffer1(table, STEADY_ROW.order_state, np.int64),
            buffer2(table, STEADY_ROW.hist_rc, np.float64),
            buffer2(table, STEADY_ROW.prev_end, np.float32),
            buffer3(table, STEADY_ROW.splice, np.float32),
        ),
        fixed,
        split_info[_INFO_SWEEP],
        exposure_ns,
        motion,
        c["length0_px"],
        Track(fraction, out_points, buffer1(table, STEADY_ROW.out_lengths, np.float64), work_seg),
        c["rope_width_px"],
    )
    result["swap"] = swap
    result["confidence"] = confidence
    result["stretch_begin"] = stretch_begin
    result["stretch_end"] = stretch_end
    if swap < 0:
        return STEADY_AFTER_SHAPES
    begin = shape_b if swap else shape_a
    end = shape_a if swap else shape_b
    if c["on_plane"] != 0 and begin.shape[0] <= work_seg.shape[0] and end.shape[0] <= work_seg.shape[0]:
        place_on_plane(begin, end, False, fraction, buffer1(table, STEADY_ROW.plane, np.float64), out_points, work_seg)
        result["placed"] = 1
    if exposure_ns > 0 and not math.isnan(predicted[2]) and shape_a.shape[0] > 0 and shape_b.shape[0] > 0:
        mask = buffer2(table, STEADY_ROW.static_mask, np.uint8)
        corners = buffer2(table, STEADY_ROW.out_seg, np.float32)  # the corners `split_frame` wrote
        # (the contour's area: not read with a prediction and a known exposure)
        code = check_frame(begin, end, fixed, predicted, stretch_begin, stretch_end, check_width_px,
                           learned_width_px, confidence, exposure_ns, True, 0.0, mask, corners, thresholds,
                           quality)  # fmt: skip
        if code == CHECK_TIP_MASKED and c["still_dn"] >= 0.0:
            # `SelfChecks.check`'s withdrawal: where the frame shows both tips as the rope's ends (the rope at each
            # tip, the learned still scene beyond it: `StaticMask.shows_end`), the checks again without the mask.
            width = learned_width_px if learned_width_px != 0.0 else check_width_px
            reach_px = thresholds[0]["tip_mask_widths"] * width + thresholds[0]["tip_mask_floor_px"]
            low = buffer2(table, STEADY_ROW.static_low, np.uint8)
            high = buffer2(table, STEADY_ROW.static_high, np.uint8)
            still_dn = c["still_dn"]
            relative = c["still_relative"]
            if tip_end_seen(begin, frame, low, high, width, reach_px, still_dn, relative) and tip_end_seen(
                end, frame, low, high, width, reach_px, still_dn, relative
            ):
                code = check_frame(
                    begin,
                    end,
                    fixed,
                    predicted,
                    stretch_begin,
                    stretch_end,
                    check_width_px,
                    learned_width_px,
                    confidence,
                    exposure_ns,
                    True,
                    0.0,
                    mask[:0],  # no row of the mask: nothing masked
                    corners,
                    thresholds,
                    quality,
                )  # fmt: skip (no row of the mask: nothing masked)
        result["check"] = code
    return STEADY_DONE
