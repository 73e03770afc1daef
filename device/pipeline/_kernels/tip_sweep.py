"""The tip's sweep during the exposure from its path over the last frames, where the band's end cannot show it.

A tip that moves along its own axis during the exposure leaves no corner at the band's far end: the band ends in a
ramp as long as the along-axis sweep, and both shapes' tips are read at the ramp's middle (the half-level crossing
of `extend_to_band_end`). Each tip is then off by half the sweep (3-7 px on the ``lab`` swing's whipping frames),
while their midpoint is right: it is the tip at mid-exposure. The midpoints of the last frames (the motion
model's log) and of this frame give the tip's velocity at mid-exposure (a quadratic through three midpoints, a
line through two); velocity x exposure is the sweep. Where the two measured tips lie much closer together than
that sweep, they are moved apart to the midpoint -/+ half the sweep (`restore_tip_sweep`). Where the two shapes'
lengths already disagree by more than the length self-check accepts, one shape ran on to the band's far end and
the midpoint is not the tip at mid-exposure: nothing moves, and the self-check reports the mismatch.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float64, int64, types

from ropecam.device.pipeline._kernels.groups import ORDER_COUNT, i8_1d
from ropecam.shared.jit import f4_1d, f4_2d, f8_2d, kernel

MOTION_FRAMES: Final = 3
"""Measured frames kept by the motion model (`observe_motion`; its layout is `tracking`'s docstring)."""
MIN_SWEEP_PX: Final = 2.0
"""A sweep estimated shorter than this is left as measured (within the tips' own noise), unless the path slides the
tip along its own axis (`_slid`, from `MIN_SLIDE_PX`)."""
COLLAPSED: Final = 0.6
"""The measured tips count as collapsed when they lie closer than this fraction of the estimated sweep: the split
lost at least 40 % of it. Where the band's corners resolve the sweep (a sideways motion, a slanted end that
`correct_slant` reads), the measured and estimated sweeps agree within about 10 % on ``lab`` (simulated, tuning
seed, 240 frames), and the measured ones stand."""
SHIFT_SPAN: Final = 3.0
"""A tip moved by d carries the shape's last ``max(SHIFT_SPAN d, SHIFT_MIN_PX)`` of arc along with it, linearly
less towards the fixed end: the shape never folds back on itself (the points move by at most a third of their
spacing more than their neighbours)."""
SHIFT_MIN_PX: Final = 4.0
MIN_SLIDE_PX: Final = 1.0
SLIDE_SHARE: Final = 0.5
"""A tip whose path slides along its own axis by at least `MIN_SLIDE_PX`, and by at least `SLIDE_SHARE` of its
sweep, counts as collapsed when the measured tips lie apart along that axis by less than `COLLAPSED` of the
path's slide, and across it by no more than the path's whole sweep plus `SLIDE_ACROSS_PX`: the band's corners
show the sweep across the rope, not along it (simulated late swing, tuning seed: frames 13 and 47 slid 3.4 and 2.5 px
with a sideways sweep of 2.8-2.9 px, the tips 0.8-1.4 px off, not collapsed as a whole; frames 17-18 slid 1.4-1.8
px, below `MIN_SWEEP_PX`). Tips farther apart than that, or in the reverse order along the axis by as much, were
measured apart: they are not a collapse (review of session 17)."""
SLIDE_ACROSS_PX: Final = 2.0
"""How much farther apart across the axis than the path's whole sweep (about a lab rope's width) tips that `_slid`
moves may lie: tips farther apart were measured apart, the path is not theirs."""
MAX_GROWTH: Final = 2.0
SAME_PATH_PX: Final = 4.0
"""A sweep from the path larger than ``MAX_GROWTH`` x the last frame's sweep (the motion model's) + this is no
path (the model's midpoints read about another fixed end): nothing moves."""
LENGTH_MISMATCH: Final = 0.03
"""Largest difference of the two shapes' lengths, as a fraction of Lc0, with which collapsed tips are moved: the
default ``checks.length_mismatch`` (`ChecksConfig`), beyond which the frame is flagged. Moving the tips changes the
two lengths by about -/+ half the sweep and can bring a flagged frame under it. Measured (simulated, tuning seed):
on the soft rig's whip (4-6 px along-axis sweeps) the collapsed shapes differ by 2.4-5.8 px (Lc0 407 px: 12 px
accepted), on the paper method's ``rig`` frames by 0.8-5.7 px (Lc0 403 px); on ``paper-soft`` 15 ms frames 45-46
the begin shape ran to the band's far end (15-18 px too long, tips 3-4 px apart against a 20-22 px sweep) and they
differ by 16-19 px (Lc0 364 px: 11 accepted): moved, the tips were 5-11 px off and the frame passed every check."""


@kernel(types.UniTuple(float64, 2)(f4_1d, int64, int64, int64, i8_1d, f8_2d, float64, float64))
def sweep_from_path(fixed, t_mid_ns, exposure_ns, max_age_ns, motion_state, motion_log, mid_r, mid_c):
    """Return the tip's sweep (row, col: end minus start) during the exposure of `exposure_ns` centred on
    `t_mid_ns`, from the tips' midpoints the motion model holds (`motion_state`, `motion_log`: log-polar about the
    fixed end, at their mid-exposure times) and this frame's midpoint (`mid_r`, `mid_c`), about the fixed end
    `fixed` (row, col): the derivative at `t_mid_ns` of the quadratic through the last two held midpoints and this
    one (the line through one held midpoint and this one), times the exposure. (nan, nan) with no held frame, an
    unknown exposure, or a held frame not before `t_mid_ns` or older than `max_age_ns`.
    """
    count = motion_state[MOTION_FRAMES]
    if count < 1 or exposure_ns <= 0 or count > MOTION_FRAMES:
        return math.nan, math.nan
    t2 = motion_state[count - 1]
    if not (0 < t_mid_ns - t2 <= max_age_ns):
        return math.nan, math.nan
    fr = float64(fixed[0])
    fc = float64(fixed[1])
    radius = math.exp(motion_log[count - 1, 0])
    m2_r = fr + radius * math.cos(motion_log[count - 1, 1])
    m2_c = fc + radius * math.sin(motion_log[count - 1, 1])
    h2 = float64(t_mid_ns - t2)
    if count < 2 or not (0 < t2 - motion_state[count - 2] <= max_age_ns):
        scale = exposure_ns / h2
        return (mid_r - m2_r) * scale, (mid_c - m2_c) * scale
    t1 = motion_state[count - 2]
    radius = math.exp(motion_log[count - 2, 0])
    m1_r = fr + radius * math.cos(motion_log[count - 2, 1])
    m1_c = fc + radius * math.sin(motion_log[count - 2, 1])
    h1 = float64(t_mid_ns - t1)
    # Lagrange's derivative at the last node of the quadratic through (t1, m1), (t2, m2), (t, m).
    w1 = h2 / ((h1 - h2) * h1)
    w2 = -h1 / ((h1 - h2) * h2)
    w3 = (h1 + h2) / (h1 * h2)
    return (
        (w1 * m1_r + w2 * m2_r + w3 * mid_r) * exposure_ns,
        (w1 * m1_c + w2 * m2_c + w3 * mid_c) * exposure_ns,
    )


@kernel(types.UniTuple(float64, 3)(int64, int64, int64, i8_1d, f8_2d, float64, float64))
def sweep_from_history(t_mid_ns, exposure_ns, max_age_ns, order_state, hist_rc, mid_r, mid_c):
    """Return the tip's sweep (row, col: end minus start) during the exposure of `exposure_ns` centred on
    `t_mid_ns` from the time order's history (`order_state`, `hist_rc`: tip samples, oldest first) where the motion
    model holds no frame: the line from the last earlier frame's tip at its mid-exposure (the midpoint of its
    begin and end samples, or its one sample) to this frame's midpoint (`mid_r`, `mid_c`), times the exposure; and
    that frame's own sweep (the distance of its two samples; 0 for one). (nan, nan, 0) without such a sample no
    older than `max_age_ns`."""
    count = order_state[ORDER_COUNT]
    start = t_mid_ns - exposure_ns // 2
    j = count - 1
    while j >= 0 and order_state[j] >= start:  # this frame's own samples (when the time order took them)
        j -= 1
    if j < 0 or not (0 < t_mid_ns - order_state[j] <= max_age_ns):
        return math.nan, math.nan, 0.0
    t_prev = float64(order_state[j])
    p_r = hist_rc[j, 0]
    p_c = hist_rc[j, 1]
    own = 0.0
    if j >= 1 and 0 < order_state[j] - order_state[j - 1] <= exposure_ns:  # a begin and end pair of one frame
        own = math.hypot(p_r - hist_rc[j - 1, 0], p_c - hist_rc[j - 1, 1])
        t_prev = 0.5 * (t_prev + float64(order_state[j - 1]))
        p_r = 0.5 * (p_r + hist_rc[j - 1, 0])
        p_c = 0.5 * (p_c + hist_rc[j - 1, 1])
    scale = exposure_ns / (t_mid_ns - t_prev)
    return (mid_r - p_r) * scale, (mid_c - p_c) * scale, own


@kernel(float64(f4_2d))
def shape_length(shape):
    """Return the arc length (px) of the polyline `shape` (n, 2) (0 for fewer than two points)."""
    total = 0.0
    for k in range(1, shape.shape[0]):
        total += math.hypot(
            float64(shape[k, 0]) - float64(shape[k - 1, 0]), float64(shape[k, 1]) - float64(shape[k - 1, 1])
        )
    return total


@kernel(types.void(f4_2d, float64, float64))
def shift_tip(shape, d_r, d_c):
    """Move the last point of `shape` (row, col) by (`d_r`, `d_c`) and the points before it by that times a weight
    falling linearly to 0 over the last ``max(SHIFT_SPAN |d|, SHIFT_MIN_PX)`` of arc, in place."""
    n = shape.shape[0]
    if n < 1:
        return
    span = max(SHIFT_SPAN * math.hypot(d_r, d_c), SHIFT_MIN_PX)
    back = 0.0
    k = n - 1
    while k >= 0:
        weight = 1.0 - back / span
        if weight <= 0.0:
            break
        if k > 0:
            back += math.hypot(
                float64(shape[k, 0]) - float64(shape[k - 1, 0]), float64(shape[k, 1]) - float64(shape[k - 1, 1])
            )
        shape[k, 0] = np.float32(float64(shape[k, 0]) + weight * d_r)
        shape[k, 1] = np.float32(float64(shape[k, 1]) + weight * d_c)
        k -= 1


@kernel(boolean(f4_2d, f4_2d, float64, float64, float64))
def _slid(begin, end, s_r, s_c, sweep):
    """Whether the path's sweep (`s_r`, `s_c`; length `sweep`) slides the tip along its axis (the mean direction
    of both shapes' last three points) by `MIN_SLIDE_PX` and `SLIDE_SHARE` of the sweep or more, and the measured
    tips of `begin` and `end` lie apart along that axis (either way) by less than `COLLAPSED` of it, and across it by
    at most the whole sweep plus `SLIDE_ACROSS_PX`."""
    nb = begin.shape[0]
    ne = end.shape[0]
    if nb < 3 or ne < 3 or not sweep >= MIN_SLIDE_PX:
        return False
    u_r = float64(begin[nb - 1, 0]) - float64(begin[nb - 3, 0]) + float64(end[ne - 1, 0]) - float64(end[ne - 3, 0])
    u_c = float64(begin[nb - 1, 1]) - float64(begin[nb - 3, 1]) + float64(end[ne - 1, 1]) - float64(end[ne - 3, 1])
    norm = math.hypot(u_r, u_c)
    if not norm > 0.0:
        return False
    slide = (s_r * u_r + s_c * u_c) / norm
    if not (abs(slide) >= MIN_SLIDE_PX and abs(slide) >= SLIDE_SHARE * sweep):
        return False
    d_r = float64(end[ne - 1, 0]) - float64(begin[nb - 1, 0])
    d_c = float64(end[ne - 1, 1]) - float64(begin[nb - 1, 1])
    measured = (d_r * u_r + d_c * u_c) / norm
    across = abs(d_c * u_r - d_r * u_c) / norm
    return abs(measured) < COLLAPSED * abs(slide) and across <= sweep + SLIDE_ACROSS_PX


@kernel(boolean(f4_2d, f4_2d, f4_1d, int64, int64, int64, int64, i8_1d, f8_2d, i8_1d, f8_2d, float64))
def restore_tip_sweep(
    begin, end, fixed, t_ns, t_end_ns, max_age_ns, exposure_ns, motion_state, motion_log, order_state, hist_rc,
    length0_px,
):  # fmt: skip
    """Where the two shapes' tips (`begin`, `end`: in time order, fixed end first) lie closer together than
    `COLLAPSED` x the sweep their path gives (`sweep_from_path`, at least `MIN_SWEEP_PX`), put them at their
    midpoint -/+ half that sweep (`shift_tip`, in place; where the motion model holds no frame, the sweep from the
    time order's history, `sweep_from_history`), and the time order's last two tip samples (this frame's,
    when `order_shapes` remembered them: times `t_ns` and `t_end_ns`) with them. Nothing moves when that sweep
    is far beyond the last frame's (`MAX_GROWTH`, `SAME_PATH_PX`: the motion model was measured about another
    fixed end), nor when the shapes' lengths differ by more than `LENGTH_MISMATCH` x `length0_px` (Lc0; negative:
    not known, not checked). Returns whether it moved them.

    `fixed` is the fixed end (row, col); `exposure_ns` the exposure (the midpoint is at ``t_ns + exposure_ns //
    2``, as `observe_motion` takes it); `motion_state`/`motion_log` the motion model before this frame is added;
    `order_state`/`hist_rc` the time order's history.
    """
    nb = begin.shape[0]
    ne = end.shape[0]
    if nb < 2 or ne < 2 or exposure_ns <= 0 or t_end_ns <= t_ns:
        return False
    br = float64(begin[nb - 1, 0])
    bc = float64(begin[nb - 1, 1])
    er = float64(end[ne - 1, 0])
    ec = float64(end[ne - 1, 1])
    mid_r = 0.5 * (br + er)
    mid_c = 0.5 * (bc + ec)
    s_r, s_c = sweep_from_path(fixed, t_ns + exposure_ns // 2, exposure_ns, max_age_ns, motion_state, motion_log,
                               mid_r, mid_c)  # fmt: skip
    last_sweep = motion_log[MOTION_FRAMES, 0]
    if math.isnan(s_r) and motion_state[MOTION_FRAMES] == 0:
        # The motion model was cleared (a frame without shapes, a flagged one): the time order's history still
        # holds the last frames' tips.
        s_r, s_c, last_sweep = sweep_from_history(t_ns + exposure_ns // 2, exposure_ns, max_age_ns, order_state,
                                                  hist_rc, mid_r, mid_c)  # fmt: skip
    sweep = math.hypot(s_r, s_c)
    if not (sweep >= MIN_SWEEP_PX and math.hypot(er - br, ec - bc) < COLLAPSED * sweep) and not _slid(
        begin, end, s_r, s_c, sweep
    ):
        return False
    # The motion model keeps its midpoints about the fixed end of their time: read about another one (the fixed
    # end was found again), they give a path that jumps. A sweep far beyond the last frame's is no path.
    if sweep > MAX_GROWTH * last_sweep + SAME_PATH_PX:
        return False
    if length0_px > 0.0 and abs(shape_length(begin) - shape_length(end)) > LENGTH_MISMATCH * length0_px:
        return False
    count = order_state[ORDER_COUNT]
    shift_tip(begin, mid_r - 0.5 * s_r - br, mid_c - 0.5 * s_c - bc)
    shift_tip(end, mid_r + 0.5 * s_r - er, mid_c + 0.5 * s_c - ec)
    if count >= 2 and order_state[count - 2] == t_ns and order_state[count - 1] == t_end_ns:
        hist_rc[count - 2, 0] = float64(begin[nb - 1, 0])
        hist_rc[count - 2, 1] = float64(begin[nb - 1, 1])
        hist_rc[count - 1, 0] = float64(end[ne - 1, 0])
        hist_rc[count - 1, 1] = float64(end[ne - 1, 1])
    return True
