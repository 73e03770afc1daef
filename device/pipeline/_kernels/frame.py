"""A steady frame in one kernel call: the band, the edges and the contour, the split, the time order and the
material points.

Once a stream is steady (the rope's width, polarity, contrast, fixed end and Lc0 are known and the last frame was
found in its band), a frame is four kernel calls (`band_stage`, `detect_and_trace`, `split_frame`, `track_frame`)
with a little Python between them. Each call from Python pays a dispatch: a fixed cost, then the type matching and
unboxing of every argument, ~0.1 us per array warm and ~0.2-0.3 us after the frame's kernels have evicted the
dispatcher's data, ~80 arguments in all. `steady_frame` makes the four calls from compiled code, and takes the
buffers, which are the same every frame, as one table of their addresses and shapes (`STEADY_BUFFERS`, made once
by `ropecam.device.pipeline._views.buffer_table`): 12 arguments. It stops where the stages' Python would have
taken another turn (a contour that leaves the band, a split that is not two shapes, shapes `track_frame` does not
take), so that Python goes on from there with the same state as after the same calls made one by one.

The table holds raw addresses: whoever makes it keeps its arrays alive and unchanged in shape while it is used
(the pipeline keeps them with the table, and makes a new table when one of them is replaced).
"""

from __future__ import annotations

import ctypes
from typing import Any, Final

import numba
import numpy as np
from numba import boolean, carray, float32, float64, int32, int64, types
from numba.extending import intrinsic

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.device.pipeline._kernels.band_stage import band_stage
from ropecam.device.pipeline._kernels.split_frame import FRAME_INFO, FRAME_STATE, split_frame
from ropecam.device.pipeline._kernels.stages import detect_and_trace
from ropecam.device.pipeline._kernels.tracking import track_frame
from ropecam.shared.jit import f8_1d, kernel, u1_2d, u1_2d_ro

i8_2d: Final = types.Array(types.int64, 2, "C")

STEADY_DONE: Final = 0
"""`steady_frame` made the frame's two shapes, put them in time order and tracked them (all four calls)."""
STEADY_AFTER_CONTOUR: Final = 1
"""It stopped after `detect_and_trace`: no contour, or one that touches the band's border or the image's (the
stage widens the band, searches elsewhere or checks the clipping)."""
STEADY_AFTER_SPLIT: Final = 2
"""It stopped after `split_frame`, which did not make two shapes (its status is in ``out[STEADY_STATUS]``)."""
STEADY_AFTER_SHAPES: Final = 3
"""It stopped after the split's two shapes, which `track_frame` refused (nothing written by it)."""

STEADY_MOTION: Final = 0
"""Slots of `steady_frame`'s `out` (float64): the band's uncertainty at the farthest point (px, `band_stage`),"""
STEADY_POINTS: Final = 1
"""the contour's point count (`detect_and_trace`),"""
STEADY_STATUS: Final = 2
"""`split_frame`'s status,"""
STEADY_SWAP: Final = 3
"""then `track_frame`'s four results: the swap (0 or 1), the order confidence, the stretch of the begin shape and
of the end shape."""
STEADY_CONFIDENCE: Final = 4
STEADY_STRETCH_BEGIN: Final = 5
STEADY_STRETCH_END: Final = 6
STEADY_SLOTS: Final = 7

_SHAPES: Final = 2
"""`split_frame`'s return when it made the two shapes."""
_INFO_COUNT_A: Final = 0
_INFO_COUNT_B: Final = 1
_INFO_SMOOTHED_A: Final = 4
_INFO_SMOOTHED_B: Final = 5
_INFO_SWEEP: Final = 6
_STATE_SWEEP: Final = 4
_STATE_POINTS: Final = 5


