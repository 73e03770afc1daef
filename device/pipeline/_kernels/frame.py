"""A steady frame in one kernel call: the band, the edges and the contour, the split, the time order and the
material points.

Once a stream is steady (the rope's width, polarity, contrast, fixed end and Lc0 are known and the last frame was
found in its band), a frame is four kernel calls (`band_stage`, `detect_and_trace`, `split_frame`, `track_frame`)
with a little Python between them. Each call from Python pays a dispatch (~4-5 us of fixed cost after the frame's
kernels have evicted the dispatcher's data, then ~0.1-0.3 us per array argument) and a return to an interpreter
whose data is cold; `steady_frame` makes the four calls from compiled code and stops where the Python would have
taken another turn (a contour that leaves the band, a split that is not two shapes, shapes `track_frame` does not
take), so the stage's Python goes on from there with the same state as after the same calls made one by one.
"""

from __future__ import annotations

from typing import Any, Final

from numba import boolean, float32, float64, int32, int64

from ropecam.device.pipeline._kernels._common import INVALID, f4_1d_ro
from ropecam.device.pipeline._kernels.band_stage import band_stage
from ropecam.device.pipeline._kernels.offsets import f4_3d
from ropecam.device.pipeline._kernels.split_frame import FRAME_INFO, FRAME_STATE, split_frame
from ropecam.device.pipeline._kernels.stages import detect_and_trace
from ropecam.device.pipeline._kernels.tracking import i8_1d, track_frame
from ropecam.shared.jit import (
    f4_1d,
    f4_2d,
    f4_2d_ro,
    f8_1d,
    f8_1d_ro,
    f8_2d,
    f8_2d_ro,
    i4_1d,
    i4_1d_ro,
    i4_2d,
    kernel,
    u1_2d,
    u1_2d_ro,
)

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


def _signature(frame_type: Any) -> Any:
    return int64(
        frame_type,
        # band_stage's, after its frame-dependent first five
        f4_2d_ro, int64, boolean, boolean, boolean, int64, int64, int64, int64, int64, float64, float64, float64,
        f4_1d, i8_1d, f8_2d, f8_2d, f8_1d, f8_1d, i4_1d, i4_1d, f4_2d,
        # detect_and_trace's, after the frame and the spans
        f4_1d_ro, float32, float32, int32, i4_2d, f4_2d, f4_2d, f4_2d, f4_2d, f4_2d, u1_2d, i4_1d, i4_2d, i4_1d,
        i4_1d, i4_2d, i4_1d, f4_2d, i4_1d,
        # split_frame's, after the contour, the planes, the frame, the weights, the spans, the smoothing buffers
        i4_1d, i4_1d, f8_1d_ro, f8_1d, f8_2d_ro, f4_1d_ro, i4_1d_ro, f4_2d, f4_3d, f8_2d, f4_1d, i4_1d, f4_2d, f8_1d,
        # track_frame's, after what the others gave
        int64, int64, i8_1d, f8_2d, f8_1d_ro, float64, f4_3d, f8_1d, f8_1d,
        f8_1d,
    )  # fmt: skip


