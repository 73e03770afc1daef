"""Subpixel refinement and geometry along the closed contour: turning angles, the split, side offsets, midlines."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float32, float64, int32, int64, types

from ropecam.device.pipeline._kernels._common import FULL, NOT_FOUND, f4_1d_ro, vector_length
from ropecam.shared.jit import (
    f4_1d,
    f4_2d,
    f4_2d_ro,
    f8_1d,
    f8_1d_ro,
    i4_1d,
    i4_2d_ro,
    kernel,
)


@kernel(float32(f4_2d_ro, float32, float32))
def sample_bilinear(image, r, c):
    """Return `image` interpolated bilinearly at (r, c), clamped to the image."""
    height = image.shape[0]
    width = image.shape[1]
    r = min(max(r, 0.0), height - 1.0)
    c = min(max(c, 0.0), width - 1.0)
    r0 = min(int(r), height - 2) if height > 1 else 0
    c0 = min(int(c), width - 2) if width > 1 else 0
    fr = r - r0
    fc = c - c0
    r1 = min(r0 + 1, height - 1)
    c1 = min(c0 + 1, width - 1)
    top = image[r0, c0] * (1.0 - fc) + image[r0, c1] * fc
    bottom = image[r1, c0] * (1.0 - fc) + image[r1, c1] * fc
    return top * (1.0 - fr) + bottom * fr


@kernel(types.UniTuple(float32, 2)(f4_2d_ro, f4_2d_ro, f4_2d_ro, int32, int32))
def axis_offset(mag, gx, gy, r, c):
    """Return the (row, col) subpixel offset of the gradient magnitude's maximum at pixel (r, c) (Devernay 1995):
    the parabola through the magnitude at -1, 0, +1 px along the image axis nearest the gradient (exact pixel
    samples, no interpolation bias), its vertex offset clamped to 1 px; (0, 0) without a gradient, at the image
    border along that axis, or when the magnitude is not a maximum there."""
    g_r = gy[r, c]
    g_c = gx[r, c]
    if g_r == 0.0 and g_c == 0.0:
        return np.float32(0.0), np.float32(0.0)
    m0 = mag[r, c]
    if abs(g_c) >= abs(g_r):
        if c < 1 or c > mag.shape[1] - 2:
            return np.float32(0.0), np.float32(0.0)
        mm = mag[r, c - 1]
        mp = mag[r, c + 1]
    else:
        if r < 1 or r > mag.shape[0] - 2:
            return np.float32(0.0), np.float32(0.0)
        mm = mag[r - 1, c]
        mp = mag[r + 1, c]
    denom = mm - 2.0 * m0 + mp
    if not denom < 0.0:
        return np.float32(0.0), np.float32(0.0)
    delta = np.float32(min(max(0.5 * (mm - mp) / denom, -1.0), 1.0))
    if abs(g_c) >= abs(g_r):
        return np.float32(0.0), delta
    return delta, np.float32(0.0)


@kernel(int32(f4_2d_ro, f4_2d_ro, f4_2d_ro, i4_2d_ro, int32, f4_2d))
def refine_subpixel(mag, gx, gy, chain, n, out_points):
    """Move each of the first `n` chain pixels to the subpixel maximum of the gradient magnitude (`axis_offset`:
    Devernay's parabola along the image axis nearest the gradient).

    Writes `out_points` (row, col) float32; returns `n`."""
    for i in range(n):
        r = chain[i, 0]
        c = chain[i, 1]
        d_r, d_c = axis_offset(mag, gx, gy, r, c)
        out_points[i, 0] = r + d_r
        out_points[i, 1] = c + d_c
    return n


@kernel(float64(f4_2d_ro, int64, int64, int64))
def _turn_at(points, n, scale, i):
    """Return the unsigned turning angle (radians) at point `i` between the chords to the points `scale` places
    before and after (cyclic); 0 where a chord has no length."""
    # Wrapped by comparison: an integer modulo costs ~30 cycles, more than the rest of the index work.
    a = i - scale
    if a < 0:
        a += n
        if a < 0:
            a = (i - scale + n * ((scale // n) + 1)) % n
    b = i + scale
    if b >= n:
        b -= n
        if b >= n:
            b = (i + scale) % n
    v1r = points[i, 0] - points[a, 0]
    v1c = points[i, 1] - points[a, 1]
    v2r = points[b, 0] - points[i, 0]
    v2c = points[b, 1] - points[i, 1]
    n1 = math.sqrt(v1r * v1r + v1c * v1c)
    n2 = math.sqrt(v2r * v2r + v2c * v2c)
    if n1 <= 0.0 or n2 <= 0.0:
        return 0.0
    cos_t = (v1r * v2r + v1c * v2c) / (n1 * n2)
    cos_t = min(max(cos_t, -1.0), 1.0)
    return math.acos(cos_t)


@kernel(int32(f4_2d_ro, int32, int32, f4_1d))
def turning_angles(points, n, scale, out_turn):
    """Write the unsigned turning angle (radians, 0 to pi) of the closed polyline at each point, measured between
    the chords to the points `scale` places before and after. Returns `n`."""
    for i in range(n):
        out_turn[i] = _turn_at(points, n, scale, i)
    return n


@kernel(int64(int64, int64, boolean))
def _step(i, n, forward):
    """Return the index after (`forward`) or before `i` on a closed contour of `n` points (i in [0, n))."""
    if forward:
        return i + 1 if i + 1 < n else 0
    return i - 1 if i > 0 else n - 1


CORNER_PERSIST: Final = 0.5
"""The least turning angle at twice the corner scale, per unit of the angle at the scale, of a corner candidate
(`_is_corner`). A corner of the band turns over its rounding, a rope width or so, and turns as much or more when
read over chords twice as long (0.7-1.5 times on simulated `lab-dark`'s 240-frame set, frames 31, 98, 178, 182);
a dent of a pixel or two in a faint band's side (a broken edge closed across its gap) turns sharply at the scale
and hardly over the longer chords (0.33 times: frame 98's end side, 11 px short of the band's end: taken for the
corner, the end tip 7.6 px off while OK)."""


@kernel(boolean(f4_2d_ro, f8_1d_ro, f4_1d_ro, int32, int32, int32, float32, float32))
def _is_corner(points, dist, turn, n, scale, i, threshold, level):
    """Whether contour point `i` is a local maximum of `turn` (the turning angles at `scale`) above `level`, at
    least `threshold` from the fixed end (`dist`: distances from it), whose turn persists over chords twice as long
    (`CORNER_PERSIST`; `points`: the contour)."""
    before = i - 1 if i > 0 else n - 1
    after = i + 1 if i + 1 < n else 0
    if turn[i] <= level or turn[i] < turn[before] or turn[i] < turn[after]:
        return False
    if dist[i] < threshold:
        return False
    return _turn_at(points, n, 2 * scale, i) >= CORNER_PERSIST * turn[i]


@kernel(
    int32(f4_2d_ro, int32, f4_1d_ro, f8_1d_ro, f4_1d_ro, int64, int64, int64, float64, float64, int32, float64,
          float64, int64, int64, i4_1d)
)  # fmt: skip
def _pick_corners(
    points, scale, turn, dist, arc, n, i_fix, i_far, threshold, total, min_gap, level_a, level_b, zone_a, zone_b,
    out_idx,
):  # fmt: skip
    """`_split_from` once the arc lengths `arc` from the fixed end (`total` the contour's length) and each side's
    corner level and first tip-zone step (`level_a`, `zone_a`, `level_b`, `zone_b`) are known: the corner pair
    (`_is_corner` on the contour `points`, turning angles `turn` at `scale`), or the fallback of the largest
    turning angles."""
    len_a = (i_far - i_fix + n) % n
    len_b = (i_fix - i_far + n) % n
    # The far point is a candidate only when no pair is found without it: it lies on the band's end, often where
    # the end meets a cap rather than at the cap's corner with the side (simulated `lab-dark`, 240 frames, 178:
    # 6 steps before the end side's corner, and the better match of arc lengths, 2.0 px off), but on a faint end
    # side whose dent is no corner (`CORNER_PERSIST`) it can be the only corner left (frame 98).
    for far in range(2):
        best_delta = 1e30
        for rep in range(2):
            pick_sum = -1.0
            ia = (i_fix + zone_a) % n
            for step_a in range(zone_a, len_a + far):
                if step_a > zone_a:
                    ia = _step(ia, n, True)
                if not _is_corner(points, dist, turn, n, scale, ia, threshold, level_a):
                    continue
                ib = (i_fix - zone_b + n) % n
                for step_b in range(zone_b, len_b + far):
                    if step_b > zone_b:
                        ib = _step(ib, n, False)
                    if not _is_corner(points, dist, turn, n, scale, ib, threshold, level_b):
                        continue
                    gap = abs(ia - ib)
                    if min(gap, n - gap) < min_gap:
                        continue
                    delta = abs(arc[ia] - (total - arc[ib]))
                    if rep == 0:
                        best_delta = min(best_delta, delta)
                    elif delta <= best_delta + 2.0 and turn[ia] + turn[ib] > pick_sum:
                        pick_sum = turn[ia] + turn[ib]
                        out_idx[1] = ia
                        out_idx[3] = ib
            if rep == 0 and best_delta > 1e29:
                break
            if rep == 1 and pick_sum >= 0.0:
                out_idx[0] = i_fix
                out_idx[2] = i_far
                return 4
    # Side A: forward from the fixed end to the far point; side B: backward. Each gets the point of largest turning
    # in the tip zone; the pair must be `min_gap` chain steps apart (the far point may itself be a corner), so the
    # best pair is taken over "A first, then B away from it" and "B first, then A away from it".
    best_sum = -1.0
    seg_a = -1
    seg_b = -1
    for first in range(2):
        a = -1
        b = -1
        ta = -1.0
        tb = -1.0
        for rep in range(2):
            pick_a = (rep == 0) == (first == 0)
            length = len_a if pick_a else len_b
            i = i_fix
            for _ in range(length):
                i = _step(i, n, pick_a)
                if dist[i] < threshold:
                    continue
                other = b if pick_a else a
                if other >= 0:
                    gap = abs(i - other)
                    if min(gap, n - gap) < min_gap:
                        continue
                if pick_a and turn[i] > ta:
                    ta = turn[i]
                    a = i
                elif not pick_a and turn[i] > tb:
                    tb = turn[i]
                    b = i
        if a >= 0 and b >= 0 and ta + tb > best_sum:
            best_sum = ta + tb
            seg_a = a
            seg_b = b
    if seg_a < 0 or seg_b < 0:
        return NOT_FOUND
    out_idx[0] = i_fix
    out_idx[1] = seg_a
    out_idx[2] = i_far
    out_idx[3] = seg_b
    return 4


@kernel(
    int32(f4_2d_ro, int32, f4_1d_ro, f8_1d_ro, int64, int64, int64, float64, float32, int32, float32, f4_1d, i4_1d)
)  # fmt: skip
def _split_from(
    points, scale, turn, dist, n, i_fix, i_far, r_far, search_px, min_gap, corner_rad, work_arc, out_idx
):  # fmt: skip
    """Find the two segmentation points once the fixed end `i_fix`, the far point `i_far` and its distance `r_far`
    are known: side A runs forward along the chain from the fixed end to the far point, side B backward. Among the
    points at least ``r_far - search_px`` from the fixed end, the corner candidates of each side are the local
    maxima of the turning angle (at `scale`) above `corner_rad` and above half the side's sharpest, whose turn
    persists at twice the scale (`CORNER_PERSIST`); of the pairs at least `min_gap` chain steps apart, those whose
    arc lengths from the fixed end differ by at most 2 px more than the best-matching pair's compete, and the
    sharpest (largest sum) wins; the far point is a candidate when no pair is found without it. Without
    candidates, the points of largest turning angle on each side (at least `min_gap` apart) are used. `dist`
    holds each point's distance from the fixed end; `work_arc` (n) is scratch. Writes ``out_idx = [fixed, seg_a,
    far, seg_b]``; returns 4, NOT_FOUND or FULL."""
    threshold = r_far - search_px
    len_a = (i_far - i_fix + n) % n
    len_b = (i_fix - i_far + n) % n
    if len_a < 1 or len_b < 1:
        return NOT_FOUND
    if work_arc.shape[0] < n:
        return FULL
    # Arc length along the contour from the fixed end, forward (side A); side B's is the total minus it.
    arc = work_arc
    arc[i_fix] = 0.0
    total = 0.0
    ip = i_fix
    for step in range(1, n + 1):
        i = ip + 1 if ip + 1 < n else 0
        total += vector_length(points[i, 0] - points[ip, 0], points[i, 1] - points[ip, 1])
        if step < n:
            arc[i] = total
        ip = i
    # Corner candidates: local maxima of the turning angle in the tip zone, at least half as sharp as the side's
    # sharpest there (and above `corner_rad`). The rope keeps its length within the exposure, so the pair whose
    # arc lengths from the fixed end agree best is the band's two corners (a slanted band end adds a second,
    # obtuse corner and a faint one kinks: both change one side's length); near-ties go to the sharper pair.
    level_a = corner_rad
    level_b = corner_rad
    zone_a = len_a
    zone_b = len_b
    for side in range(2):
        length = len_a if side == 0 else len_b
        i = i_fix
        for step in range(1, length + 1):
            i = _step(i, n, side == 0)
            if dist[i] >= threshold:
                if side == 0:
                    level_a = max(level_a, 0.5 * turn[i])
                    zone_a = min(zone_a, step)
                else:
                    level_b = max(level_b, 0.5 * turn[i])
                    zone_b = min(zone_b, step)
    return _pick_corners(
        points, scale, turn, dist, arc, n, i_fix, i_far, threshold, total, min_gap, level_a, level_b, zone_a, zone_b,
        out_idx,
    )  # fmt: skip


@kernel(int32(f4_2d_ro, int32, int32, float32, float32, float32, int32, float32, f8_1d, f4_1d, f4_1d, i4_1d))
def find_segmentation_points(
    points, n, scale, fixed_r, fixed_c, search_px, min_gap, corner_rad, out_dist, out_turn, work_arc, out_idx
):
    """Find the fixed end, the far point and the two segmentation points on the closed subpixel contour: the
    distances from (fixed_r, fixed_c) into `out_dist`, the turning angles (`turning_angles`) where they are read
    into `out_turn`, then `_split_from` (the fixed end is the nearest point, the far point the farthest), with its
    `work_arc`, `out_idx` and return value (FULL also when `out_dist` or `out_turn` is shorter than `n`).

    One pass gives the distances, the fixed end and the far point; `out_turn` is written only where
    `_split_from` reads it (the tip zone and its neighbours), not cleared elsewhere.
    """
    if n < 8:
        return NOT_FOUND
    if out_dist.shape[0] < n or out_turn.shape[0] < n:
        return FULL
    i_fix = 0
    best = 1e30
    i_far = 0
    r_far = -1.0
    for i in range(n):
        d = vector_length(points[i, 0] - fixed_r, points[i, 1] - fixed_c)
        out_dist[i] = d
        if d < best:
            best = d
            i_fix = i
        if d > r_far:
            r_far = d
            i_far = i
    threshold = r_far - search_px
    done = -1  # last index written (the zone is visited in order; its neighbours may repeat)
    for i in range(n):
        if out_dist[i] < threshold:
            continue
        for j in range(i - 1, i + 2):
            if j <= done and j >= 0:
                continue
            k = j + n if j < 0 else (j - n if j >= n else j)
            out_turn[k] = _turn_at(points, n, scale, k)
            done = max(done, j)
    return _split_from(
        points, scale, out_turn, out_dist, n, i_fix, i_far, r_far, search_px, min_gap, corner_rad, work_arc, out_idx
    )


@kernel(
    int32(f4_2d_ro, int32, int32, float32, float32, float32, int32, float32, f8_1d, f4_1d, f4_1d, f8_1d, i4_1d)
)  # fmt: skip
def find_segmentation_points_seg(
    points, n, scale, fixed_r, fixed_c, search_px, min_gap, corner_rad, out_dist, out_turn, work_arc, work_seg,
    out_idx,
):  # fmt: skip
    """`find_segmentation_points` (the same `out_dist`, `work_arc`, `out_idx` and return value) with a float64
    scratch `work_seg` (n) for the contour's segment lengths: the distances and the segment lengths are taken in
    one pass without a loop-carried value (their square roots vectorise), the arc lengths are then sums of the
    stored lengths in `_split_from`'s order, and each side's tip zone (its first step and corner level) is noted
    in the pass that computes the turning angles instead of a walk along both sides. FULL also when `work_seg` is
    shorter than `n`."""
    if n < 8:
        return NOT_FOUND
    if out_dist.shape[0] < n or out_turn.shape[0] < n or work_seg.shape[0] < n:
        return FULL
    for i in range(n):
        out_dist[i] = vector_length(points[i, 0] - fixed_r, points[i, 1] - fixed_c)
    for i in range(1, n):
        work_seg[i] = vector_length(points[i, 0] - points[i - 1, 0], points[i, 1] - points[i - 1, 1])
    work_seg[0] = vector_length(points[0, 0] - points[n - 1, 0], points[0, 1] - points[n - 1, 1])
    i_fix = 0
    best = 1e30
    i_far = 0
    r_far = -1.0
    for i in range(n):
        d = out_dist[i]
        if d < best:
            best = d
            i_fix = i
        if d > r_far:
            r_far = d
            i_far = i
    threshold = r_far - search_px
    len_a = (i_far - i_fix + n) % n
    len_b = (i_fix - i_far + n) % n
    # `_split_from`'s walk along both sides, by index: point i is step (i - i_fix) mod n of side A when that is
    # in 1..len_a, step (i_fix - i) mod n of side B when that is in 1..len_b (the far point is on both).
    level_a = np.float64(corner_rad)
    level_b = np.float64(corner_rad)
    zone_a = len_a
    zone_b = len_b
    # `find_segmentation_points`' angle loop with the tip zones noted in it, on purpose: a separate pass (or
    # `_split_from`'s walk along both sides) over the zone is what this variant saves on the steady frame.
    done = -1  # last index written (the zone is visited in order; its neighbours may repeat)
    for i in range(n):
        if out_dist[i] < threshold:
            continue
        for j in range(i - 1, i + 2):
            if j <= done and j >= 0:
                continue
            k = j + n if j < 0 else (j - n if j >= n else j)
            out_turn[k] = _turn_at(points, n, scale, k)
            done = max(done, j)
        if not out_dist[i] >= threshold:  # nan: in the angle pass, not in a tip zone
            continue
        half_turn = 0.5 * out_turn[i]
        step_a = i - i_fix if i >= i_fix else i - i_fix + n
        if 1 <= step_a <= len_a:
            level_a = max(level_a, half_turn)
            zone_a = min(zone_a, step_a)
        step_b = i_fix - i if i_fix >= i else i_fix - i + n
        if 1 <= step_b <= len_b:
            level_b = max(level_b, half_turn)
            zone_b = min(zone_b, step_b)
    if len_a < 1 or len_b < 1:
        return NOT_FOUND
    if work_arc.shape[0] < n:
        return FULL
    arc = work_arc
    arc[i_fix] = 0.0
    total = 0.0
    for i in range(i_fix + 1, n):
        total += work_seg[i]
        arc[i] = total
    for i in range(i_fix):
        total += work_seg[i]
        arc[i] = total
    total += work_seg[i_fix]
    return _pick_corners(
        points, scale, out_turn, out_dist, arc, n, i_fix, i_far, threshold, total, min_gap, level_a, level_b, zone_a,
        zone_b, out_idx,
    )  # fmt: skip


@kernel(float64(f4_2d_ro, int64, int64, int64, int64))
def chain_step_length(points, n, i_start, direction, k):
    """Return the length of step `k` (>= 1) of the contour walked from `i_start` in `direction` (+1/-1), cyclic:
    from its point k - 1 to its point k."""
    i0 = (i_start + (k - 1) * direction + n * 4) % n
    i1 = (i_start + k * direction + n * 4) % n
    return vector_length(points[i1, 0] - points[i0, 0], points[i1, 1] - points[i0, 1])


@kernel(float64(f4_2d_ro, int64, int64, int64, int64))
def chain_length(points, n, i_start, count, direction):
    """Return the length of the `count` contour points from `i_start`, stepping `direction` (+1/-1), cyclic."""
    total = 0.0
    for k in range(1, count):
        total += chain_step_length(points, n, i_start, direction, k)
    return total


@kernel(float64(float32, float32, float64, float64))
def linear_sweep_shift(width_px, sweep_tip_px, s, total):
    """Return the inward shift ``max(0, (width_px - sweep(s)) / 2)`` of a side's point at arc length `s` of
    `total` (> 0), the sweep growing linearly from 0 at the side's start to `sweep_tip_px` at its end (rotation
    about the fixed end): the edge of a blurred band lies at the centre of its intensity ramp."""
    return max(0.0, 0.5 * (width_px - sweep_tip_px * s / total))


@kernel(int32(f4_2d_ro, int32, int32, int32, int32, float32, float32, float32, int32, f4_2d))
def offset_side(points, n, i_start, i_stop, direction, interior_sign, width_px, sweep_tip_px, tangent_span, out_poly):
    """Copy the contour from `i_start` to `i_stop` (stepping `direction` = +1 or -1, cyclic) into `out_poly`,
    each point moved towards the band's interior by ``max(0, (width_px - sweep(s)) / 2)``.

    The edge of a blurred band lies at the centre of the intensity ramp: on the rope axis where the local sweep
    is at least the rope width, `width_px / 2` outside it where the rope did not move. The sweep is modelled as
    growing linearly with arc length from the fixed end to `sweep_tip_px` at the tip (rotation about the fixed
    end). The interior normal is ``interior_sign * (t_col, -t_row)`` for the forward chain tangent t (estimated
    over +-`tangent_span` points). Returns the number of points written or FULL.
    """
    count = (i_stop - i_start) * direction
    count = (count % n + n) % n + 1
    if count > out_poly.shape[0]:
        return FULL
    total = chain_length(points, n, i_start, count, direction)
    # The walk and the shift are `offset_by_gradient`'s step kernels (`chain_step_length`, `linear_sweep_shift`);
    # the two loops differ where they must: the direction moved (the tangent's normal here, the gradient there)
    # and a side of zero length (moved by 0 here, by half a width there). Both serve cold paths (the paper's
    # method, the static fallback), where the calls cost a little: `offset_by_gradient` 29.4 -> 32.8 us and
    # `chain_length` 7.2 -> 7.8 us on a 700-point side (script, session 10); the steady frame calls neither.
    s = 0.0
    for k in range(count):
        i = (i_start + k * direction + n * 4) % n
        if k > 0:
            s += chain_step_length(points, n, i_start, direction, k)
        a = (i - tangent_span + n * 4) % n
        b = (i + tangent_span) % n
        t_r = points[b, 0] - points[a, 0]
        t_c = points[b, 1] - points[a, 1]
        norm = math.sqrt(t_r * t_r + t_c * t_c)
        shift = 0.0
        if total > 0.0:
            shift = linear_sweep_shift(width_px, sweep_tip_px, s, total)
        if norm > 0.0:
            out_poly[k, 0] = points[i, 0] + shift * interior_sign * t_c / norm
            out_poly[k, 1] = points[i, 1] - shift * interior_sign * t_r / norm
        else:
            out_poly[k, 0] = points[i, 0]
            out_poly[k, 1] = points[i, 1]
    return count


@kernel(int32(f4_2d_ro, int32, f4_2d_ro, int32, f4_2d, f4_1d))
def midline(side_a, n_a, side_b, n_b, out_poly, out_dist):
    """Write the midline of two polylines that run between the same two ends (fixed end first, free end last):
    each vertex of `side_a` is paired with the point of `side_b` at the same fraction of its length, the midpoint
    goes to `out_poly` and the pair's distance to `out_dist`; returns `n_a`, 0 when a side is empty, or FULL.

    The two sides of a blurred band are the rope's edges at the two instants (plus half of the tip's track each),
    so equal fractions of their lengths are the same material point of the rope. Pairing by nearest point instead
    is ill-posed where the sides run apart (a flat end's cap, the tip's track): both ends of the pairing then
    collapse onto one point or one side's vertex, and the midline's end wanders along the track. A side of zero
    length pairs every point with the other side's first point.
    """
    if n_a > out_poly.shape[0] or n_a > out_dist.shape[0]:
        return FULL
    if n_a < 1 or n_b < 1:
        return 0
    len_a = 0.0
    for i in range(1, n_a):
        len_a += math.hypot(side_a[i, 0] - side_a[i - 1, 0], side_a[i, 1] - side_a[i - 1, 1])
    len_b = 0.0
    for j in range(1, n_b):
        len_b += math.hypot(side_b[j, 0] - side_b[j - 1, 0], side_b[j, 1] - side_b[j - 1, 1])
    ratio = len_b / len_a if len_a > 0.0 else 0.0
    arc_a = 0.0
    j = 0  # side B's segment [j, j + 1] holds the target; arc_b is the arc length at vertex j
    arc_b = 0.0
    seg_b = math.hypot(side_b[1, 0] - side_b[0, 0], side_b[1, 1] - side_b[0, 1]) if n_b > 1 else 0.0
    for i in range(n_a):
        ar = side_a[i, 0]
        ac = side_a[i, 1]
        if i > 0:
            arc_a += math.hypot(ar - side_a[i - 1, 0], ac - side_a[i - 1, 1])
        target = min(arc_a * ratio, len_b)
        while j + 2 < n_b and arc_b + seg_b < target:
            arc_b += seg_b
            j += 1
            seg_b = math.hypot(side_b[j + 1, 0] - side_b[j, 0], side_b[j + 1, 1] - side_b[j, 1])
        if n_b == 1:
            br = side_b[0, 0]
            bc = side_b[0, 1]
        else:
            t = min(max((target - arc_b) / seg_b, 0.0), 1.0) if seg_b > 0.0 else 0.0
            br = side_b[j, 0] + t * (side_b[j + 1, 0] - side_b[j, 0])
            bc = side_b[j, 1] + t * (side_b[j + 1, 1] - side_b[j, 1])
        if i == n_a - 1 and len_a > 0.0:  # the shared free end, exactly (no rounding of the two lengths)
            br = side_b[n_b - 1, 0]
            bc = side_b[n_b - 1, 1]
        out_poly[i, 0] = 0.5 * (ar + br)
        out_poly[i, 1] = 0.5 * (ac + bc)
        out_dist[i] = math.hypot(ar - br, ac - bc)
    return n_a
