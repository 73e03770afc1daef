"""Shapes that cross: where the rope at the start and at the end of the exposure cross each other, each side of the
blurred band is the start shape on one stretch and the end shape on the next.

The split makes its two shapes from the band's two sides, and the time order (`tracking.order_shapes`) decides
which side is the start of the exposure from the tip's path. That is right for the whole rope only while every part
of it moves the same way across the band. A wave that runs down a swinging rope moves its middle one way and its
tip the other; the two true shapes then cross where the motion changes sign, the band pinches there to the rope's
width, and beyond the pinch the side that was the start shape is the end shape. Measured on the simulated `lab`
preset (240 frames, 2 s of a swing, tuning seed), a quarter of the frames had such a crossing and their centreline
error was 1-5 px with both tips right.

`uncross_shapes` finds the pinches (interior local minima, below the rope's width, of the distance from the start
shape to the end shape, over the distance the split reads by the fixed end, `FLOOR_SPAN`, or deep below the
distance either side, `PROMINENCE`) and decides each stretch between two pinches by continuity: between exposures
the rope moves on from where the last one ended, so of the two sides on a stretch, the start shape is the one
nearer to the previous frame's end shape. The stretch that holds the tip keeps the tip's order. By the fixed end
the two shapes lie too close for nearness to say anything, and the edges' noise cuts that part into many short
stretches: they take the side of the first stretch beyond them that nearness orders, unless the separation dips
between them (a crossing by the fixed end). A stretch further on whose sides lie too close for nearness (between
two crossings at the turn of the swing) takes the side of the next decided stretch towards the tip (the tip's own
at last), exchanged once for every crossing between the two (`_resolve_sides`). The previous end shape (or the
one shape of a one-shape frame) is kept in the time order's group (`Order`): ``prev_end`` and its count and time
in ``state``.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float64, int32, int64, types

from ropecam.device.pipeline._kernels.groups import ORDER, ORDER_PREV_COUNT, ORDER_PREV_T
from ropecam.shared.jit import f4_2d, kernel

PINCH_WIDTHS: Final = 0.5
"""A pinch is closer than this many rope widths: the two shapes cross there (a true crossing's distance is the
edges' noise; splicing at a wider one would leave a step of that size in both shapes)."""
FLOOR_SPAN: Final = 40
"""The separation the split reads where the rope cannot move, by its fixed end (the smallest over the first
1 / `FLOOR_SPAN` of the start shape's points, at least three), is added to the pinch's limit (up to `PINCH_WIDTHS`
rope widths more). The local sweep read from the edge slope does not reach 0 on a still stretch under a strong
blur: on ``paper-soft`` (simulated, tuning seed) the two shapes lie 0.3-0.6 px apart by the fixed end, and 1.3-1.6
px apart where the true shapes cross (0.2 px), above 0.5 rope widths (1.26 px): the crossing was not seen, and the
shapes were exchanged from the fixed end to the crossing (centreline 1-3 px off, both tips right, reported OK). A
fixed end anchored on a plane calibration reads 0 there: the limit is then `PINCH_WIDTHS` rope widths."""
PROMINENCE: Final = 0.35
"""Between that limit and one rope width, an interior local minimum is a pinch when it lies below this fraction of
the largest separation on either side of it (before it back to the last pinch, after it up to the tip): a
crossing whose sides are read too far apart (the sweep from the edge slope over-read by a contrast or lens blur
read 10 % off, ``paper-soft`` 15 ms: 1.3-1.7 px where the true shapes cross) still dips to a third or less of the
separation around it."""
DECISIVE: Final = 0.25
"""A stretch is exchanged only when the other side is nearer to the previous end shape by this fraction of the
stretch's mean separation, and that separation is at least `PINCH_WIDTHS` rope widths: where the two sides lie
within noise of each other, nearness decides nothing (measured: a rope swinging as a rigid pendulum, whose shapes
never cross, had stretches by the fixed end exchanged on noise, with steps in the shapes)."""
CROSSING_PEAK_WIDTHS: Final = 0.4
"""A pinch between two stretches is a crossing (the band's sides change shapes there) only when the separation
on both sides of it reaches this many rope widths: below, the noise of the edges makes pinches (by the fixed end)
whose sides lie too close for an exchange to matter."""
_RESOLVED: Final = 3.0
"""Added to the side (0 keep, 1 exchange) an undecided stretch takes from its neighbours (`_resolve_sides`)."""
_WINDOW: Final = 24
"""Segments searched either side of the proportional guess for the first point of a stretch on another shape: the
shapes run the same way from the fixed end with similar point spacing, so a point's match is near the same arc
fraction; the window covers the along-rope shift of a fast tip over one exposure and one gap."""
_BACK: Final = 3
_AHEAD: Final = 5
"""The next point's match is searched from `_BACK` segments before the last match to `_AHEAD` after it: both
shapes are spaced at the output step, so a match moves on by about one point per point (a window of 48 segments
for every point cost ~225 us per frame on a 200-point rope; tracked, ~8 segments)."""


_NEAR: Final = 1e-9
"""Two squared distances closer than this fraction of each other are too close to order by their squares
(`nearest_on` then orders them by `math.hypot`, as it reports them); farther apart, the squares order them as
their roots do (both within a few ulp of the true distance)."""
_TINY: Final = 1e-290
"""Added to `_NEAR`'s margin: squares of distances below ~1e-145 px lose their precision (subnormals)."""


@kernel(types.UniTuple(float64, 2)(float64, float64, f4_2d, int64, int64, int64))
def nearest_on(r, c, poly, n, lo, hi):
    """Distance from (`r`, `c`) to the polyline ``poly[:n]`` (n >= 1) over its segments `lo` .. `hi` - 1 (clipped
    to the polyline; at least one), and the index of its vertex nearest to the foot of that distance. Returns
    (distance, index): the first segment of the smallest `math.hypot` distance.

    Segments are compared by their squared distances, and `math.hypot` (a libm call, most of the cost when it ran
    on every segment) is taken only of the nearest one and of a segment whose square ties with the nearest's
    within `_NEAR`: the same segment, index and distance as `math.hypot` of every segment."""
    if n == 1:
        return math.hypot(r - poly[0, 0], c - poly[0, 1]), 0.0
    lo = max(0, lo)
    hi = min(n - 1, hi)
    if lo >= hi:
        lo = max(0, hi - 1)
    best = math.inf  # the nearest segment's hypot distance; -1: not taken yet
    best_d2 = math.inf
    best_x = 0.0
    best_y = 0.0
    best_i = lo
    for i in range(lo, hi):
        ar = float(poly[i, 0])
        ac = float(poly[i, 1])
        dr = float(poly[i + 1, 0]) - ar
        dc = float(poly[i + 1, 1]) - ac
        length2 = dr * dr + dc * dc
        t = 0.0
        if length2 > 0.0:
            t = min(max(((r - ar) * dr + (c - ac) * dc) / length2, 0.0), 1.0)
        x = r - ar - t * dr
        y = c - ac - t * dc
        d2 = x * x + y * y
        if d2 > best_d2 * (1.0 + _NEAR) + _TINY or d2 != d2:
            continue  # farther (or not a number, which `d < best` never takes)
        if best_d2 != math.inf and d2 >= best_d2 * (1.0 - _NEAR) - _TINY:
            # Within rounding of the nearest so far: the first of equal hypot distances stays.
            if best < 0.0:
                best = math.hypot(best_x, best_y)
            d = math.hypot(x, y)
            if not d < best:
                continue
            best = d
        else:
            best = -1.0
        best_d2 = d2
        best_x = x
        best_y = y
        best_i = i + 1 if t > 0.5 else i
    if best < 0.0:
        best = math.hypot(best_x, best_y)
    return best, float(best_i)


@kernel(float64(f4_2d, int64, int64, f4_2d, int64))
def _mean_distance(shape, first, stop, other, m):
    """Mean distance of ``shape[first:stop]`` (stop > first) to the polyline ``other[:m]``: the first point
    matched within `_WINDOW` of its arc fraction, the next ones tracked from the last match."""
    n = shape.shape[0]
    total = 0.0
    guess = (first * (m - 1)) // max(1, n - 1)
    lo = guess - _WINDOW
    hi = guess + _WINDOW
    for k in range(first, stop):
        d, j = nearest_on(float(shape[k, 0]), float(shape[k, 1]), other, m, lo, hi)
        total += d
        lo = int(j) - _BACK
        hi = int(j) + _AHEAD
    return total / (stop - first)


@kernel(int64(f4_2d, int64, int64, f4_2d))
def _resample_into(source, count, out_count, out):
    """Resample the polyline ``source[:count]`` (count >= 2) to `out_count` (>= 2) points evenly spaced along its
    arc into ``out[:out_count]`` (not `source`). Returns `out_count`."""
    total = 0.0
    for i in range(count - 1):
        total += math.hypot(float(source[i + 1, 0] - source[i, 0]), float(source[i + 1, 1] - source[i, 1]))
    step = total / (out_count - 1)
    i = 0
    walked = 0.0
    seg = math.hypot(float(source[1, 0] - source[0, 0]), float(source[1, 1] - source[0, 1]))
    for k in range(out_count):
        target = k * step
        while i < count - 2 and walked + seg < target:
            walked += seg
            i += 1
            seg = math.hypot(float(source[i + 1, 0] - source[i, 0]), float(source[i + 1, 1] - source[i, 1]))
        t = 0.0 if seg <= 0.0 else min(max((target - walked) / seg, 0.0), 1.0)
        out[k, 0] = np.float32(source[i, 0] + t * (source[i + 1, 0] - source[i, 0]))
        out[k, 1] = np.float32(source[i, 1] + t * (source[i + 1, 1] - source[i, 1]))
    out[out_count - 1, 0] = source[count - 1, 0]
    out[out_count - 1, 1] = source[count - 1, 1]
    return out_count


@kernel(types.UniTuple(int64, 3)(f4_2d, int64, int64, int64, int64, int64, float64, float64))
def _next_stretch(match, nb, ne, k, start_b, start_e, limit, width_px):
    """The stretch of the begin shape that starts at point `start_b` (its match on the end shape at `start_e`),
    searched for its pinch from point `k` on (``match[:nb]``: each begin point's distance to the end shape and
    the index of its match there, of `ne` points; the pinches' `limit` and the rope's width as in
    `uncross_shapes`). Returns (the point where it ends, its stop on begin, its stop on end): the last stretch
    (the tip's, to point ``nb - 2``) stops at `nb` and `ne`."""
    while k < nb - 1:
        last = k == nb - 2
        gap = match[k, 0]
        pinch = gap <= match[k - 1, 0] and gap <= match[k + 1, 0] and gap < width_px
        if pinch and gap >= limit:
            # Above the limit only a dip to `PROMINENCE` of the separation on both sides is a crossing.
            before = 0.0
            for i in range(start_b, k):
                before = max(before, float(match[i, 0]))
            after = 0.0
            for i in range(k + 1, nb):
                after = max(after, float(match[i, 0]))
            pinch = gap <= PROMINENCE * min(before, after)
        if pinch or last:
            stop_b = nb if last else k
            stop_e = ne if last else min(max(int(match[k, 1]), start_e + 1), ne - 1)
            if last or (stop_b - start_b >= 2 and stop_e - start_e >= 2):
                return k, stop_b, stop_e
        k += 1
    return nb - 2, nb, ne


@kernel(int64(f4_2d, f4_2d, f4_2d, int64, int64, int64, int64, f4_2d, int64, float64))
def _side_of(begin, end, match, start_b, stop_b, start_e, stop_e, prev, n_prev, width_px):
    """Which side the stretch ``begin[start_b:stop_b]`` / ``end[start_e:stop_e]`` takes by nearness to the
    previous end shape ``prev[:n_prev]``: 1 exchange (the end side is nearer by `DECISIVE` of their mean
    separation, from ``match``), 0 keep, -1 undecided (the sides lie less than `PINCH_WIDTHS` rope widths
    apart: nearness says nothing)."""
    separation = 0.0
    for i in range(start_b, stop_b):
        separation += match[i, 0]
    separation /= stop_b - start_b
    if not separation >= PINCH_WIDTHS * width_px:
        return -1
    keep = _mean_distance(begin, start_b, stop_b, prev, n_prev)
    other = _mean_distance(end, start_e, stop_e, prev, n_prev)
    return 1 if other < keep - DECISIVE * separation else 0


@kernel(int64(f4_2d, f4_2d, f4_2d, int64, int64, float64, float64, f4_2d, int64, boolean))
def _stretch_sides(begin, end, match, nb, ne, limit, width_px, prev, n_prev, tip_undecided):
    """Walk the stretches between pinches from the fixed end (as `_next_stretch`) and write each one's side into
    ``match[nb + s]`` (rows past the begin points' matches; ``match`` has at least `nb` + `ne` rows and there are
    fewer stretches than `ne`): (`_side_of`'s 1, 0 or -1, the stretch's first point). The tip's stretch keeps
    the tip's order (0) unless `tip_undecided` and nearness exchanges it. Returns the number of stretches."""
    count = 0
    k = 2
    start_b = 0
    start_e = 0
    while k < nb - 1:
        k, stop_b, stop_e = _next_stretch(match, nb, ne, k, start_b, start_e, limit, width_px)
        last = stop_b == nb
        side = 0
        if not last or tip_undecided:
            side = _side_of(begin, end, match, start_b, stop_b, start_e, stop_e, prev, n_prev, width_px)
            if last:
                side = max(side, 0)
        match[nb + count, 0] = np.float32(side)
        match[nb + count, 1] = np.float32(start_b)
        count += 1
        start_b = stop_b
        start_e = stop_e
        if last:
            break
        k += 1
    return count


@kernel(boolean(f4_2d, int64, int64, float64))
def _crossing(match, nb, k, least_peak):
    """Whether the pinch at begin point `k` (``match[:nb]``: each begin point's distance to the end shape) is a
    crossing: its distance at most `PROMINENCE` of the largest separation on each side of it (up to where the
    separation falls below the pinch's again), and both of those at least `least_peak`."""
    gap = float(match[k, 0])
    left = 0.0
    i = k - 1
    while i >= 0 and float(match[i, 0]) >= gap:
        left = max(left, float(match[i, 0]))
        i -= 1
    right = 0.0
    i = k + 1
    while i < nb and float(match[i, 0]) >= gap:
        right = max(right, float(match[i, 0]))
        i += 1
    peak = min(left, right)
    return peak >= least_peak and gap <= PROMINENCE * peak


@kernel(types.void(f4_2d, int64, int64, float64))
def _resolve_sides(match, nb, count, least_peak):
    """Give each undecided stretch of ``match[nb:nb + count]`` (`_stretch_sides`' rows) a side, written as
    `_RESOLVED` + that side (0 keep, 1 exchange; the decided rows keep theirs).

    The stretches before the first decided one (by the fixed end) take its exchange back to where the separation
    between them and it dips to `PROMINENCE` of their own largest (a crossing by the fixed end), and keep their
    side beyond (as do all of them when it keeps its side: a dip by the fixed end is as often two shapes that
    come close without crossing, read closer than they are). A stretch after a decided one takes the side of the
    nearest decided stretch towards the tip (the tip's own at last), exchanged once for every crossing
    (`_crossing`) between the two: the band's side that is one shape before a crossing is the other shape after
    it."""
    first = count
    for s in range(count):
        if match[nb + s, 0] >= 0.0:
            first = s
            break
    cut = nb
    if first < count and match[nb + first, 0] == 1.0:
        start = int(match[nb + first, 1])
        cut = start
        valley = float(match[start, 0])
        for s in range(first - 1, -1, -1):
            lo = int(match[nb + s, 1])
            hi = int(match[nb + s + 1, 1])
            peak = 0.0
            low = math.inf
            for i in range(lo, hi):
                peak = max(peak, float(match[i, 0]))
                low = min(low, float(match[i, 0]))
            if valley <= PROMINENCE * peak:
                break
            cut = lo
            valley = min(valley, low)
    for s in range(min(first, count)):
        match[nb + s, 0] = np.float32(_RESOLVED + (1.0 if match[nb + s, 1] >= cut else 0.0))
    for s in range(first + 1, count):
        if match[nb + s, 0] >= 0.0:
            continue
        # The tip's stretch is always decided (`_stretch_sides`), so one lies beyond every undecided stretch.
        side = 0
        flips = 0
        for t in range(s + 1, count):
            if _crossing(match, nb, int(match[nb + t, 1]), least_peak):
                flips += 1
            value = match[nb + t, 0]
            if value == 0.0 or value == 1.0:
                side = int(value)
                break
        match[nb + s, 0] = np.float32(_RESOLVED + ((side + flips) % 2))


@kernel(int32(f4_2d, f4_2d, boolean, int64, int64, float64, boolean, ORDER))
def uncross_shapes(begin, end, single, t_end_ns, max_age_ns, width_px, tip_undecided, order):
    """Exchange the stretches of `begin` and `end` (float32 (n, 2), fixed end first, in time order by the tip)
    that the previous frame's end shape says are the other way round, between the pinches where the two cross;
    then remember `end` as the previous end shape (exposure ending at `t_end_ns`).

    A pinch is an interior local minimum of the distance from a point of `begin` to `end` below `PINCH_WIDTHS` x
    `width_px` plus the distance read by the fixed end (`FLOOR_SPAN`, at most as much again), or below `width_px`
    and `PROMINENCE` x the largest distance on either side of it. On every stretch between pinches but the last
    (the tip's; it too when `tip_undecided`: the tips' order was a coin flip), the side decisively nearer
    (`DECISIVE`) to the previous end shape (kept at most `max_age_ns` before this exposure's end) is the start of
    the exposure. The stretches before the first one that nearness decides (sides less than `PINCH_WIDTHS`
    rope widths apart: by the fixed end, where the edges' noise makes pinches every few points) take its
    exchange, back to where the separation between a stretch and it dips to `PROMINENCE` of that stretch's
    largest (a crossing there): without one they are part of the same stretch of rope, moving the one way. An
    undecided stretch after a decided one takes the side of the nearest decided stretch towards the tip (the tip's
    stretch, in the tip's order, at last), exchanged once for every crossing between them (`_crossing`: a pinch
    below `PROMINENCE` of the separation on both sides, each at least `CROSSING_PEAK_WIDTHS` rope widths). The
    exchanged shapes keep their point counts (each resampled evenly along its new arc). Nothing is exchanged for
    a `single` shape (it is remembered as the previous end shape: the rope at mid-exposure, from which the next
    exposure's start lies nearer than its end, as from an end shape), without a previous end shape, or when a
    shape is longer than ``order.prev_end``. Uses ``order.splice`` as scratch (its rows hold the new begin, the
    new end, and each begin point's (distance, match) on `end`, then each stretch's side and first point).

    Returns the stretches exchanged (0 or more), or -1 when the shapes were not looked at.
    """
    prev = order.prev_end
    splice = order.splice
    state = order.state
    cap = prev.shape[0]
    nb = begin.shape[0]
    ne = end.shape[0]
    if nb > cap or ne > cap or splice.shape[0] < 3 or splice.shape[1] < nb + ne:
        state[ORDER_PREV_COUNT] = 0
        return -1
    n_prev = state[ORDER_PREV_COUNT]
    fresh = n_prev >= 2 and 0 <= t_end_ns - state[ORDER_PREV_T] <= max_age_ns
    flipped = 0
    if fresh and nb >= 5 and ne >= 5 and not single:
        # The distance of each begin point to the end shape, and its match there (in splice[2]).
        match = splice[2]
        lo = 0
        hi = _WINDOW
        for k in range(nb):
            d, j = nearest_on(float(begin[k, 0]), float(begin[k, 1]), end, ne, lo, hi)
            match[k, 0] = np.float32(d)
            match[k, 1] = np.float32(j)
            lo = int(j) - _BACK
            hi = int(j) + _AHEAD
        # The separation read by the fixed end (`FLOOR_SPAN`), added to the pinches' limit.
        floor = math.inf
        for k in range(max(3, nb // FLOOR_SPAN)):
            floor = min(floor, float(match[k, 0]))
        limit = PINCH_WIDTHS * width_px + min(floor, PINCH_WIDTHS * width_px)
        # Each stretch's side (rows `nb` on of ``match``: the side, the stretch's first point): nearness's, the
        # tip's order for the tip's stretch; then the undecided ones resolved (`_resolve_sides`).
        count = _stretch_sides(begin, end, match, nb, ne, limit, width_px, prev, n_prev, tip_undecided)
        _resolve_sides(match, nb, count, CROSSING_PEAK_WIDTHS * width_px)
        # Stretches between pinches, from the fixed end, each from the side resolved above.
        out_b = splice[0]
        out_e = splice[1]
        kb = 0  # begin's points written
        ke = 0
        start_b = 0
        start_e = 0
        k = 2
        s = 0
        while k < nb - 1 and s < count:
            k, stop_b, stop_e = _next_stretch(match, nb, ne, k, start_b, start_e, limit, width_px)
            last = stop_b == nb
            resolved = match[nb + s, 0]
            swap = resolved == 1.0 or resolved == _RESOLVED + 1.0
            s += 1
            src_b = end if swap else begin
            src_e = begin if swap else end
            lo_b, hi_b = (start_e, stop_e) if swap else (start_b, stop_b)
            lo_e, hi_e = (start_b, stop_b) if swap else (start_e, stop_e)
            for i in range(lo_b, hi_b):
                out_b[kb, 0] = src_b[i, 0]
                out_b[kb, 1] = src_b[i, 1]
                kb += 1
            for i in range(lo_e, hi_e):
                out_e[ke, 0] = src_e[i, 0]
                out_e[ke, 1] = src_e[i, 1]
                ke += 1
            if swap:
                flipped += 1
            start_b = stop_b
            start_e = stop_e
            if last:
                break
            k += 1
        if flipped > 0 and kb >= 2 and ke >= 2:
            _resample_into(out_b, kb, nb, begin)
            _resample_into(out_e, ke, ne, end)
        else:
            flipped = 0
    for k in range(ne):
        prev[k, 0] = end[k, 0]
        prev[k, 1] = end[k, 1]
    state[ORDER_PREV_COUNT] = ne
    state[ORDER_PREV_T] = t_end_ns
    return -1 if single else flipped