# Compiled for a read-only frame (a mapped capture buffer) and a writable one (a frame read from a file), as the
# kernels it calls.
@kernel([_signature(u1_2d_ro), _signature(u1_2d)])
def steady_frame(
    frame,
    prev_points, prev_count, measure, use_profile, predict, t_ns, exposure_ns, margin_px, height, width, gain,
    floor_px, floor_share, fixed, motion_state, motion_log, need_hist, profile, band_state, lo, hi, moved,
    weights, low, high, min_pixels, work_spans, tmp, smooth, gx, gy, mag, edges, edge_stack, labels, stack, start,
    chain, codes, points, counts,
    box_lo, box_hi, params, split_state, curves, table, sweep_index, lines, sides, scratch, turn, idx, out_seg,
    split_info,
    t_end_ns, max_age_ns, order_state, hist_rc, fraction, length0_px, out_points, out_lengths, work_seg,
    out,
):  # fmt: skip
    """One steady frame (exposed from `t_ns` to `t_end_ns`, `exposure_ns`): `band_stage` around the last contour
    (`prev_points`, `prev_count` points) into the spans `lo`/`hi`; `detect_and_trace` of `frame` in them; when
    it found a contour (`points`, `chain`) that touches neither the band's border nor the image's, `split_frame`
    of it (``split_state[5]`` set to its point count, ``split_state[4]`` holding the last frame's sweep as the
    caller set it) with the same planes, frame, weights and spans; when that made the two shapes (views of
    `sides`, smoothed or not as ``split_info`` says), `track_frame` of them with the new sweep, the fixed end
    `fixed` and the motion state of the band.

    Arguments as for those four kernels, in their order, each given once: the edge stage's planes, smoothing
    buffers and weights, the contour's buffers, the spans, the fixed end, the motion state and the exposure are
    shared. `out` (float64, >= STEADY_SLOTS) gets the band's uncertainty, the contour's point count, the split's
    status and `track_frame`'s four results (slots STEADY_*), each as far as the calls went.

    Returns STEADY_DONE, or where it stopped (STEADY_AFTER_CONTOUR, STEADY_AFTER_SPLIT, STEADY_AFTER_SHAPES):
    everything before that point is done and written exactly as the calls one by one write it, nothing after it;
    or INVALID, before any call, when `out`, `split_state` or `split_info` is too short.
    """
    if out.shape[0] < STEADY_SLOTS or split_state.shape[0] < FRAME_STATE or split_info.shape[0] < FRAME_INFO:
        return INVALID
    out[STEADY_MOTION] = band_stage(
        prev_points, prev_count, measure, use_profile, predict, t_ns, exposure_ns, margin_px, height, width, gain,
        floor_px, floor_share, fixed, motion_state, motion_log, need_hist, profile, band_state, lo, hi, moved,
    )  # fmt: skip
    n = detect_and_trace(
        frame, lo, hi, weights, low, high, min_pixels, work_spans, tmp, smooth, gx, gy, mag, edges, edge_stack,
        labels, stack, start, chain, codes, points, counts,
    )  # fmt: skip
    out[STEADY_POINTS] = n
    if n <= 0 or counts[1] != 0 or counts[2] != 0:
        return STEADY_AFTER_CONTOUR
    split_state[_STATE_POINTS] = n
    status = split_frame(
        points, chain, mag, gx, gy, frame, weights, lo, hi, box_lo, box_hi, tmp, smooth, params, split_state, curves,
        table, sweep_index, lines, sides, scratch, turn, idx, out_seg, split_info,
    )  # fmt: skip
    out[STEADY_STATUS] = status
    if status != _SHAPES:
        return STEADY_AFTER_SPLIT
    shape_a = sides[0 if split_info[_INFO_SMOOTHED_A] != 0.0 else 2, : int(split_info[_INFO_COUNT_A])]
    shape_b = sides[1 if split_info[_INFO_SMOOTHED_B] != 0.0 else 3, : int(split_info[_INFO_COUNT_B])]
    swap, confidence, stretch_begin, stretch_end = track_frame(
        shape_a, shape_b, False, t_ns, t_end_ns, max_age_ns, order_state, hist_rc, fixed, split_info[_INFO_SWEEP],
        exposure_ns, motion_state, motion_log, fraction, length0_px, out_points, out_lengths, work_seg,
    )  # fmt: skip
    out[STEADY_SWAP] = swap
    out[STEADY_CONFIDENCE] = confidence
    out[STEADY_STRETCH_BEGIN] = stretch_begin
    out[STEADY_STRETCH_END] = stretch_end
    if swap < 0:
        return STEADY_AFTER_SHAPES
    return STEADY_DONE
