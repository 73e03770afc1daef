"""Tracking across and within frames: the time order of a frame's two shapes (constant-acceleration prediction of
the tip), the motion model of the free end that places the next frame's region of interest, and the material
points on both shapes (uniform stretch, eqs. 9-12 of the paper); `track_frame` does all three in one call.

They keep their state in caller-owned arrays, so a stream's frame costs one call.

Time-order state (fewer arrays: each array argument costs a dispatch): ``order_state`` (int64,
`ORDER_STATE_SIZE`) holds the times (ns) of the last tip samples oldest first, then [samples held, history ordered
(0/1), rejects in a row] (indices ``ORDER_COUNT``, ``ORDER_ORDERED``, ``ORDER_REJECTS``; the layout is in
`groups`), then `uncross_shapes`' slots; ``hist_rc`` (float64, (HISTORY, 2)) their (row, col).

Motion state: ``motion_state`` (int64, MOTION_FRAMES + 2) holds the mid-exposure times (ns) of up to three
measured frames, then [frames held, last exposure in ns] (``MOTION_COUNT``, ``MOTION_EXPOSURE``);
``motion_log`` (float64, (MOTION_FRAMES + 1, 2)) the log-polar position (log radius, unwrapped angle) of the
tips' midpoint about the fixed end per frame, then (last tip sweep px, unused).
"""

from __future__ import annotations

import math
import sys
from typing import Final

import numpy as np
from numba import boolean, float64, int32, int64, types

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.device.pipeline._kernels.groups import (
    HISTORY,
    MOTION,
    ORDER,
    ORDER_COUNT,
    ORDER_ORDERED,
    ORDER_REJECTS,
    TRACK,
    f4_3d,
    i8_1d,
)
from ropecam.device.pipeline._kernels.tip_sweep import MOTION_FRAMES, restore_tip_sweep
from ropecam.device.pipeline._kernels.uncross import uncross_shapes
from ropecam.shared.jit import f4_1d, f4_2d, f8_1d, f8_1d_ro, f8_2d, kernel

MOTION_COUNT: Final = MOTION_FRAMES
MOTION_EXPOSURE: Final = MOTION_FRAMES + 1
_TWO_PI: Final = 2.0 * math.pi
_LOG_LARGE: Final = math.log(sys.float_info.max / 4.0)
"""Above this real part, exp(z) is computed as exp(z - 1) * e (as CPython's `cmath.exp`)."""
NEAR_UNDECIDED: Final = 0.55
"""The fitted path's time order counts as a coin flip below this confidence (`order_shapes`): nearness may then
overrule it. Measured (simulated ``lab``, ``lab-rolling``, set up from their first 2 s, 240 frames, tuning seed):
the fit's wrong orders had confidence 0.501-0.505; its right ones where nearness disagreed followed a frame whose
tips were 367 px off (nearness not decisive there: 0.15-0.2)."""
NEAR_DECISIVE: Final = 0.5
"""Nearness decides only when the two tips' distances from the last sample differ by this fraction of their
separation or more (at most 1: the last sample on the line through both, beyond one). The fit's wrong orders on
those scenes had 0.68-1.0."""
NEAR_MIN_SEPARATION_PX: Final = 1.0
"""Tips closer together than this are not reordered by nearness (their order is within the tips' noise)."""


# --------------------------------------------------------------------------------------------- time order
@kernel(types.void(i8_1d, f8_2d, int64))
def drop_oldest(times, rows, count):
    """Drop the oldest of `count` samples: move samples ``1 .. count - 1`` of `times` and of `rows` (row, col)
    one place down (the last place is then free)."""
    for i in range(1, count):
        times[i - 1] = times[i]
        rows[i - 1, 0] = rows[i, 0]
        rows[i - 1, 1] = rows[i, 1]