STEADY_BUFFERS: Final = (
    # band_stage's
    ("prev_points", np.float32, 2), ("fixed", np.float32, 1), ("motion_state", np.int64, 1),
    ("motion_log", np.float64, 2), ("need_hist", np.float64, 2), ("profile", np.float64, 1),
    ("band_state", np.float64, 1), ("lo", np.int32, 1), ("hi", np.int32, 1), ("moved", np.float32, 2),
    # detect_and_trace's
    ("weights", np.float32, 1), ("work_spans", np.int32, 2), ("tmp", np.float32, 2), ("smooth", np.float32, 2),
    ("gx", np.float32, 2), ("gy", np.float32, 2), ("mag", np.float32, 2), ("edges", np.uint8, 2),
    ("edge_stack", np.int32, 1), ("labels", np.int32, 2), ("stack", np.int32, 1), ("start", np.int32, 1),
    ("chain", np.int32, 2), ("codes", np.int32, 1), ("points", np.float32, 2), ("counts", np.int32, 1),
    # split_frame's
    ("box_lo", np.int32, 1), ("box_hi", np.int32, 1), ("params", np.float64, 1), ("split_state", np.float64, 1),
    ("curves", np.float64, 2), ("table", np.float32, 1), ("sweep_index", np.int32, 1), ("lines", np.float32, 2),
    ("sides", np.float32, 3), ("scratch", np.float64, 2), ("turn", np.float32, 1), ("idx", np.int32, 1),
    ("out_seg", np.float32, 2), ("split_info", np.float64, 1),
    # track_frame's
    ("order_state", np.int64, 1), ("hist_rc", np.float64, 2), ("fraction", np.float64, 1),
    ("out_points", np.float32, 3), ("out_lengths", np.float64, 1), ("work_seg", np.float64, 1),
    # steady_frame's results (STEADY_* slots)
    ("out", np.float64, 1),
)  # fmt: skip
"""The buffers of `steady_frame`'s table, in its row order: (name, dtype, dimensions), C-contiguous; each is the
argument of that name of the kernel it is listed under (`out`: the STEADY_* slots)."""
STEADY_CONSTANTS: Final = (
    "margin_px", "height", "width", "gain", "floor_px", "floor_share", "low", "high", "min_pixels", "length0_px",
)  # fmt: skip
"""`steady_frame`'s `constants` (float64), in order: the scalars of the four kernels that do not change between
frames (the int and float32 ones exactly representable)."""

_PREV_POINTS: Final = 0
_FIXED: Final = 1
_MOTION_STATE: Final = 2
_MOTION_LOG: Final = 3
_NEED_HIST: Final = 4
_PROFILE: Final = 5
_BAND_STATE: Final = 6
_LO: Final = 7
_HI: Final = 8
_MOVED: Final = 9
_WEIGHTS: Final = 10
_WORK_SPANS: Final = 11
_TMP: Final = 12
_SMOOTH: Final = 13
_GX: Final = 14
_GY: Final = 15
_MAG: Final = 16
_EDGES: Final = 17
_EDGE_STACK: Final = 18
_LABELS: Final = 19
_STACK: Final = 20
_START: Final = 21
_CHAIN: Final = 22
_CODES: Final = 23
_POINTS: Final = 24
_COUNTS: Final = 25
_BOX_LO: Final = 26
_BOX_HI: Final = 27
_PARAMS: Final = 28
_SPLIT_STATE: Final = 29
_CURVES: Final = 30
_TABLE: Final = 31
_SWEEP_INDEX: Final = 32
_LINES: Final = 33
_SIDES: Final = 34
_SCRATCH: Final = 35
_TURN: Final = 36
_IDX: Final = 37
_OUT_SEG: Final = 38
_SPLIT_INFO: Final = 39
_ORDER_STATE: Final = 40
_HIST_RC: Final = 41
_FRACTION: Final = 42
_OUT_POINTS: Final = 43
_OUT_LENGTHS: Final = 44
_WORK_SEG: Final = 45
_OUT: Final = 46

# ``_pointer(address, dtype)``: the int64 `address` as a pointer to `dtype` (a NumPy scalar type).
if numba.config.DISABLE_JIT:

    def _pointer(address: int, dtype: Any) -> Any:
        return ctypes.cast(int(address), ctypes.POINTER(np.ctypeslib.as_ctypes_type(dtype)))

