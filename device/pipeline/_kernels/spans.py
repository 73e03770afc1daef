"""Row-span regions of interest: grow, build around a polyline, test membership."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float64, int32, int64, types

from ropecam.shared.jit import (
    f4_2d,
    f4_2d_ro,
    f8_1d_ro,
    i4_1d,
    i4_1d_ro,
    i4_2d,
    kernel,
    u1_2d_ro,
)

_SEGMENT_POINTS: Final = 48
"""Most chain steps one straight piece of a band spans (`spans_around_chain`)."""
_SEGMENT_DEV_PX: Final = 0.5
"""Largest distance (px) of a chain point from the straight piece that stands for it (a piece's radius is the
disc radius plus its points' largest distance)."""
_CHAIN_STEP2: Final = 4.5
"""Largest squared step (px^2) between consecutive points for them to be joined by a piece (an 8-connected chain
steps at most sqrt(2) px, a refined one a little more); farther points get discs of their own."""
_PROFILE_REACH: Final = 2.0
"""A measured uncertainty profile (`spans_around_chain`) gives at most this many times the step-scaled one."""
_SMOOTH_COS: Final = 0.8
"""Two pieces meeting at less than ~37 degrees share their end disc's uncovered wedge (a small box) instead of
drawing the disc."""


@kernel(int64(float64, int64, float64, float64))
def _disc_radius(share, margin_px, motion_px, cap):
    """Return the disc radius of a point at ``s = share``: ``margin_px + ceil(u)``, ``u = motion_px * s``, or when
    `cap` (the profile's bin of s; inf: none) is finite, `cap` but at most `_PROFILE_REACH` x ``motion_px * s``
    (one expression for every use, so that a piece's radius is never a rounding smaller than a disc's). The
    caller looks the profile up itself: an array passed in here made the band kernel a third slower."""
    u = motion_px * share
    if cap < _PROFILE_REACH * u:
        u = cap
    elif cap < 1e300:
        u = _PROFILE_REACH * u
    return margin_px + math.ceil(u)


@kernel(types.UniTuple(float64, 2)(f8_1d_ro, int64, float64, int64, float64, float64, int64, float64))
def _radius_range(profile, k, cap, m, d_max, d2_max, margin_px, motion_px):
    """Return a range [lo, hi] of squared distances from the fixed end over which the disc radius is `m`, found at
    a point in `profile` bin `k` (`cap` that bin's value; any bin when the profile is empty), or an empty range
    (lo > hi).

    The radius of a point is ``_disc_radius(sqrt(d2) / d_max, margin_px, motion_px, cap)`` with the cap of the
    bin ``min(bins - 1, int(s * bins))``. The bin never decreases as d2 grows, and over bins of one cap neither
    does the radius (``min(cap, 2 u)`` or u, ``u = motion_px * s``; correctly rounded operations keep the order).
    So when both ends of a range lie in the run of bins of `cap` around `k` and give radius `m`, every d2
    between them does. The ends are guessed from the run's and the radius step's bounds (shrunk a little), then
    computed as a point's radius is: a wrong guess only costs the range.
    """
    bins = profile.shape[0]
    k_lo = k
    k_hi = k
    while k_lo > 0 and profile[k_lo - 1] == cap:
        k_lo -= 1
    while k_hi < bins - 1 and profile[k_hi + 1] == cap:
        k_hi += 1
    s_lo = 0.0
    s_hi = math.inf
    if bins > 0:
        s_lo = k_lo / bins
        if k_hi < bins - 1:
            s_hi = (k_hi + 1) / bins
    step = m - margin_px
    if motion_px > 0.0:
        if cap < 1e300:
            s_lo = max(s_lo, (step - 1) / (_PROFILE_REACH * motion_px))
            if cap > step:
                s_hi = min(s_hi, step / (_PROFILE_REACH * motion_px))
        else:
            s_lo = max(s_lo, (step - 1) / motion_px)
            s_hi = min(s_hi, step / motion_px)
    s_lo = s_lo * (1.0 + 1e-9) + 1e-12
    s_hi = s_hi * (1.0 - 1e-9) - 1e-12
    lo = s_lo * d_max
    lo = lo * lo
    hi = d2_max
    if s_hi * d_max < math.sqrt(d2_max):
        hi = s_hi * d_max
        hi = hi * hi
    if not lo <= hi:
        return 1.0, 0.0
    for end in (lo, hi):
        s = math.sqrt(end) / d_max
        if bins > 0 and not k_lo <= min(bins - 1, int(s * bins)) <= k_hi:
            return 1.0, 0.0
        if _disc_radius(s, margin_px, motion_px, cap) != m:
            return 1.0, 0.0
    return lo, hi


@kernel(types.Tuple((int64, float64, float64))(float64, f8_1d_ro, float64, float64, int64, float64))
def _radius_of(d2, profile, d_max, d2_max, margin_px, motion_px):
    """The disc radius of a point at squared distance `d2` from the fixed end (its bin's cap of `profile`), and
    the range of squared distances known to share it (`_radius_range`): (radius, range low, range high)."""
    bins = profile.shape[0]
    share = math.sqrt(d2) / d_max
    k = min(bins - 1, int(share * bins)) if bins > 0 else 0
    cap = profile[k] if bins > 0 else math.inf
    m = _disc_radius(share, margin_px, motion_px, cap)
    lo, hi = _radius_range(profile, k, cap, m, d_max, d2_max, margin_px, motion_px)
    return m, lo, hi


@kernel(types.void(float64, float64, float64, int64, int64, i4_1d, i4_1d))
def _draw_disc(centre_r, centre_c, radius, height, width, out_lo, out_hi):
    """Widen the row spans `out_lo`/`out_hi` to cover the disc: rows ``ceil(r - R) .. floor(r + R)``, columns
    ``floor(c - h) .. ceil(c + h)`` with ``h = sqrt(R**2 - dy**2)``, clipped to the image."""
    r0 = max(0, math.ceil(centre_r - radius))
    r1 = min(height - 1, math.floor(centre_r + radius))
    for r in range(r0, r1 + 1):
        dy = r - centre_r
        half = math.sqrt(max(0.0, radius * radius - dy * dy))
        c0 = max(0, math.floor(centre_c - half))
        c1 = min(width - 1, math.ceil(centre_c + half))
        if c0 <= c1:
            out_lo[r] = min(out_lo[r], c0)
            out_hi[r] = max(out_hi[r], c1)


@kernel(types.void(float64, float64, float64, float64, int64, int64, i4_1d, i4_1d))
def _draw_box(top, bottom, left, right, height, width, out_lo, out_hi):
    """Widen the row spans `out_lo`/`out_hi` to cover the box: rows ``ceil(top) .. floor(bottom)``, columns
    ``floor(left) .. ceil(right)``, clipped to the image."""
    r0 = max(0, math.ceil(top))
    r1 = min(height - 1, math.floor(bottom))
    c0 = max(0, math.floor(left))
    c1 = min(width - 1, math.ceil(right))
    if c0 <= c1:
        for r in range(r0, r1 + 1):
            out_lo[r] = min(out_lo[r], c0)
            out_hi[r] = max(out_hi[r], c1)


@kernel(types.void(float64, float64, float64, float64, float64, float64, float64, int64, int64, i4_1d, i4_1d))
def _draw_rectangle(p_r, p_c, u_r, u_c, length, radius, reach, height, width, out_lo, out_hi):
    """Widen the row spans `out_lo`/`out_hi` to cover the rectangle ``0 <= (X - P).u <= length``,
    ``|(X - P).n| <= radius`` (P = (p_r, p_c), u a unit vector, n = (u_c, -u_r)), clipped to the image; `reach` is
    ``radius * |u_c|``. Per row the column bounds are linear in ``y = r - p_r``; a constraint whose column
    coefficient is tiny bounds the rows only, which the row range already does: leaving it out only widens.

    One scalar loop for every case (band9: `band_stage` ~6 us less per frame on rig-soft, in the pipeline, than
    the loop with a min, a max and a test of each constraint per row): the row counted in
    float64 (``y = r - p_r`` exactly as from the integer row, which float64 holds exactly) is a floating-point
    induction, which LLVM does not vectorize without fast-math. A vectorized loop uses 512-bit registers here
    (AVX-512), whose frequency licence made the band 10-18 us slower in the pipeline (band8). The strip along u
    gives ``y * a_slope + (0 .. a_width)``: its lower end chosen once by the sign of `a_width` (adding a
    non-negative number never decreases a float) instead of a min and a max per row; a constraint left out gets
    slope 0 and the bounds -1e18 .. 1e18 the loop started from."""
    r0 = max(0, math.ceil(min(p_r, p_r + length * u_r) - reach))
    r1 = min(height - 1, math.floor(max(p_r, p_r + length * u_r) + reach))
    if r0 > r1:
        return
    a_slope = 0.0
    a_lo = -1e18
    a_hi = 1e18
    if abs(u_c) > 1e-6:
        a_slope = -u_r / u_c
        a_width = length / u_c
        a_lo = min(0.0, a_width)
        a_hi = max(0.0, a_width)
    b_slope = 0.0
    b_half = 1e18
    if abs(u_r) > 1e-6:
        b_slope = u_c / u_r
        b_half = abs(radius / u_r)
    last = width - 1
    lo = out_lo[r0 : r1 + 1]  # (indices from 0: no negative-index wrap per row)
    hi = out_hi[r0 : r1 + 1]
    row = float(r0)
    for k in range(r1 - r0 + 1):
        y = row - p_r
        row += 1.0
        t = a_slope * y
        s = b_slope * y
        x0 = max(t + a_lo, s - b_half)
        x1 = min(t + a_hi, s + b_half)
        if x0 <= x1:
            c0 = max(0, math.floor(p_c + x0))
            c1 = min(last, math.ceil(p_c + x1))
            if c0 <= c1:
                lo[k] = min(lo[k], c0)
                hi[k] = max(hi[k], c1)


@kernel(
    int32(
        f4_2d_ro, int64, int64, float64, f8_1d_ro, float64, float64, float64, float64, int64, int64, i4_1d, i4_1d,
        f4_2d,
    )
)  # fmt: skip
def spans_around_chain(
    points, n_points, margin_px, motion_px, profile, rot_a, rot_b, fixed_r, fixed_c, height, width, out_lo, out_hi,
    out_moved,
):  # fmt: skip
    """Write row spans covering a disc around each of the first `n_points` (row, col) `points`, each moved by a
    rotation and scaling about the fixed end, clipped to the image; returns the number of non-empty rows.

    Seen as complex numbers ``z = (row - fixed_r) + 1j * (col - fixed_c)``, each point moves to
    ``(rot_a + 1j * rot_b) * z`` (1, 0: no motion): the predicted swing of the rope about its fixed end
    (fixed_r, fixed_c). With d the point's distance from the fixed end and d_max the largest such distance, the
    disc's radius is ``m = margin_px + ceil(motion_px * d / d_max)``: `motion_px` is the uncertainty of the
    prediction at the farthest point. A non-empty `profile` (px, one value per equal bin of ``s = d / d_max`` in
    [0, 1]; inf: none) replaces that uncertainty: ``m = margin_px + ceil(min(profile[floor(s * bins)],
    _PROFILE_REACH * motion_px * s))`` (the prediction's measured error, `need_profile`). When `out_moved` has room
    for the points, the moved points are written there (float32), for `need_profile` to compare the next contour
    with. (The scalars are int64 and float64: Python ints and floats pass as they are, without a NumPy scalar
    made per call.) Row r gets the columns ``floor(x0) .. ceil(x1)`` where [x0, x1] is what
    the covered region holds of the line ``row = r`` (one span per row: its outermost columns).

    The points are taken as a chain: runs of consecutive points at most ``sqrt(_CHAIN_STEP2)`` px apart are cut
    into straight pieces (up to `_SEGMENT_POINTS` steps of one disc radius m, every point within
    `_SEGMENT_DEV_PX` of the segment and projecting onto it). A piece P-Q covers its capsule of radius R = m + the
    points' largest distance from it, which holds every disc of its points: drawn as the rectangle along the
    segment (rows of the segment only, no square root) and the discs at its ends. Where two pieces, each at
    least R long, meet at a small angle, the rectangles hold all of the end disc but a thin wedge (whose bounding
    box is drawn) and, when their radii differ, two slivers beside the narrower one (a short rectangle of the
    larger radius). The last point of a run, a lone point and unordered points (steps too long) get their disc.
    The band is never smaller than the union of the discs of all the points (a band of discs around every other
    few points, as before, is inside it) and at most the points' distance from their pieces wider. Non-finite
    points are skipped.
    """
    for r in range(height):
        out_lo[r] = width
        out_hi[r] = -1
    d2_max = 1e-12
    keep = out_moved.shape[0] >= n_points
    for i in range(n_points):
        dr = points[i, 0] - fixed_r
        dc = points[i, 1] - fixed_c
        d2 = dr * dr + dc * dc
        if d2 > d2_max:
            d2_max = d2
        if keep:
            out_moved[i, 0] = fixed_r + rot_a * dr - rot_b * dc
            out_moved[i, 1] = fixed_c + rot_b * dr + rot_a * dc
    d_max = math.sqrt(d2_max)
    # The radius is known without its square root and division for squared distances in [known_lo, known_hi]
    # (`_radius_range` of the last radius computed): ~4 us less per band on rig.
    known_lo = 1.0
    known_hi = 0.0
    known_m = 0
    scale = math.sqrt(float(rot_a) * rot_a + float(rot_b) * rot_b)
    dev_orig = _SEGMENT_DEV_PX / max(scale, 1e-9)  # the deviation allowed before the motion's scaling
    prev_radius = 0.0  # 0: no steep piece ends at point i
    prev_ur = 0.0
    prev_uc = 0.0
    prev_length = 0.0
    # Points scan_start + 1 .. scan_end were found in one run of radius scan_m (a piece cut short of its run
    # starts the next piece inside it: the scan is not repeated).
    scan_start = -1
    scan_end = -1
    scan_m = 0
    i = 0
    while i < n_points:
        pr = float(points[i, 0])
        pc = float(points[i, 1])
        if not (abs(pr) < 1e9 and abs(pc) < 1e9):
            prev_radius = 0.0
            i += 1
            continue
        # The piece from i: as far as the chain goes on in short steps with the disc radius of point i + 1
        # (point i may have another: its own disc is drawn at the joint); a run of up to 2 * _SEGMENT_POINTS
        # steps is cut in two equal pieces.
        zr = pr - fixed_r
        zc = pc - fixed_c
        if scan_start < i <= scan_end:  # scanned before: short steps, radius scan_m
            own = scan_m
        else:
            qr = points[i, 0] - fixed_r  # (as in the first loop: the same d2 with or without the JIT)
            qc = points[i, 1] - fixed_c
            d2 = qr * qr + qc * qc
            # The known-range lookup is written out here and in the scan below on purpose: as one step kernel
            # returning (radius, range), Numba called it per point instead of inlining it, `spans_around_chain`
            # 51 -> 70 us on a 1400-point rig-sized contour (+40 %, on every band; script, session 10).
            if known_lo <= d2 <= known_hi:
                own = known_m
            else:
                own, known_lo, known_hi = _radius_of(d2, profile, d_max, d2_max, margin_px, motion_px)
                known_m = own
        mr = fixed_r + rot_a * zr - rot_b * zc
        mc = fixed_c + rot_b * zr + rot_a * zc
        m_piece = -1
        last = i
        lim = min(n_points - 1, i + 2 * _SEGMENT_POINTS)
        if i < scan_end:  # the last scan went on past i: start where it stopped
            last = min(scan_end, lim)
            m_piece = scan_m
        while last < lim:
            sr = float(points[last + 1, 0]) - float(points[last, 0])
            sc = float(points[last + 1, 1]) - float(points[last, 1])
            if not sr * sr + sc * sc <= _CHAIN_STEP2:  # also for a non-finite point
                break
            qr = points[last + 1, 0] - fixed_r
            qc = points[last + 1, 1] - fixed_c
            d2 = qr * qr + qc * qc
            if known_lo <= d2 <= known_hi:
                m = known_m
            else:
                m, known_lo, known_hi = _radius_of(d2, profile, d_max, d2_max, margin_px, motion_px)
                known_m = m
            if m_piece < 0:
                m_piece = m
            elif m != m_piece:
                break
            last += 1
        if last > i:
            scan_start = i
            scan_end = last
            scan_m = m_piece
        if last - i > _SEGMENT_POINTS:
            last = i + (last - i + 1) // 2
        if last == i:  # the run ends here: the disc of point i (and the end disc of the piece before)
            _draw_disc(mr, mc, max(own, prev_radius), height, width, out_lo, out_hi)
            prev_radius = 0.0
            i += 1
            continue
        # Halved while a point strays from the segment (or does not project onto it).
        b = last
        dev = 0.0
        while b > i + 1:
            vr = float(points[b, 0]) - pr
            vc = float(points[b, 1]) - pc
            len2 = vr * vr + vc * vc
            limit = dev_orig * dev_orig * len2
            cross_max = 0.0
            fits = True
            for j in range(i + 1, b):  # (the first point that does not fit ends the test: ~1.5 us per band)
                wr = float(points[j, 0]) - pr
                wc = float(points[j, 1]) - pc
                cross = abs(wr * vc - wc * vr)
                dot = wr * vr + wc * vc
                if cross > cross_max:
                    cross_max = cross
                if not (cross_max * cross_max <= limit and dot >= 0.0 and dot <= len2):
                    fits = False
                    break
            if fits:
                dev = cross_max / math.sqrt(len2) * scale
                break
            b = i + (b - i) // 2
        radius = m_piece + dev + 1e-4  # (centres moved in float64: a rounding must not lose a column)
        zr = float(points[b, 0]) - fixed_r
        zc = float(points[b, 1]) - fixed_c
        nr = fixed_r + rot_a * zr - rot_b * zc
        nc = fixed_c + rot_b * zr + rot_a * zc
        length = math.sqrt((nr - mr) ** 2 + (nc - mc) ** 2)
        if not length > 1e-9:  # two points in one place: a disc
            _draw_disc(mr, mc, max(own, prev_radius, radius), height, width, out_lo, out_hi)
            prev_radius = radius
            prev_length = 0.0
            i = b
            continue
        ur = (nr - mr) / length
        uc = (nc - mc) / length
        big = max(radius, prev_radius, own)
        if prev_radius > 0.0 and min(length, prev_length) >= big and prev_ur * ur + prev_uc * uc >= _SMOOTH_COS:
            # Of the end disc (radius the larger R), the two rectangles leave out the wedge ahead of the
            # first piece's end and behind the second's start, {v : v.u1 >= 0, v.u2 <= 0, |v| <= R}, and
            # beside the rectangle of smaller radius r, the slivers r < |v.n| <= R within the disc. The wedge's
            # bounding box: the apex, the rays' ends, the disc's extreme points along an axis inside it.
            w1r, w1c = prev_uc, -prev_ur
            if w1r * ur + w1c * uc > 0.0:
                w1r, w1c = -w1r, -w1c
            w2r, w2c = uc, -ur
            if w2r * prev_ur + w2c * prev_uc < 0.0:
                w2r, w2c = -w2r, -w2c
            top = min(0.0, w1r, w2r)
            bottom = max(0.0, w1r, w2r)
            left = min(0.0, w1c, w2c)
            right = max(0.0, w1c, w2c)
            if prev_ur >= 0.0 >= ur:
                bottom = 1.0
            if prev_ur <= 0.0 <= ur:
                top = -1.0
            if prev_uc >= 0.0 >= uc:
                right = 1.0
            if prev_uc <= 0.0 <= uc:
                left = -1.0
            _draw_box(
                mr + big * top, mr + big * bottom, mc + big * left, mc + big * right, height, width, out_lo, out_hi
            )
            if radius != prev_radius:
                # The slivers: P + a u + s n (n = (u_c, -u_r)) with a in [0, along] behind the end of piece 1
                # or ahead of the start of piece 2, r < |s| <= R: inside that rectangle with |s| <= R.
                small = min(radius, prev_radius)
                along = math.sqrt(big * big - small * small)
                if prev_radius < radius:
                    _draw_rectangle(mr - along * prev_ur, mc - along * prev_uc, prev_ur, prev_uc, along, big,
                                    big * abs(prev_uc), height, width, out_lo, out_hi)  # fmt: skip
                else:
                    _draw_rectangle(mr, mc, ur, uc, along, big, big * abs(uc), height, width, out_lo, out_hi)
        else:
            _draw_disc(mr, mc, big, height, width, out_lo, out_hi)
        _draw_rectangle(mr, mc, ur, uc, length, radius, radius * abs(uc), height, width, out_lo, out_hi)
        prev_radius = radius
        prev_ur = ur
        prev_uc = uc
        prev_length = length
        i = b
    count = 0
    for r in range(height):
        if out_hi[r] >= out_lo[r]:
            count += 1
        else:
            out_lo[r] = 1
            out_hi[r] = 0
    return count


@kernel(boolean(int32, int32, i4_1d_ro, i4_1d_ro))
def in_spans(r, c, lo, hi):
    """Return True when pixel (r, c) lies inside the row spans `lo`/`hi`."""
    if r < 0 or r >= lo.shape[0]:
        return False
    return lo[r] <= c <= hi[r]


@kernel(int32(i4_1d_ro, i4_1d_ro, i4_1d, i4_1d))
def union_spans(lo, hi, out_lo, out_hi):
    """Widen the row spans `out_lo`/`out_hi` to also cover `lo`/`hi` (an empty span has ``hi < lo``); returns the
    number of non-empty rows (one span per row: the union of two disjoint spans also covers the gap)."""
    count = 0
    for r in range(out_lo.shape[0]):
        if hi[r] >= lo[r]:
            if out_hi[r] < out_lo[r]:
                out_lo[r] = lo[r]
                out_hi[r] = hi[r]
            else:
                out_lo[r] = min(out_lo[r], lo[r])
                out_hi[r] = max(out_hi[r], hi[r])
        if out_hi[r] >= out_lo[r]:
            count += 1
    return count


@kernel(int32(u1_2d_ro, int32, int32, int32, int32, i4_2d, i4_2d, i4_1d, i4_1d, i4_1d))
def coarse_spans(frame, block, step_sum, min_cells, dilate, out_sums, out_labels, stack, out_lo, out_hi):
    """Find where the rope may be from block sums, without edge detection: write row spans covering it.

    The frame is cut into `block` x `block` cells (the last partial row and column of cells are left out) whose
    sums go into `out_sums` (at least (height // block, width // block)). A cell is active when a 4-neighbour's
    sum differs from its own by at least `step_sum` (an intensity step of ``step_sum / block**2`` grey levels).
    Of the 8-connected groups of active cells (labels in `out_labels`, `stack` needs one slot per cell) those of
    at least `min_cells` cells are kept; the spans cover them grown by `dilate` cells on every side (and reach the
    image border where they touch the left-out partial cells). Returns the number of kept cells (0: empty spans).
    """
    height = frame.shape[0]
    width = frame.shape[1]
    gh = height // block
    gw = width // block
    if gh < 1 or gw < 1 or out_sums.shape[0] < gh or out_sums.shape[1] < gw:
        return 0
    if out_labels.shape[0] < gh or out_labels.shape[1] < gw or stack.shape[0] < gh * gw:
        return 0
    if stack.shape[0] < width:
        return 0
    size = height * width
    f = frame.reshape(size)
    acc = stack[:width]  # column sums of one row of cells (the stack is free until the flood fill)
    for i in range(gh):
        for c in range(width):
            acc[c] = 0
        for r in range(i * block, (i + 1) * block):
            base = np.uint64(r * width)
            for c in range(width):
                acc[c] += np.int32(f[base + np.uint64(c)])
        for j in range(gw):
            total = np.int32(0)
            for k in range(j * block, (j + 1) * block):
                total += acc[k]
            out_sums[i, j] = total
    for i in range(gh):
        for j in range(gw):
            s = out_sums[i, j]
            step = 0
            if j > 0:
                step = max(step, abs(out_sums[i, j - 1] - s))
            if j < gw - 1:
                step = max(step, abs(out_sums[i, j + 1] - s))
            if i > 0:
                step = max(step, abs(out_sums[i - 1, j] - s))
            if i < gh - 1:
                step = max(step, abs(out_sums[i + 1, j] - s))
            active = step >= step_sum
            out_labels[i, j] = -1 if active else 0
    # Flood-fill the active cells; a group too small is marked -2 (kept as visited), a group kept gets 1.
    kept = 0
    for i0 in range(gh):
        for j0 in range(gw):
            if out_labels[i0, j0] != -1:
                continue
            out_labels[i0, j0] = -3
            stack[0] = i0 * gw + j0
            top = 1
            first = 0
            while first < top:  # breadth first: the stack holds the whole group afterwards
                i = stack[first] // gw
                j = stack[first] - i * gw
                first += 1
                for di in range(-1, 2):
                    for dj in range(-1, 2):
                        ii = i + di
                        jj = j + dj
                        if 0 <= ii < gh and 0 <= jj < gw and out_labels[ii, jj] == -1:
                            out_labels[ii, jj] = -3
                            stack[top] = ii * gw + jj
                            top += 1
            mark = 1 if top >= min_cells else -2
            for t in range(top):
                i = stack[t] // gw
                out_labels[i, stack[t] - i * gw] = mark
            if mark == 1:
                kept += top
    for r in range(height):
        out_lo[r] = width
        out_hi[r] = -1
    if kept == 0:
        for r in range(height):
            out_lo[r] = 1
            out_hi[r] = 0
        return 0
    for i in range(gh):
        j_min = gw
        j_max = -1
        for j in range(gw):
            if out_labels[i, j] == 1:
                if j < j_min:
                    j_min = j
                j_max = j
        if j_max < 0:
            continue
        c0 = max(0, (j_min - dilate) * block)
        c1 = (j_max + 1 + dilate) * block - 1
        if j_max + 1 + dilate >= gw:
            c1 = width - 1
        c1 = min(c1, width - 1)
        r0 = max(0, (i - dilate) * block)
        r1 = (i + 1 + dilate) * block - 1
        if i + 1 + dilate >= gh:
            r1 = height - 1
        r1 = min(r1, height - 1)
        for r in range(r0, r1 + 1):
            if c0 < out_lo[r]:
                out_lo[r] = c0
            if c1 > out_hi[r]:
                out_hi[r] = c1
    for r in range(height):
        if out_hi[r] < out_lo[r]:
            out_lo[r] = 1
            out_hi[r] = 0
    return kept