@kernel(int32(f4_2d, boolean, int64, int64, i8_1d, f8_2d))
def remember_tips(shape, single, t_ns, t_end_ns, order_state, hist_rc):
    """Append the tip (last point) of `shape` to the history: at mid-exposure when `single` (one shape, no blur to
    split), else at `t_ns` (the begin shape's tip) -- call it twice, begin then end (`t_ns` = the end's time).
    Keeps the last `HISTORY` samples. Writes `order_state` (times, count) and `hist_rc`; returns the count held or
    INVALID (empty shape)."""
    n = shape.shape[0]
    if n < 1:
        return INVALID
    t = (t_ns + t_end_ns) // 2 if single else t_ns
    count = order_state[ORDER_COUNT]
    if count >= HISTORY:
        drop_oldest(order_state, hist_rc, HISTORY)
        count = HISTORY - 1
    order_state[count] = t
    hist_rc[count, 0] = np.float64(shape[n - 1, 0])
    hist_rc[count, 1] = np.float64(shape[n - 1, 1])
    order_state[ORDER_COUNT] = count + 1
    return count + 1


@kernel(types.UniTuple(float64, 4)(int64, int64, i8_1d, f8_2d, int64))
def _predict(t_ns, t_end_ns, hist_t, hist_rc, count):
    """Predict the tip (row, col) at `t_ns` and `t_end_ns` from the first `count` (>= 1) samples: a least-squares
    quadratic in time through four to six samples, a line through two or three, no motion from one (times scaled
    to [-1, 0]; the normal equations solved by Cramer's rule, a singular system falls back to the line, then to
    the mean). Returns (begin row, begin col, end row, end col)."""
    t0 = hist_t[count - 1]
    span = max(1, t0 - hist_t[0])
    size = 3 if count >= 4 else min(count, 2)
    m0 = m1 = m2 = m3 = m4 = 0.0
    r0 = r1 = r2 = c0 = c1 = c2 = 0.0
    for i in range(count):
        x = (hist_t[i] - t0) / span
        row = hist_rc[i, 0]
        col = hist_rc[i, 1]
        x2 = x * x
        m0 += 1.0
        m1 += x
        m2 += x2
        m3 += x2 * x
        m4 += x2 * x2
        r0 += row
        r1 += x * row
        r2 += x2 * row
        c0 += col
        c1 += x * col
        c2 += x2 * col
    a0 = a1 = a2 = b0 = b1 = b2 = 0.0
    if size == 1:
        a0 = r0 / m0
        b0 = c0 / m0
    else:
        linear = size == 2
        if size == 3:
            a = m2 * m4 - m3 * m3
            b = m1 * m4 - m2 * m3
            c = m1 * m3 - m2 * m2
            det = m0 * a - m1 * b + m2 * c
            if abs(det) < 1e-12:
                linear = True
            else:
                a0 = (r0 * a - r1 * b + r2 * c) / det
                a1 = (m0 * (r1 * m4 - m3 * r2) - r0 * b + m2 * (m1 * r2 - r1 * m2)) / det
                a2 = (m0 * (m2 * r2 - r1 * m3) - m1 * (m1 * r2 - r1 * m2) + r0 * c) / det
                b0 = (c0 * a - c1 * b + c2 * c) / det
                b1 = (m0 * (c1 * m4 - m3 * c2) - c0 * b + m2 * (m1 * c2 - c1 * m2)) / det
                b2 = (m0 * (m2 * c2 - c1 * m3) - m1 * (m1 * c2 - c1 * m2) + c0 * c) / det
        if linear:
            det = m0 * m2 - m1 * m1
            if abs(det) < 1e-12:
                a0, a1 = r0 / m0, 0.0
                b0, b1 = c0 / m0, 0.0
            else:
                a0, a1 = (r0 * m2 - r1 * m1) / det, (m0 * r1 - m1 * r0) / det
                b0, b1 = (c0 * m2 - c1 * m1) / det, (m0 * c1 - m1 * c0) / det
            a2 = b2 = 0.0
    q = (t_ns - t0) / span
    e = (t_end_ns - t0) / span
    return (
        a0 + a1 * q + a2 * q * q,
        b0 + b1 * q + b2 * q * q,
        a0 + a1 * e + a2 * e * e,
        b0 + b1 * e + b2 * e * e,
    )


