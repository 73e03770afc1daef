"""The self-checks of a measured frame in one call: the tips' predicted position, then every check and its measure.

The thresholds and the measures travel as one-record structured arrays (`CHECK_THRESHOLDS`, `CHECK_QUALITY`), read
and written by field name (``record["name"]``, which NumPy also takes: the kernels run without the JIT too). The
reason codes are the wire's (`ropecam.shared.protocol.quality.Reason`; a test keeps them equal).
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float64, int64, types
from numba.np.numpy_support import from_dtype

from ropecam.device.pipeline._kernels.static_mask import MASK_FREE
from ropecam.device.pipeline._kernels.tip_sweep import sweep_from_history, sweep_from_path
from ropecam.device.pipeline._kernels.tracking import MOTION_COUNT, i8_1d, predict_motion
from ropecam.shared.jit import f4_1d, f4_2d, f4_2d_ro, f8_1d, f8_2d, kernel, u1_2d_ro

CHECK_NONE: Final = 0
"""Every check passed."""
CHECK_LENGTH: Final = 1
CHECK_WIDTH: Final = 2
CHECK_FIXED_END: Final = 3
CHECK_TIP_MOTION: Final = 4
CHECK_ORDER: Final = 5
CHECK_NO_BLUR: Final = 6
CHECK_TIP_MASKED: Final = 7
CHECK_FALLBACK_SWEEP: Final = 8
CHECK_TIP_KINK: Final = 9
CHECK_TIP_AT_FIXED_END: Final = 10
"""Checked by `SelfChecks` (Python) on frames without a motion prediction, as is `CHECK_TIP_CORNER`'s tip distance
from its corner (`check_frame` checks its coinciding corners on every split)."""
CHECK_TIP_CORNER: Final = 11
CHECK_TIP_SHORT: Final = 12
CHECK_FIXED_END_GUESS: Final = 13
"""Checked by `ResultFinisher` (Python) after the others, on frames before the fixed end is confirmed (never a steady
frame's: the fixed end has settled by then)."""

CHECK_THRESHOLDS: Final = np.dtype(
    [
        ("length_tolerance", np.float64),
        ("length_mismatch", np.float64),
        ("width_tolerance", np.float64),
        ("fixed_end_widths", np.float64),
        ("fixed_end_floor_px", np.float64),
        ("tip_motion_factor", np.float64),
        ("tip_motion_floor_px", np.float64),
        ("min_order_confidence", np.float64),
        ("no_blur_px", np.float64),
        ("min_blur_evidence", np.float64),
        ("tip_mask_widths", np.float64),
        ("tip_mask_floor_px", np.float64),
        ("fallback_sweep_widths", np.float64),
        ("tip_kink_widths", np.float64),
        ("tip_kink_deg", np.float64),
        ("tip_corner_widths", np.float64),
        ("tip_short_widths", np.float64),
        ("tip_short_floor_px", np.float64),
    ]
)
"""The checks' thresholds (`ChecksConfig`'s numbers), one record."""
CHECK_QUALITY: Final = np.dtype(
    [
        ("length_ratio", np.float64),
        ("width_ratio", np.float64),
        ("fixed_end_px", np.float64),
        ("tip_separation_px", np.float64),
        ("tip_motion_px", np.float64),
        ("tip_motion_limit_px", np.float64),
        ("blur_evidence", np.float64),
    ]
)
"""The checks' measures of one frame (the wire's `QUALITY_KEYS`, in its order), one record."""

_thresholds_ro = types.Array(from_dtype(CHECK_THRESHOLDS), 1, "C", readonly=True)
_quality = types.Array(from_dtype(CHECK_QUALITY), 1, "C")


_NO_AGE_LIMIT: Final = 1 << 62
"""The motion model's frames are as fresh as the model keeps them (it starts again after a gap)."""


@kernel(boolean(int64, int64, i8_1d, f8_2d, f4_1d, f8_1d))
def predict_tips(t_ns, exposure_ns, motion_state, motion_log, fixed, out_predicted):
    """Write where the motion model (`motion_state`, `motion_log`) puts the tips' midpoint (row, col) in the frame
    exposed from `t_ns` for `exposure_ns`, about the fixed end (row, col), the prediction's error (px), and how far
    the tip sweeps during that exposure along its path (px: `sweep_from_path` through the model's last midpoints
    and the predicted one; nan for an unknown exposure) into `out_predicted` (4,). With fewer than two frames in
    the model: nan error and sweep (no prediction); returns whether there is a prediction."""
    count = motion_state[MOTION_COUNT]
    if count < 2:
        out_predicted[2] = math.nan
        out_predicted[3] = math.nan
        return False
    f_re, f_im, error_px = predict_motion(t_ns, exposure_ns, motion_state, motion_log)
    radius = math.exp(motion_log[count - 1, 0])
    angle = motion_log[count - 1, 1]
    z_re = radius * math.cos(angle)
    z_im = radius * math.sin(angle)
    out_predicted[0] = float64(fixed[0]) + f_re * z_re - f_im * z_im
    out_predicted[1] = float64(fixed[1]) + f_re * z_im + f_im * z_re
    out_predicted[2] = error_px
    s_r, s_c = sweep_from_path(fixed, t_ns + exposure_ns // 2, exposure_ns, _NO_AGE_LIMIT, motion_state, motion_log,
                               out_predicted[0], out_predicted[1])  # fmt: skip
    out_predicted[3] = math.hypot(s_r, s_c)
    return True


@kernel(boolean(int64, int64, int64, i8_1d, f8_2d, f4_2d, f8_1d))
def predict_sweep_from_history(t_mid_ns, exposure_ns, max_age_ns, order_state, hist_rc, shape, out_predicted):
    """Write how far the tip sweeps during the exposure of `exposure_ns` centred on `t_mid_ns` into
    ``out_predicted[3]`` where the motion model gives no sweep (nan there: cleared by a flagged frame, a gap):
    `sweep_from_history` from the time order's history (`order_state`, `hist_rc`: the last earlier frame's tip no
    older than `max_age_ns`) to the tip of `shape`, one shape's tip being the tip at mid-exposure (the split's
    static fallback, the band's middle). Leaves a sweep already there; returns whether it wrote one."""
    n = shape.shape[0]
    if n < 1 or exposure_ns <= 0 or not math.isnan(out_predicted[3]):
        return False
    s_r, s_c, _ = sweep_from_history(t_mid_ns, exposure_ns, max_age_ns, order_state, hist_rc,
                                     float64(shape[n - 1, 0]), float64(shape[n - 1, 1]))  # fmt: skip
    if math.isnan(s_r):
        return False
    out_predicted[3] = math.hypot(s_r, s_c)
    return True


# The shapes as the splitter leaves them (writable) or read-only views; the fixed end is the workspace's.
_CHECK_SIGNATURES = int64(
    f4_2d_ro,
    f4_2d_ro,
    f4_1d,
    f8_1d,
    *(float64,) * 5,
    int64,
    boolean,
    float64,
    u1_2d_ro,
    f4_2d_ro,
    _thresholds_ro,
    _quality,
)
"""`check_frame`'s one signature: writable shapes are taken through Numba's safe mutable-to-read-only conversion."""

TIP_DIRECTION_PX: Final = 3.0
"""The tip's direction is read over this much of the shape's end (px)."""


TIP_END_CLEAR_PX: Final = 1.0
"""How far (px) past a free tip's end cap (half the rope's width) the band's blurred end may still show (the 1 px
smoothing and the lens blur): `tip_end_seen` reads the learned scene only beyond it (simulated scratches, dust
and texture rows, tuning seed: up to 1 px past tips within 0.3 px of the truth, 2-4 px past tips 1.5-3 px short
of it)."""
TIP_END_BEYOND_WIDTHS: Final = 2.0
"""`tip_end_seen` reads the learned scene this many rope widths beyond the ``tip_masked`` reach: a rope the mask
cut goes on past the masked pixels."""


@kernel(types.UniTuple(float64, 4)(f4_2d_ro))
def tip_direction(shape):
    """Return the free tip of `shape` (row, col; its last point) and the unit direction of its last
    `TIP_DIRECTION_PX` of arc (tip row, tip col, direction row, direction col); the direction is (0, 0) when the
    shape has fewer than two points or no length there."""
    n = shape.shape[0]
    if n < 2:
        return (math.nan, math.nan, 0.0, 0.0)
    tr = float64(shape[n - 1, 0])
    tc = float64(shape[n - 1, 1])
    k = n - 2
    while k > 0 and math.hypot(tr - float64(shape[k, 0]), tc - float64(shape[k, 1])) < TIP_DIRECTION_PX:
        k -= 1
    dr = tr - float64(shape[k, 0])
    dc = tc - float64(shape[k, 1])
    norm = math.hypot(dr, dc)
    if norm == 0.0:
        return (tr, tc, 0.0, 0.0)
    return (tr, tc, dr / norm, dc / norm)


@kernel(types.UniTuple(int64, 2)(float64, float64, float64, float64, float64, float64))
def tip_pixel(tr, tc, dr, dc, along, side):
    """The pixel (row, col) `along` px from the tip (`tr`, `tc`) along its unit direction (`dr`, `dc`) and `side` px
    across it (towards (-`dc`, `dr`)): the sampling of `tip_mask_distance` and `tip_end_seen`."""
    return math.floor(tr + along * dr - side * dc + 0.5), math.floor(tc + along * dc + side * dr + 0.5)


@kernel(float64(f4_2d_ro, u1_2d_ro, float64, float64))
def tip_mask_distance(shape, mask, width_px, reach_px):
    """Return where (px along the shape's direction at its free end, `tip_direction`; negative: behind the tip) the
    static `mask` (not `MASK_FREE`) lies near the free tip of `shape` (row, col; the last point): sampled every
    half pixel from a rope's `width_px` behind the tip to `reach_px` beyond it, out to a width either side of the
    shape's line (a tip read just past a masked cable the rope crossed ends beside or behind it): the first
    masked pixel met walking from behind the tip forward (callers read only whether one is found); nan when no
    masked pixel lies there (or the shape has fewer than two points).
    Pixels outside `mask` (a 1x1 placeholder: no mask) are free."""
    if not reach_px > 0.0:
        return math.nan
    tr, tc, dr, dc = tip_direction(shape)
    if dr == 0.0 and dc == 0.0:
        return math.nan
    height = mask.shape[0]
    width = mask.shape[1]
    half = 0.5 * width_px
    behind = int(width_px * 2.0)
    for step in range(-behind, int(reach_px * 2.0) + 1):
        along = 0.5 * step
        for side in (-width_px, -half, 0.0, half, width_px):
            r, c = tip_pixel(tr, tc, dr, dc, along, side)
            if 0 <= r < height and 0 <= c < width and mask[r, c] != MASK_FREE:
                return along
    return math.nan


@kernel(boolean(f4_2d_ro, u1_2d_ro, u1_2d_ro, u1_2d_ro, float64, float64, float64, float64))
def tip_end_seen(shape, frame, low, high, width_px, reach_px, still_dn, relative):
    """Whether `frame` shows the free tip of `shape` (row, col; the last point) as the rope's end: at the tip or up
    to a pixel behind it (the tip is read at the band's half level) some pixel across the rope's `width_px` lies
    outside its learned grey-level range [`low`, `high`] (the rope is there), and from half a width +
    `TIP_END_CLEAR_PX` to `reach_px` + `TIP_END_BEYOND_WIDTHS` widths beyond it, along the shape's direction at
    its end (`tip_direction`, sampled as `tip_mask_distance` samples it), every pixel lies inside a still pixel's
    learned range (``high - low <= still_dn + relative * high``): the view there is as it was learned, so the
    static mask hides no rope there. A pixel the rope crossed while the mask was learned has a range as wide as
    the rope's contrast and shows nothing. False when the shape has fewer than two points, a sample lies outside
    the image or the arrays are not of one shape."""
    height = frame.shape[0]
    width = frame.shape[1]
    if low.shape[0] != height or low.shape[1] != width or high.shape[0] != height or high.shape[1] != width:
        return False
    tr, tc, dr, dc = tip_direction(shape)
    if dr == 0.0 and dc == 0.0:
        return False
    half = 0.5 * width_px
    steps = int((reach_px + TIP_END_BEYOND_WIDTHS * width_px) * 2.0) + 1
    clear_px = half + TIP_END_CLEAR_PX
    on_rope = False
    for step in range(-2, steps):
        along = 0.5 * step
        if step > 0 and along < clear_px:
            continue
        for side in (-half, 0.0, half):
            r, c = tip_pixel(tr, tc, dr, dc, along, side)
            if not (0 <= r < height and 0 <= c < width):
                return False
            v = int64(frame[r, c])
            lo = int64(low[r, c])
            hi = int64(high[r, c])
            inside = lo <= v <= hi
            if step <= 0:
                on_rope = on_rope or not inside
            elif not inside or hi - lo > still_dn + relative * hi:
                return False
    return on_rope


@kernel(float64(f4_2d_ro, float64))
def tip_turn_deg(shape, reach_px):
    """Return how far (degrees) the direction of `shape` (row, col; its free tip last) turns at its end: the angle
    between the chords of its last `reach_px` of arc and of the `reach_px` before them; nan when the shape is
    shorter than twice `reach_px` (or `reach_px` is not positive)."""
    n = shape.shape[0]
    if n < 3 or not reach_px > 0.0:
        return math.nan
    tr = float64(shape[n - 1, 0])
    tc = float64(shape[n - 1, 1])
    mr = math.nan
    mc = math.nan
    arc = 0.0
    for k in range(n - 1, 0, -1):
        r0 = float64(shape[k, 0])
        c0 = float64(shape[k, 1])
        r1 = float64(shape[k - 1, 0])
        c1 = float64(shape[k - 1, 1])
        step = math.hypot(r1 - r0, c1 - c0)
        target = reach_px if math.isnan(mr) else 2.0 * reach_px
        while step > 0.0 and arc + step >= target:
            f = (target - arc) / step
            if math.isnan(mr):
                mr = r0 + f * (r1 - r0)
                mc = c0 + f * (c1 - c0)
                target = 2.0 * reach_px
                continue
            br = r0 + f * (r1 - r0) - mr
            bc = c0 + f * (c1 - c0) - mc
            ar = tr - mr
            ac = tc - mc
            norm = math.hypot(ar, ac) * math.hypot(br, bc)
            if norm == 0.0:
                return math.nan
            # b points back from the middle point: on a straight shape a . b = -|a| |b|, a turn of 0 degrees
            cosine = -(ar * br + ac * bc) / norm
            return math.degrees(math.acos(min(1.0, max(-1.0, cosine))))
        arc += step
    return math.nan


@kernel(boolean(f4_2d_ro, int64, f4_1d, f4_2d))
def contour_far_end(points, n, fixed, out_far):
    """Write the point of the closed contour's first `n` `points` (row, col) farthest from the fixed end `fixed`
    (row, col) into ``out_far[0]`` (the band's far end, `check_frame`'s ``tip_short``); return whether one was
    written (nan left when `n` < 1, `n` exceeds the points or `fixed` is nan; nothing when `out_far` has no row)."""
    if out_far.shape[0] < 1:
        return False
    out_far[0, 0] = math.nan
    out_far[0, 1] = math.nan
    if n < 1 or n > points.shape[0]:
        return False
    fr = float64(fixed[0])
    fc = float64(fixed[1])
    best = -1.0
    for k in range(n):
        d = (float64(points[k, 0]) - fr) ** 2 + (float64(points[k, 1]) - fc) ** 2
        if d > best:
            best = d
            out_far[0, 0] = points[k, 0]
            out_far[0, 1] = points[k, 1]
    return best >= 0.0


@kernel(boolean(f4_2d_ro, f4_2d_ro, float64, _thresholds_ro))
def tip_short(shape, far_end, width, thresholds):
    """``tip_short``: whether the free tip of `shape` (row, col; its last point) lies farther than
    ``tip_short_widths`` x `width` + ``tip_short_floor_px`` (`thresholds`) from the band's far end ``far_end[0]``
    (`contour_far_end`). False when the check is off (``tip_short_widths`` 0), the shape is empty, or the far end
    is not known (no row, nan)."""
    limits = thresholds[0]
    n = shape.shape[0]
    if limits["tip_short_widths"] <= 0.0 or n < 1 or far_end.shape[0] < 1:
        return False
    gap = math.hypot(
        float64(shape[n - 1, 0]) - float64(far_end[0, 0]), float64(shape[n - 1, 1]) - float64(far_end[0, 1])
    )
    return gap > limits["tip_short_widths"] * width + limits["tip_short_floor_px"]  # False for a nan far end


@kernel(_CHECK_SIGNATURES)
def check_frame(
    begin, end, fixed, predicted, stretch_begin, stretch_end, width_px, learned_width_px, order_confidence,
    exposure_ns, split, contour_area_px2, mask, corners, thresholds, out_quality,
):  # fmt: skip
    """Run every self-check on a measured frame; return the first failed check's code (`CHECK_NO_BLUR` before the
    others; `CHECK_NONE`: all passed) and write every measure into `out_quality[0]`.

    `begin`/`end` are the shapes (row, col), fixed end first; `fixed` the fixed end; `predicted` the tips' predicted
    midpoint, its error and the tip's sweep (`predict_tips`; nan error: none); `stretch_*` Lc / Lc0 of each shape
    (nan: unknown); `width_px` the split's width, `learned_width_px` the learned one (0: unknown); `split` whether
    the method gave two shapes (a single shape is checked against the tip's sweep: a fallback);
    `contour_area_px2` the contour's area (used only for a split the motion model cannot check: unknown exposure or
    no prediction); `mask` the static mask (`tip_mask_distance`); `corners` the band's far end as the contour gives
    it (row, col; fewer rows or nan: not known): on a split its two segmentation points (2, 2), for
    ``tip_corner``'s coinciding corners; on one shape the contour's farthest point from the fixed end (1, 2,
    `contour_far_end`), for ``tip_short``. The rules are `ropecam.device.pipeline.checks`' table.
    """
    limits = thresholds[0]
    q = out_quality[0]
    failed = CHECK_NONE
    length_ratio = math.nan
    for stretch in (stretch_begin, stretch_end):
        if math.isfinite(stretch) and not abs(stretch - 1.0) <= abs(length_ratio - 1.0):
            length_ratio = stretch
    q["length_ratio"] = length_ratio
    if abs(length_ratio - 1.0) > limits["length_tolerance"]:
        failed = CHECK_LENGTH
    # The two instants' shapes are one rope: a side that ran on along a scratch or lost its end differs from the
    # other one (a nan stretch compares False).
    if split and abs(stretch_begin - stretch_end) > limits["length_mismatch"]:
        failed = CHECK_LENGTH
    width_ratio = width_px / learned_width_px if learned_width_px != 0.0 else math.nan
    q["width_ratio"] = width_ratio
    if failed == CHECK_NONE and abs(width_ratio - 1.0) > limits["width_tolerance"]:
        failed = CHECK_WIDTH
    fr = float64(fixed[0])
    fc = float64(fixed[1])
    offset = max(
        math.hypot(float64(begin[0, 0]) - fr, float64(begin[0, 1]) - fc),
        math.hypot(float64(end[0, 0]) - fr, float64(end[0, 1]) - fc),
    )
    q["fixed_end_px"] = offset
    width = learned_width_px if learned_width_px != 0.0 else width_px
    if failed == CHECK_NONE and offset > limits["fixed_end_widths"] * width + limits["fixed_end_floor_px"]:
        failed = CHECK_FIXED_END
    nb = begin.shape[0] - 1
    ne = end.shape[0] - 1
    br = float64(begin[nb, 0])
    bc = float64(begin[nb, 1])
    er = float64(end[ne, 0])
    ec = float64(end[ne, 1])
    separation = math.hypot(er - br, ec - bc)
    q["tip_separation_px"] = separation
    motion_px = math.nan
    motion_limit_px = math.nan
    if not math.isnan(predicted[2]):
        motion_px = math.hypot(0.5 * (br + er) - predicted[0], 0.5 * (bc + ec) - predicted[1])
        motion_limit_px = limits["tip_motion_factor"] * predicted[2] + limits["tip_motion_floor_px"]
    q["tip_motion_px"] = motion_px
    q["tip_motion_limit_px"] = motion_limit_px
    if failed == CHECK_NONE and motion_px > motion_limit_px:
        failed = CHECK_TIP_MOTION
    if failed == CHECK_NONE and split and exposure_ns > 0 and order_confidence < limits["min_order_confidence"]:
        failed = CHECK_ORDER
    # One shape (the split's static fallback: the band's middle, the rope at mid-exposure) while the tip's path
    # swept more than a rope width or so: the shape is neither the start nor the end of the exposure.
    if (
        failed == CHECK_NONE
        and not split
        and limits["fallback_sweep_widths"] > 0.0
        and predicted[3] > limits["fallback_sweep_widths"] * width
    ):
        failed = CHECK_FALLBACK_SWEEP
    # A tip that ends where the static mask begins may be where the mask cut the rope (a rope crossing a masked
    # plate edge ends at it): the rope's end is then not seen, and the shapes are short.
    reach_px = limits["tip_mask_widths"] * width + limits["tip_mask_floor_px"]
    if failed == CHECK_NONE and (
        math.isfinite(tip_mask_distance(begin, mask, width, reach_px))
        or math.isfinite(tip_mask_distance(end, mask, width, reach_px))
    ):
        failed = CHECK_TIP_MASKED
    # A rope's free end carries no bending moment: its last few widths run straight. A shape that turns sharply
    # there ran on along noise beyond the band's faint end (its length may still pass `length_tolerance`).
    kink_reach_px = limits["tip_kink_widths"] * width
    if (
        failed == CHECK_NONE
        and kink_reach_px > 0.0
        and (
            tip_turn_deg(begin, kink_reach_px) > limits["tip_kink_deg"]
            or tip_turn_deg(end, kink_reach_px) > limits["tip_kink_deg"]
        )
    ):
        failed = CHECK_TIP_KINK
    # The band's far end has two corners, one on each side of the rope's end cap, about the edges' spacing (`width`)
    # apart or more: each shape's tip is read at one of them. Corners closer than half that are one corner found
    # twice (the other side of the band's end lost in the rope's texture or the noise), and tips lying farther
    # apart than the corners by more than the spacing were not read at two corners (simulated `rope photo texture
    # = 2`, tuning seed, frame 46: corners 1.0 px apart, spacing 3.2 px, tips 8.0 px, the end tip 8.7 px off;
    # right frames of `rig-soft` and `lab` have corners 0.97 spacings apart where the tip moves along the rope).
    if failed == CHECK_NONE and split and limits["tip_corner_widths"] > 0.0 and corners.shape[0] >= 2:
        corner_sep = math.hypot(
            float64(corners[0, 0]) - float64(corners[1, 0]), float64(corners[0, 1]) - float64(corners[1, 1])
        )
        if corner_sep < 0.5 * width and separation > corner_sep + width:  # False for nan corners
            failed = CHECK_TIP_CORNER
    # One shape of a stream (the split's static fallback: the still rope's centreline, carried to the band's end)
    # ends where the band does: its free tip lies within a width or so of the contour's farthest point from the
    # fixed end (`contour_far_end`, in `corners`' first row). A tip short of it ended on a cap read inside the band
    # (simulated lab through the paper's camera at 9 ms, fresh device, tuning seed, frame 59: OK, 11.4 px short).
    # Not on frames of unknown exposure: a still photo's rope may lie in loops, its farthest point anywhere.
    # Checked last (`SelfChecks.check` then runs its own checks too): a frame it flags passed every other check.
    if failed == CHECK_NONE and not split and exposure_ns > 0 and tip_short(begin, corners, width, thresholds):
        failed = CHECK_TIP_SHORT
    evidence = math.nan
    unchecked = split and (exposure_ns <= 0 or math.isnan(predicted[2]))
    if unchecked:
        length_px = 0.0
        for k in range(nb):
            length_px += math.hypot(
                float64(begin[k + 1, 0]) - float64(begin[k, 0]), float64(begin[k + 1, 1]) - float64(begin[k, 1])
            )
        evidence = (contour_area_px2 - length_px * width) / max(0.5 * length_px * separation, 1.0)
    q["blur_evidence"] = evidence
    # The pixel contour's area is uncertain by ~ half a pixel along both sides (~ length px^2), which is
    # 2 / separation of the implied sweep area: a verdict only where that is below half the threshold.
    no_blur_px = limits["no_blur_px"]
    if limits["min_blur_evidence"] > 0.0:
        no_blur_px = max(no_blur_px, 4.0 / limits["min_blur_evidence"])
    if unchecked and separation > no_blur_px and not evidence >= limits["min_blur_evidence"]:
        failed = CHECK_NO_BLUR
    return failed