else:

    @intrinsic
    def _pointer(typingctx: Any, address: Any, dtype: Any) -> Any:
        if not isinstance(address, types.Integer) or not isinstance(dtype, types.NumberClass):
            return None
        pointer_type = types.CPointer(dtype.instance_type)

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            return builder.inttoptr(args[0], context.get_value_type(pointer_type))

        return pointer_type(address, dtype), codegen


@numba.njit(inline="always")
def _buffer1(table, row, dtype):  # type: ignore[no-untyped-def]
    """The 1-D buffer of `table`'s `row`."""
    return carray(_pointer(table[row, 0], dtype), (table[row, 1],))


@numba.njit(inline="always")
def _buffer2(table, row, dtype):  # type: ignore[no-untyped-def]
    """The 2-D buffer of `table`'s `row`."""
    return carray(_pointer(table[row, 0], dtype), (table[row, 1], table[row, 2]))


@numba.njit(inline="always")
def _buffer3(table, row, dtype):  # type: ignore[no-untyped-def]
    """The 3-D buffer of `table`'s `row`."""
    return carray(_pointer(table[row, 0], dtype), (table[row, 1], table[row, 2], table[row, 3]))


def _signature(frame_type: Any) -> Any:
    return int64(frame_type, int64, boolean, boolean, boolean, int64, int64, int64, int64, float64, i8_2d, f8_1d)