@kernel(types.Tuple((int32, float64))(f4_2d, f4_2d, boolean, int64, int64, int64, i8_1d, f8_2d))
def order_shapes(shape_a, shape_b, single, t_ns, t_end_ns, max_age_ns, order_state, hist_rc):
    """Put a frame's two shapes (fixed end first, tip last) in time order by continuity with the tip history.

    `single` says the two are one shape (no split). A history whose last sample is more than `max_age_ns` before
    `t_ns` is dropped first (frames lost: too old to extrapolate). Without history, or for a single shape, the
    shapes keep their order. While the history's own order is a guess (one split frame before), the nearest pair
    of (last tips, these tips) orders both frames (the tip moves on from where the last exposure ended; the
    remembered samples are swapped when they were the wrong way round). Otherwise the tips predicted at `t_ns`
    and `t_end_ns` (`_predict`) decide by squared distances, unless that is a coin flip (`NEAR_UNDECIDED`) and
    nearness to the last sample decisively disagrees (`NEAR_DECISIVE`): nearness then decides. A frame whose tips
    lie far from the predicted path (middle of the band, sweep) is left out of the history once (confidence halved
    towards 0.5), and on a second such frame in a row the history starts again from it.

    Updates `order_state` and `hist_rc`. Returns (1 when `shape_b` is the start of the exposure (swapped), 0 when
    `shape_a` is, or INVALID on an empty shape or `t_end_ns <= t_ns`; the confidence, 0.5-1).
    """
    na = shape_a.shape[0]
    nb = shape_b.shape[0]
    if na < 1 or nb < 1 or t_end_ns <= t_ns:
        return INVALID, 0.0
    count = order_state[ORDER_COUNT]
    if count > 0 and t_ns - order_state[count - 1] > max_age_ns:
        count = 0
        order_state[ORDER_COUNT] = 0
        order_state[ORDER_ORDERED] = 0
    if single or count == 0:
        order_state[ORDER_ORDERED] = 1 if single else 0
        if single:
            remember_tips(shape_a, True, t_ns, t_end_ns, order_state, hist_rc)
            return 0, 1.0
        else:
            remember_tips(shape_a, False, t_ns, t_end_ns, order_state, hist_rc)
            remember_tips(shape_b, False, t_end_ns, t_end_ns, order_state, hist_rc)
            return 0, 0.5
    ar = np.float64(shape_a[na - 1, 0])
    ac = np.float64(shape_a[na - 1, 1])
    br = np.float64(shape_b[nb - 1, 0])
    bc = np.float64(shape_b[nb - 1, 1])
    if order_state[ORDER_ORDERED] == 0:
        # The nearest pair of (last frame's tips, this frame's tips); ties keep the earlier sample, then shape a.
        first = count - 2 if count >= 2 and order_state[count - 2] < order_state[count - 1] else count - 1
        best = math.inf
        best_j = 0
        best_mine = 0
        d_low = math.inf
        d_next = math.inf
        for j in range(first, count):
            r = hist_rc[j, 0]
            c = hist_rc[j, 1]
            for mine in range(2):
                d = math.hypot(ar - r, ac - c) if mine == 0 else math.hypot(br - r, bc - c)
                if d < best:
                    best, best_j, best_mine = d, j - first, mine
                if d < d_low:
                    d_low, d_next = d, d_low
                elif d < d_next:
                    d_next = d
        if count - first == 2 and best_j == 0:
            # The remembered begin is nearer: it was the end; swap the two samples' positions.
            for k in range(2):
                hist_rc[count - 2, k], hist_rc[count - 1, k] = hist_rc[count - 1, k], hist_rc[count - 2, k]
        confidence = 0.5 + 0.5 * (d_next - d_low) / (d_next + d_low + 1e-6)
        order_state[ORDER_ORDERED] = 1
        if best_mine == 0:
            remember_tips(shape_a, False, t_ns, t_end_ns, order_state, hist_rc)
            remember_tips(shape_b, False, t_end_ns, t_end_ns, order_state, hist_rc)
            return 0, confidence
        remember_tips(shape_b, False, t_ns, t_end_ns, order_state, hist_rc)
        remember_tips(shape_a, False, t_end_ns, t_end_ns, order_state, hist_rc)
        return 1, confidence
    pbr, pbc, per, pec = _predict(t_ns, t_end_ns, order_state, hist_rc, count)
    # Squared distances: their difference is 2 (b - a) . (pred_end - pred_begin), so the predicted direction of
    # motion decides, not where the prediction lies (a path bias moves both predictions alike).
    straight = (ar - pbr) ** 2 + (ac - pbc) ** 2 + (br - per) ** 2 + (bc - pec) ** 2
    swapped = (br - pbr) ** 2 + (bc - pbc) ** 2 + (ar - per) ** 2 + (ac - pec) ** 2
    confidence = 0.5 + 0.5 * abs(straight - swapped) / (straight + swapped + 1e-6)
    swap = 0 if straight <= swapped else 1
    last_r = hist_rc[count - 1, 0]
    last_c = hist_rc[count - 1, 1]
    # Nearness: between exposures the tip moves on from where the last sample left it. Where the fit (which
    # extrapolates a whipping tip badly across its turns) is a coin flip and nearness decisively disagrees (the
    # last sample lies beyond one tip, along the line through both), nearness decides.
    d_a = math.hypot(ar - last_r, ac - last_c)
    d_b = math.hypot(br - last_r, bc - last_c)
    near_swap = 1 if d_b < d_a else 0
    separation = math.hypot(br - ar, bc - ac)
    if (
        near_swap != swap
        and confidence < NEAR_UNDECIDED
        and separation >= NEAR_MIN_SEPARATION_PX
        and abs(d_a - d_b) >= NEAR_DECISIVE * separation
    ):
        swap = near_swap
        confidence = 0.5 + 0.5 * abs(d_a - d_b) / (d_a + d_b + 1e-6)
    # Judged on what does not depend on the order: where the band's middle is and how far the tip swept.
    pred_sweep = math.hypot(per - pbr, pec - pbc)
    mid_miss = 0.5 * math.hypot(ar + br - pbr - per, ac + bc - pbc - pec)
    sweep_miss = abs(math.hypot(br - ar, bc - ac) - pred_sweep)
    reach = math.hypot(0.5 * (pbr + per) - last_r, 0.5 * (pbc + pec) - last_c)  # how far it extrapolates
    tolerance = 3.0
    if 0.5 * pred_sweep > tolerance:
        tolerance = 0.5 * pred_sweep
    if 0.25 * reach > tolerance:
        tolerance = 0.25 * reach
    odd = mid_miss > tolerance or sweep_miss > tolerance
    if odd and order_state[ORDER_REJECTS] < 1:
        order_state[ORDER_REJECTS] += 1
        return swap, 0.5 + 0.5 * (confidence - 0.5) * 0.5
    if odd:
        order_state[ORDER_COUNT] = 0
        order_state[ORDER_ORDERED] = 0
    order_state[ORDER_REJECTS] = 0
    if swap == 0:
        remember_tips(shape_a, False, t_ns, t_end_ns, order_state, hist_rc)
        remember_tips(shape_b, False, t_end_ns, t_end_ns, order_state, hist_rc)
    else:
        remember_tips(shape_b, False, t_ns, t_end_ns, order_state, hist_rc)
        remember_tips(shape_a, False, t_end_ns, t_end_ns, order_state, hist_rc)
    return swap, confidence


# --------------------------------------------------------------------------------------------- motion model
@kernel(types.UniTuple(float64, 2)(float64, float64))
def _exp_complex(re, im):
    """exp(re + i im) as (real, imaginary), computed as CPython's `cmath.exp` does for finite input."""
    if re > _LOG_LARGE:
        scale = math.exp(re - 1.0)
        return scale * math.cos(im) * math.e, scale * math.sin(im) * math.e
    scale = math.exp(re)
    return scale * math.cos(im), scale * math.sin(im)


@kernel(int32(f4_2d, f4_2d, f4_1d, int64, float64, int64, i8_1d, f8_2d))
def observe_motion(begin, end, fixed, t_mid_ns, sweep_px, exposure_ns, motion_state, motion_log):
    """Add a measured frame to the motion model: the midpoint of the two shapes' tips (independent of their time
    order) about the fixed end `fixed` (row, col), at mid-exposure `t_mid_ns`, in log-polar form (the angle
    unwrapped against the last frame's); the tip sweep is the larger of `sweep_px` (the split's) and the distance
    between the tips (non-finite: 0). A tip on the fixed end (within 1 px), or a time not after the last one,
    starts a new sequence (and the former adds nothing). Keeps `MOTION_FRAMES` frames.

    Writes `motion_state` and `motion_log`; returns the frames held, or INVALID on an empty shape.
    """
    nb = begin.shape[0]
    ne = end.shape[0]
    if nb < 1 or ne < 1:
        return INVALID
    begin_r = np.float64(begin[nb - 1, 0])
    begin_c = np.float64(begin[nb - 1, 1])
    end_r = np.float64(end[ne - 1, 0])
    end_c = np.float64(end[ne - 1, 1])
    sweep = math.hypot(end_r - begin_r, end_c - begin_c)
    if not sweep > sweep_px:
        sweep = sweep_px
    z_re = 0.5 * (begin_r + end_r) - np.float64(fixed[0])
    z_im = 0.5 * (begin_c + end_c) - np.float64(fixed[1])
    h = math.hypot(z_re, z_im)
    count = motion_state[MOTION_COUNT]
    if h < 1.0 or (count > 0 and t_mid_ns <= motion_state[count - 1]):
        count = 0
        motion_state[MOTION_COUNT] = 0
        motion_state[MOTION_EXPOSURE] = 0
        motion_log[MOTION_FRAMES, 0] = 0.0
        if h < 1.0:
            return 0
    # log(z) as CPython's `cmath.log` computes it: near |z| = 1 through log1p, for accuracy.
    if 0.71 <= h <= 1.73:
        am = max(abs(z_re), abs(z_im))
        an = min(abs(z_re), abs(z_im))
        log_re = math.log1p((am - 1.0) * (am + 1.0) + an * an) / 2.0
    else:
        log_re = math.log(h)
    log_im = math.atan2(z_im, z_re)
    if count > 0:  # unwrap the angle
        turns = round((log_im - motion_log[count - 1, 1]) / _TWO_PI)
        log_im -= _TWO_PI * turns
    if count >= MOTION_FRAMES:
        drop_oldest(motion_state, motion_log, count)
        count -= 1
    motion_state[count] = t_mid_ns
    motion_log[count, 0] = log_re
    motion_log[count, 1] = log_im
    motion_state[MOTION_COUNT] = count + 1
    motion_state[MOTION_EXPOSURE] = exposure_ns
    motion_log[MOTION_FRAMES, 0] = sweep if math.isfinite(sweep) else 0.0
    return count + 1