# Compiled for a read-only frame (a mapped capture buffer) and a writable one (a frame read from a file), as the
# kernels it calls.
@kernel([_signature(u1_2d_ro), _signature(u1_2d)])
def steady_frame(
    frame, prev_count, measure, use_profile, predict, t_ns, exposure_ns, t_end_ns, max_age_ns, last_sweep_px, table,
    constants,
):  # fmt: skip
    """One steady frame, exposed from `t_ns` to `t_end_ns` (`exposure_ns`): `band_stage` around the last contour
    (`prev_count` points of ``prev_points``, `measure` and `use_profile` and `predict` as its arguments) into the
    spans ``lo``/``hi``; `detect_and_trace` of `frame` in them; when it found a contour (``points``, ``chain``)
    that touches neither the band's border nor the image's, `split_frame` of it (``split_state[4]`` set to
    `last_sweep_px`, ``split_state[5]`` to the point count) with the same planes, frame, weights and spans; when
    that made the two shapes (views of ``sides``, smoothed or not as ``split_info`` says), `track_frame` of them
    with the new sweep, ``fixed``, the band's motion state and `max_age_ns`.

    The buffers (names in ``double backquotes``) are the rows of `table` (int64, (len(STEADY_BUFFERS), 4):
    address, then the sizes of up to three dimensions; `buffer_table` makes it), the constant scalars the
    entries of `constants` (STEADY_CONSTANTS). ``out`` gets the band's uncertainty, the contour's point count,
    the split's status and `track_frame`'s four results (slots STEADY_*), each as far as the calls went.

    Returns STEADY_DONE, or where it stopped (STEADY_AFTER_CONTOUR, STEADY_AFTER_SPLIT, STEADY_AFTER_SHAPES):
    everything before that point is done and written exactly as the calls one by one write it, nothing after it;
    or INVALID, before any call, when `table` or `constants` has too few rows, or ``out``, ``split_state`` or
    ``split_info`` is too short.
    """
    if table.shape[0] < _OUT + 1 or table.shape[1] < 4 or constants.shape[0] < len(STEADY_CONSTANTS):
        return INVALID
    out = _buffer1(table, _OUT, np.float64)
    split_state = _buffer1(table, _SPLIT_STATE, np.float64)
    split_info = _buffer1(table, _SPLIT_INFO, np.float64)
    if out.shape[0] < STEADY_SLOTS or split_state.shape[0] < FRAME_STATE or split_info.shape[0] < FRAME_INFO:
        return INVALID
    lo = _buffer1(table, _LO, np.int32)
    hi = _buffer1(table, _HI, np.int32)
    fixed = _buffer1(table, _FIXED, np.float32)
    motion_state = _buffer1(table, _MOTION_STATE, np.int64)
    motion_log = _buffer2(table, _MOTION_LOG, np.float64)
    out[STEADY_MOTION] = band_stage(
        _buffer2(table, _PREV_POINTS, np.float32), prev_count, measure, use_profile, predict, t_ns, exposure_ns,
        int64(constants[0]), int64(constants[1]), int64(constants[2]), constants[3], constants[4], constants[5],
        fixed, motion_state, motion_log, _buffer2(table, _NEED_HIST, np.float64), _buffer1(table, _PROFILE, np.float64),
        _buffer1(table, _BAND_STATE, np.float64), lo, hi, _buffer2(table, _MOVED, np.float32),
    )  # fmt: skip
    weights = _buffer1(table, _WEIGHTS, np.float32)
    tmp = _buffer2(table, _TMP, np.float32)
    smooth = _buffer2(table, _SMOOTH, np.float32)
    gx = _buffer2(table, _GX, np.float32)
    gy = _buffer2(table, _GY, np.float32)
    mag = _buffer2(table, _MAG, np.float32)
    chain = _buffer2(table, _CHAIN, np.int32)
    points = _buffer2(table, _POINTS, np.float32)
    counts = _buffer1(table, _COUNTS, np.int32)
    n = detect_and_trace(
        frame, lo, hi, weights, float32(constants[6]), float32(constants[7]), int32(constants[8]),
        _buffer2(table, _WORK_SPANS, np.int32), tmp, smooth, gx, gy, mag, _buffer2(table, _EDGES, np.uint8),
        _buffer1(table, _EDGE_STACK, np.int32), _buffer2(table, _LABELS, np.int32), _buffer1(table, _STACK, np.int32),
        _buffer1(table, _START, np.int32), chain, _buffer1(table, _CODES, np.int32), points, counts,
    )  # fmt: skip
    out[STEADY_POINTS] = n
    if n <= 0 or counts[1] != 0 or counts[2] != 0:
        return STEADY_AFTER_CONTOUR
    split_state[_STATE_SWEEP] = last_sweep_px
    split_state[_STATE_POINTS] = n
    sides = _buffer3(table, _SIDES, np.float32)
    status = split_frame(
        points, chain, mag, gx, gy, frame, weights, lo, hi, _buffer1(table, _BOX_LO, np.int32),
        _buffer1(table, _BOX_HI, np.int32), tmp, smooth, _buffer1(table, _PARAMS, np.float64), split_state,
        _buffer2(table, _CURVES, np.float64), _buffer1(table, _TABLE, np.float32),
        _buffer1(table, _SWEEP_INDEX, np.int32), _buffer2(table, _LINES, np.float32), sides,
        _buffer2(table, _SCRATCH, np.float64), _buffer1(table, _TURN, np.float32), _buffer1(table, _IDX, np.int32),
        _buffer2(table, _OUT_SEG, np.float32), split_info,
    )  # fmt: skip
    out[STEADY_STATUS] = status
    if status != _SHAPES:
        return STEADY_AFTER_SPLIT
    shape_a = sides[0 if split_info[_INFO_SMOOTHED_A] != 0.0 else 2, : int(split_info[_INFO_COUNT_A])]
    shape_b = sides[1 if split_info[_INFO_SMOOTHED_B] != 0.0 else 3, : int(split_info[_INFO_COUNT_B])]
    swap, confidence, stretch_begin, stretch_end = track_frame(
        shape_a, shape_b, False, t_ns, t_end_ns, max_age_ns, _buffer1(table, _ORDER_STATE, np.int64),
        _buffer2(table, _HIST_RC, np.float64), fixed, split_info[_INFO_SWEEP], exposure_ns, motion_state, motion_log,
        _buffer1(table, _FRACTION, np.float64), constants[9], _buffer3(table, _OUT_POINTS, np.float32),
        _buffer1(table, _OUT_LENGTHS, np.float64), _buffer1(table, _WORK_SEG, np.float64),
    )  # fmt: skip
    out[STEADY_SWAP] = swap
    out[STEADY_CONFIDENCE] = confidence
    out[STEADY_STRETCH_BEGIN] = stretch_begin
    out[STEADY_STRETCH_END] = stretch_end
    if swap < 0:
        return STEADY_AFTER_SHAPES
    return STEADY_DONE