@kernel(types.UniTuple(float64, 3)(int64, int64, i8_1d, f8_2d))
def predict_motion(t_ns, exposure_ns, motion_state, motion_log):
    """Predict the rope's motion from the last measured frame to the frame exposed from `t_ns` for `exposure_ns`:
    the complex factor (real, imaginary) that rotates and scales points about the fixed end, and the uncertainty
    of the free end's position (px).

    With no frame: no motion, no uncertainty. With one (or a time not after the last): no motion, an
    uncertainty of 1.3 x the last sweep scaled from the exposure to the time gap, plus a pixel. With two, a
    constant angular and radial velocity (uncertainty half the predicted step); with three, a constant
    acceleration (uncertainty 0.3 x the step plus the acceleration term); both plus a quarter of the sweep and
    2 px. An implausible step (the radius changing by a factor e or more, a non-finite factor): no direction,
    1.3 x twice the sweep plus a pixel.

    Returns (factor real, factor imaginary, uncertainty px).
    """
    count = motion_state[MOTION_COUNT]
    if count == 0:
        return 1.0, 0.0, 0.0
    gap = float(t_ns + exposure_ns // 2 - motion_state[count - 1])
    sweep = motion_log[MOTION_FRAMES, 0]
    last_exposure = motion_state[MOTION_EXPOSURE]
    if count == 1 or gap <= 0:
        scale = gap / last_exposure if last_exposure > 0 and gap > 0 else 1.0
        return 1.0, 0.0, 1.3 * sweep * max(1.0, scale) + 1.0
    l0_re = motion_log[count - 2, 0]
    l0_im = motion_log[count - 2, 1]
    l1_re = motion_log[count - 1, 0]
    l1_im = motion_log[count - 1, 1]
    dt1 = float(motion_state[count - 1] - motion_state[count - 2])
    rate_re = (l1_re - l0_re) / dt1
    rate_im = (l1_im - l0_im) / dt1
    radius = math.exp(l1_re)
    if count == 2:
        step_re = rate_re * gap
        step_im = rate_im * gap
        f_re, f_im = _exp_complex(step_re, step_im)
        uncertainty = 0.5 * math.hypot(f_re - 1.0, f_im) * radius
    else:
        dt0 = float(motion_state[count - 2] - motion_state[count - 3])
        mean_dt = 0.5 * (dt0 + dt1)
        accel_re = (rate_re - (l0_re - motion_log[count - 3, 0]) / dt0) / mean_dt
        accel_im = (rate_im - (l0_im - motion_log[count - 3, 1]) / dt0) / mean_dt
        half_dt1 = 0.5 * dt1
        step_re = (rate_re + half_dt1 * accel_re) * gap + 0.5 * accel_re * gap * gap
        step_im = (rate_im + half_dt1 * accel_im) * gap + 0.5 * accel_im * gap * gap
        f_re, f_im = _exp_complex(rate_re * gap, rate_im * gap)
        uncertainty = 0.3 * math.hypot(f_re - 1.0, f_im) * radius + math.hypot(accel_re, accel_im) * gap * gap * radius
    f_re, f_im = _exp_complex(step_re, step_im)
    if not (abs(step_re) < 1.0 and math.isfinite(f_re) and math.isfinite(f_im)):
        return 1.0, 0.0, 1.3 * sweep * 2.0 + 1.0
    return f_re, f_im, uncertainty + 0.25 * sweep + 2.0


# --------------------------------------------------------------------------------------------- material points
@kernel(float64(f4_2d, f8_1d))
def _segment_lengths(poly, out_seg):
    """Write the length of each segment of `poly` into `out_seg` and return their sum (the polyline's length,
    eq. (9))."""
    total = 0.0
    for i in range(1, poly.shape[0]):
        # A float32 hypot (libm's hypotf: the double square root of the exact sum of
        # squares, rounded to float32), without its call: 3x faster, the same bits.
        d_r = np.float64(poly[i, 0] - poly[i - 1, 0])
        d_c = np.float64(poly[i, 1] - poly[i - 1, 1])
        seg = np.float64(np.float32(math.sqrt(d_r * d_r + d_c * d_c)))
        out_seg[i - 1] = seg
        total += seg
    return total


@kernel(int32(f4_2d, f8_1d, float64, f8_1d_ro, float64, f4_2d))
def _points_at(poly, seg_px, total, fraction, length0_px, out_points):
    """Write the points of `poly` (segment lengths `seg_px`, length `total`) at arc lengths
    ``fraction * length0_px * total / length0_px`` into `out_points`: arc lengths in increasing order in one walk
    (each search resumes where the last one stopped), others each from the start; beyond the end, the last
    point."""
    n = poly.shape[0]
    m = fraction.shape[0]
    ratio = total / length0_px
    increasing = True
    for k in range(1, m):
        if fraction[k] * length0_px < fraction[k - 1] * length0_px:
            increasing = False
    j0 = 0
    acc0 = 0.0
    for k in range(m):
        target = fraction[k] * length0_px * ratio
        if n == 1 or target <= 0.0:
            out_points[k, 0] = poly[0, 0]
            out_points[k, 1] = poly[0, 1]
            continue
        acc = acc0 if increasing else 0.0
        done = False
        for j in range(j0 if increasing else 0, n - 1):
            seg = seg_px[j]
            if acc + seg > target and seg > 0.0:
                t = (target - acc) / seg
                out_points[k, 0] = poly[j, 0] + t * (poly[j + 1, 0] - poly[j, 0])
                out_points[k, 1] = poly[j, 1] + t * (poly[j + 1, 1] - poly[j, 1])
                done = True
                j0 = j
                acc0 = acc
                break
            acc += seg
        if not done:
            out_points[k, 0] = poly[n - 1, 0]
            out_points[k, 1] = poly[n - 1, 1]
    return m


@kernel(types.Tuple((int32, float64, float64))(f4_2d, f4_2d, boolean, f8_1d_ro, float64, f4_3d, f8_1d, f8_1d))
def track_shapes(begin, end, single, fraction, length0_px, out_points, out_lengths, work_seg):
    """Locate the material points on both shapes of a frame (fixed end first) and their stretch.

    `fraction` holds the points' unstretched arc lengths as fractions of the rope; `length0_px` is the
    unstretched length Lc0 in pixels (<= 0 or not finite: unknown, each shape is taken unstretched). `single`
    says `begin` and `end` are one shape (measured once). A shape of length Lc has its point k at arc length
    ``fraction[k] * Lc0 * Lc / Lc0`` (eqs. 9-12). `work_seg` (at least as long as a shape) holds the segment
    lengths.

    Writes `out_points[0]` (begin) and `out_points[1]` (end), (k, 2) (row, col) each, and `out_lengths` = (Lc
    begin, Lc end). Returns (k or INVALID (an empty shape, buffers too small), stretch Lc/Lc0 of begin, of end).
    """
    m = fraction.shape[0]
    nb = begin.shape[0]
    ne = end.shape[0]
    if nb < 1 or ne < 1 or out_points.shape[0] < 2 or out_points.shape[1] < m or out_lengths.shape[0] < 2:
        return INVALID, math.nan, math.nan
    if work_seg.shape[0] < max(nb, ne):
        return INVALID, math.nan, math.nan
    stretch_begin = math.nan
    stretch_end = math.nan
    for slot in range(2):
        poly = begin if slot == 0 else end
        if slot == 0 or not single:
            lc = _segment_lengths(poly, work_seg)
        length0 = length0_px if length0_px > 0.0 else lc
        out_lengths[slot] = lc
        if length0 > 0.0:
            _points_at(poly, work_seg, lc, fraction, length0, out_points[slot])
            stretch = lc / length0
        else:  # a shape of zero length without a reference: its points all at its start
            for k in range(m):
                out_points[slot, k, 0] = poly[0, 0]
                out_points[slot, k, 1] = poly[0, 1]
            stretch = math.nan
        if slot == 0:
            stretch_begin = stretch
        else:
            stretch_end = stretch
    return m, stretch_begin, stretch_end


# --------------------------------------------------------------------------------------------- the three at once
@kernel(
    types.Tuple((int32, float64, float64, float64))(
        f4_2d, f4_2d, boolean, int64, int64, int64, ORDER, f4_1d, float64, int64, MOTION, float64, TRACK, float64
    )
)  # fmt: skip
def track_frame(
    shape_a, shape_b, single, t_ns, t_end_ns, max_age_ns, order, fixed, sweep_px, exposure_ns, motion, length0_px,
    track, width_px,
):  # fmt: skip
    """`order_shapes`, then `uncross_shapes` (the stretches of a rope whose start and end shapes cross, put in
    time order by continuity, the tip's too when its order was a coin flip; `width_px` the rope's width),
    `restore_tip_sweep` (tips the band's end put together, moved apart by the sweep of their path), `track_shapes`
    on the shapes in time order, then `observe_motion`, in one call: what
    a frame's two shapes (the same array for one shape) give once they are known, exposed from `t_ns` for
    `exposure_ns` (>= 0; `t_end_ns` = `t_ns` + exposure: not later means unknown, no time order, confidence 0.5
    or 1 for one shape, the history untouched). Arguments as those three kernels': `order` is the time order's
    group (`Order`: ``state`` as `order_state`, ``hist_rc``), `motion` the motion model's (`Motion`: ``state``
    and ``log`` as `motion_state` and `motion_log`), `track` the material points' (`Track`: ``fraction``,
    ``out`` as `out_points`, ``lengths_px`` as `out_lengths`, ``work`` as `work_seg`).

    Every size is checked before any state is written. Returns (0 or 1: `shape_b` is the start of the exposure,
    or INVALID (an empty shape, buffers too small; nothing written); the order confidence; the stretch of the
    begin shape; of the end shape).
    """
    order_state = order.state
    hist_rc = order.hist_rc
    motion_state = motion.state
    motion_log = motion.log
    fraction = track.fraction
    out_points = track.out
    out_lengths = track.lengths_px
    work_seg = track.work
    na = shape_a.shape[0]
    nb = shape_b.shape[0]
    m = fraction.shape[0]
    if na < 1 or nb < 1 or work_seg.shape[0] < max(na, nb) or out_lengths.shape[0] < 2:
        return INVALID, 0.0, math.nan, math.nan
    if out_points.shape[0] < 2 or out_points.shape[1] < m:
        return INVALID, 0.0, math.nan, math.nan
    if t_end_ns > t_ns:
        swap, confidence = order_shapes(shape_a, shape_b, single, t_ns, t_end_ns, max_age_ns, order_state, hist_rc)
    else:
        swap, confidence = 0, (1.0 if single else 0.5)
    begin = shape_b if swap == 1 else shape_a
    end = shape_a if swap == 1 else shape_b
    if t_end_ns > t_ns:
        undecided = confidence < NEAR_UNDECIDED
        if uncross_shapes(begin, end, single, t_end_ns, max_age_ns, width_px, undecided, order) > 0 and undecided:
            # The tip's stretch may have changed sides: the time order's history takes the tips as they now are.
            count = order_state[ORDER_COUNT]
            if count >= 2 and order_state[count - 2] == t_ns and order_state[count - 1] == t_end_ns:
                hist_rc[count - 2, 0] = float64(begin[begin.shape[0] - 1, 0])
                hist_rc[count - 2, 1] = float64(begin[begin.shape[0] - 1, 1])
                hist_rc[count - 1, 0] = float64(end[end.shape[0] - 1, 0])
                hist_rc[count - 1, 1] = float64(end[end.shape[0] - 1, 1])
        if not single:
            restore_tip_sweep(begin, end, fixed, t_ns, t_end_ns, max_age_ns, exposure_ns, motion_state, motion_log,
                              order_state, hist_rc, length0_px)  # fmt: skip
    _, stretch_begin, stretch_end = track_shapes(
        begin, end, single, fraction, length0_px, out_points, out_lengths, work_seg
    )
    observe_motion(begin, end, fixed, t_ns + exposure_ns // 2, sweep_px, exposure_ns, motion_state, motion_log)
    return swap, confidence, stretch_begin, stretch_end
