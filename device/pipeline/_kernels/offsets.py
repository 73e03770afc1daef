"""Polarity, rope width and gradient-based inward offsets of the contour sides."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import float32, float64, int32, int64, void

from ropecam.device.pipeline._kernels._common import FULL, INVALID, NOT_FOUND, f4_1d_ro, prefetch_read, vector_length
from ropecam.device.pipeline._kernels.geometry import axis_offset, chain_length, chain_step_length, linear_sweep_shift
from ropecam.shared.jit import (
    f4_1d,
    f4_2d,
    f4_2d_ro,
    f8_1d,
    f8_1d_ro,
    i4_1d,
    i4_1d_ro,
    i4_2d_ro,
    kernel,
    u1_2d_ro,
)

_AHEAD: Final = 16
"""Chain points ahead whose plane values `side_sweeps` and `offset_by_table` ask the caches for."""
_DENSE_ENDS: Final = 1.2
"""Arc lengths (in units of the tip fit's skip + span) at both ends of a side offset at every contour point by
`split_shapes`; between them every other point (the output is resampled at 2 px)."""


@kernel(int32(u1_2d_ro, i4_1d_ro, i4_1d_ro, f4_2d_ro, f4_2d_ro, f4_2d_ro, i4_2d_ro, int32, float32, float32, f4_1d))
def measure_widths(edges, lo, hi, mag, gx, gy, chain, n, polarity, max_px, out_width):
    """Write for each contour pixel the distance to the opposite edge of the rope, found by stepping (0.5 px)
    from the pixel into the rope (along ``polarity`` times the gradient) until an edge pixel whose gradient points
    the other way; both ends are refined to subpixel (parabola of `mag` along the image axis nearest the
    gradient) and the distance is taken along the stepping direction. ``nan`` when no opposite edge lies within
    `max_px` or the step leaves the row spans `lo`/`hi` the edges were detected in (beyond them the planes hold
    what earlier frames left). Returns `n`."""
    height = edges.shape[0]
    width = edges.shape[1]
    if lo.shape[0] < height or hi.shape[0] < height:
        return INVALID
    for i in range(n):
        r = chain[i, 0]
        c = chain[i, 1]
        g_r = gy[r, c] * polarity
        g_c = gx[r, c] * polarity
        norm = math.sqrt(g_r * g_r + g_c * g_c)
        out_width[i] = np.nan
        if norm <= 0.0:
            continue
        u_r = g_r / norm
        u_c = g_c / norm
        steps = int(max_px * 2.0)
        for k in range(2, steps + 1):
            t = 0.5 * k
            rr = math.floor(r + t * u_r + 0.5)
            cc = math.floor(c + t * u_c + 0.5)
            if rr < 0 or rr >= height or cc < lo[rr] or cc > hi[rr] or cc < 0 or cc >= width:
                break
            if (rr != r or cc != c) and edges[rr, cc] != 0:
                dot = (gy[rr, cc] * u_r + gx[rr, cc] * u_c) * polarity
                if dot < 0.0:
                    d0r, d0c = axis_offset(mag, gx, gy, r, c)
                    d1r, d1c = axis_offset(mag, gx, gy, rr, cc)
                    out_width[i] = (rr + d1r - r - d0r) * u_r + (cc + d1c - c - d0c) * u_c
                    break
    return n


@kernel(int32(f4_1d_ro, f4_2d_ro, int32, int32, float32, i4_1d))
def find_caps(turn, points, n, min_gap, min_dist, out_idx):
    """Write into `out_idx` the contour indices of the two rope ends: the largest turning angle, then the largest
    at least `min_gap` chain steps and `min_dist` px (between the `points`) from it (none so far: the largest at
    least `min_gap` steps away, as before the distance). Returns 2 or NOT_FOUND.

    The distance: a band open at the clamp is traced out and back, so each of its pixels comes twice, a
    contour's length apart; the open ends' U-turns (turning through 180 degrees) then made both "ends", and the
    static centreline ran from the clamp to the tip and back (lab-dark, 240 frames: 212 and 213, tips 372 px off).
    """
    if n < 3:
        return NOT_FOUND
    e1 = 0
    for i in range(n):
        if turn[i] > turn[e1]:
            e1 = i
    e2 = -1
    best = -1.0
    near = -1  # the largest at least `min_gap` steps away, however near: taken when no end lies `min_dist` away
    best_near = -1.0
    for i in range(n):
        gap = abs(i - e1)
        if min(gap, n - gap) < min_gap:
            continue
        if turn[i] > best_near:
            best_near = turn[i]
            near = i
        if turn[i] > best and math.hypot(points[i, 0] - points[e1, 0], points[i, 1] - points[e1, 1]) >= min_dist:
            best = turn[i]
            e2 = i
    if e2 < 0:
        e2 = near
    if e2 < 0:
        return NOT_FOUND
    out_idx[0] = e1
    out_idx[1] = e2
    return 2


@kernel(void(f4_2d_ro, i4_2d_ro, int64, f4_2d_ro, f4_2d_ro, float32, float64, f4_2d, int64))
def place_along_gradient(points, chain, i, gx, gy, polarity, shift, out_poly, k):
    """Write contour point `i` moved by `shift` px along ``polarity`` times the gradient at its chain pixel (into
    the rope) to ``out_poly[k]``; unmoved where the gradient is zero. The one placement rule of the offset kernels."""
    r = chain[i, 0]
    c = chain[i, 1]
    g_r = gy[r, c] * polarity
    g_c = gx[r, c] * polarity
    norm = math.sqrt(g_r * g_r + g_c * g_c)
    out_poly[k, 0] = points[i, 0]
    out_poly[k, 1] = points[i, 1]
    if norm > 0.0:
        out_poly[k, 0] += shift * g_r / norm
        out_poly[k, 1] += shift * g_c / norm


@kernel(int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, f4_2d_ro, float32, float32, float32, f4_2d))
def offset_by_gradient(
    points, chain, n, i_start, i_stop, direction, gx, gy, polarity, width_px, sweep_tip_px, out_poly
):
    """Copy the contour from `i_start` to `i_stop` (stepping `direction` = +1 or -1, cyclic) into `out_poly`,
    each point moved into the rope along ``polarity`` times its gradient direction by
    ``max(0, (width_px - sweep(s)) / 2)``, the sweep growing linearly with arc length s from 0 at `i_start` to
    `sweep_tip_px` at `i_stop` (see `offset_side`). The gradient knows where the rope is even where the contour
    doubles back (a rope leaving the image, a crossing). Returns the number of points written or FULL."""
    count = (i_stop - i_start) * direction
    count = (count % n + n) % n + 1
    if count > out_poly.shape[0]:
        return FULL
    total = chain_length(points, n, i_start, count, direction)
    s = 0.0
    for k in range(count):
        i = (i_start + k * direction + n * 4) % n
        if k > 0:
            s += chain_step_length(points, n, i_start, direction, k)
        shift = 0.5 * width_px
        if total > 0.0:
            shift = linear_sweep_shift(width_px, sweep_tip_px, s, total)
        place_along_gradient(points, chain, i, gx, gy, polarity, shift, out_poly, k)
    return count


@kernel(void(f4_1d, int64, int64, f4_1d))
def box_mean(work, count, half, out):
    """Write into ``out[:count]`` the mean of ``work[:count]`` over the ``2 half + 1`` points centred on each (the
    end points repeated beyond the ends), as a running sum (float64)."""
    acc = 0.0
    for j in range(-half, half + 1):
        acc += work[min(max(j, 0), count - 1)]
    width = 2 * half + 1
    for k in range(count):
        out[k] = acc / width
        acc += work[min(k + half + 1, count - 1)] - work[max(k - half, 0)]


@kernel(
    int32(i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, float32, f8_1d_ro, f8_1d_ro, f8_1d_ro, int32, f4_1d, f4_1d)
)  # fmt: skip
def side_sweeps(
    chain, n, i_start, i_stop, direction, mag, inv_contrast, gains, ratios, sweeps, half, work, out_sweeps
):  # fmt: skip
    """Write the local sideways sweep (px) at each contour point of one side (from `i_start` stepping `direction`
    to `i_stop`, cyclic) into `out_sweeps`: the gradient magnitude at its chain pixel times `inv_contrast` (times
    ``gains[k]`` at the k-th point when `gains` holds the side's points: the frame's contrast over the point's own,
    `contrast_gains`; empty: 1), turned into a sweep by the table (`ratios` increasing, `sweeps`;
    `BandEdgeModel`), then averaged over +-`half` points (ends repeated). `work` is scratch of the same length
    (it keeps the raw sweeps). Returns the number of points or FULL (`gains` neither empty nor as long)."""
    count = ((i_stop - i_start) * direction % n + n) % n + 1
    if count > out_sweeps.shape[0] or count > work.shape[0]:
        return FULL
    local = gains.shape[0] > 0
    if local and gains.shape[0] < count:
        return FULL
    # The table lookup walks from the last point's interval (neighbours' ratios are close): the same interval as
    # a bisection finds (the last `lo` with ratios[lo] <= x), without its unpredictable branches.
    m = ratios.shape[0]
    lo = 0
    i = (i_start + 4 * n) % n
    # The chain pixels' cache lines are scattered (a new row every step or two): ask for them `_AHEAD` points early.
    flat_mag = mag.reshape(mag.size)
    cols = mag.shape[1]
    ahead = (i_start + _AHEAD * direction + 4 * n) % n
    for k in range(count):
        if k + _AHEAD < count:
            prefetch_read(flat_mag, chain[ahead, 0] * cols + chain[ahead, 1])
            ahead += direction
            if ahead == n:
                ahead = 0
            elif ahead < 0:
                ahead = n - 1
        x = mag[chain[i, 0], chain[i, 1]] * inv_contrast
        if local:
            x = np.float32(x * gains[k])
        if m == 0:
            work[k] = np.nan
        elif x <= ratios[0]:
            work[k] = sweeps[0]
        elif x >= ratios[m - 1]:
            work[k] = sweeps[m - 1]
        else:
            while lo > 0 and ratios[lo] > x:
                lo -= 1
            while lo < m - 2 and ratios[lo + 1] <= x:
                lo += 1
            span = ratios[lo + 1] - ratios[lo]
            t = (x - ratios[lo]) / span if span > 0.0 else 0.0
            work[k] = np.float32(sweeps[lo] + t * (sweeps[lo + 1] - sweeps[lo]))
        i += direction
        if i == n:
            i = 0
        elif i < 0:
            i = n - 1
    box_mean(work, count, half, out_sweeps)
    return count


@kernel(
    int32(i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, float32, f8_1d_ro, f8_1d_ro, f8_1d_ro, i4_1d_ro, int32,
          f4_1d, f4_1d)
)  # fmt: skip
def side_sweeps_indexed(
    chain, n, i_start, i_stop, direction, mag, inv_contrast, gains, ratios, sweeps, index, half, work, out_sweeps
):  # fmt: skip
    """`side_sweeps` with the table's interval found by an `index` of `ratios` (``2 nb`` values, made once per
    table by `BlurSplitter`'s per-width constants, see `split.py`'s `_sweep_index`): the same values bit for bit.

    A point's ratio x falls in bucket ``b = int(clip((x - ratios[0]) * scale, 0, nb - 1))``, ``scale = nb /
    (ratios[-1] - ratios[0])``; ``index[2 b]`` is the last ratio below the bucket's (the count of ratios in
    lower buckets, less one), ``index[2 b + 1]`` the last ratio in it, and a bucket holds one distinct ratio value
    at most: the interval is one of the two, chosen by one compare. The rounded bucket is a non-decreasing
    function of x, the index was made with the same operations, so no interval is missed. The clamps at the
    table's ends are selects on the interpolated value (computed anyway): neighbouring points alternate between
    the clamp and the interior, a walk from the last interval mispredicted its branches. `ratios` needs two
    values or more, its last above its first. `gains` as `side_sweeps`'. Returns the number of points or FULL.
    """
    count = ((i_stop - i_start) * direction % n + n) % n + 1
    if count > out_sweeps.shape[0] or count > work.shape[0]:
        return FULL
    local = gains.shape[0] > 0
    if local and gains.shape[0] < count:
        return FULL
    m = ratios.shape[0]
    buckets = index.shape[0] // 2
    r_first = ratios[0]
    r_last = ratios[m - 1]
    s_first = sweeps[0]
    s_last = sweeps[m - 1]
    scale = buckets / (r_last - r_first)
    top = buckets - 1.0
    i = (i_start + 4 * n) % n
    flat_mag = mag.reshape(mag.size)
    cols = mag.shape[1]
    ahead = (i_start + _AHEAD * direction + 4 * n) % n
    # The walk and its prefetch are `side_sweeps`' (written out: see `offset_by_table_thinned`); the lookup
    # differs. One loop for both lookups would choose per point (or call a function argument, which Numba does
    # not inline) in the steady frame's split: kept as two loops.
    for k in range(count):
        if k + _AHEAD < count:  # as in `side_sweeps`
            prefetch_read(flat_mag, chain[ahead, 0] * cols + chain[ahead, 1])
            ahead += direction
            if ahead == n:
                ahead = 0
            elif ahead < 0:
                ahead = n - 1
        x = mag[chain[i, 0], chain[i, 1]] * inv_contrast
        if local:
            x = np.float32(x * gains[k])
        where = (x - r_first) * scale
        where = where if where > 0.0 else 0.0  # (a nan x: bucket 0)
        b = np.int64(where if where < top else top)
        lo = index[2 * b]
        last = index[2 * b + 1]
        lo = last if ratios[last] <= x else lo
        span = ratios[lo + 1] - ratios[lo]  # > 0 inside the table; the clamped values are dropped below
        t = (x - ratios[lo]) / span if span > 0.0 else 0.0
        value = sweeps[lo] + t * (sweeps[lo + 1] - sweeps[lo])
        value = s_last if x >= r_last else value
        work[k] = np.float32(s_first if x <= r_first else value)
        i += direction
        if i == n:
            i = 0
        elif i < 0:
            i = n - 1
    box_mean(work, count, half, out_sweeps)
    return count


@kernel(int32(float32, float32))
def dense_end_points(skip_px, span_px):
    """The points at each end of a side that `split_shapes` offsets one by one (`offset_by_table_thinned`):
    ``_DENSE_ENDS`` times the tip fit's `skip_px` + `span_px` (contour points are at least ~1 px apart), plus one,
    so that the tip fit (`extend_to_band_end`) and the anchoring at the fixed end (`anchor_start`) read the same
    points as on the dense side."""
    return np.int32(int(_DENSE_ENDS * (skip_px + span_px)) + 1)


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, f4_2d_ro, float32, f4_1d_ro, float32, f4_1d_ro,
          int32, int32, f4_2d)
)  # fmt: skip
def offset_by_table_thinned(
    points, chain, n, i_start, i_stop, direction, gx, gy, polarity, sweeps, step_px, table, keep_head, keep_tail,
    out_poly,
):  # fmt: skip
    """`offset_by_table` with local sweeps (``sweeps[k]`` at the k-th point of the side) on fewer points: the
    first `keep_head` and the last `keep_tail` points of the side (from `i_start` to `i_stop`, stepping
    `direction`, cyclic) are all placed, between them every other point (the first and the last point of the
    side always). Each placed point is the same as `offset_by_table`'s. Returns the number of points written or
    FULL."""
    count = (i_stop - i_start) * direction
    count = (count % n + n) % n + 1
    if count > out_poly.shape[0] or count > sweeps.shape[0]:
        return FULL
    last = table.shape[0] - 1
    i = (i_start + n * 4) % n
    flat_gx = gx.reshape(gx.size)
    flat_gy = gy.reshape(gy.size)
    cols = gx.shape[1]
    ahead = (i_start + _AHEAD * direction + 4 * n) % n
    tail = count - keep_tail
    out = 0
    # The walk, its prefetch and the table lookup are written out here, in `offset_by_table` and (walk and
    # prefetch) in `side_sweeps` / `side_sweeps_indexed` on purpose: folded into step kernels both loops call (the
    # lookup, the cyclic step, the prefetch) they were slower, the calls not inlined away. Measured (script,
    # session 10; a side of 700 points of a rig-sized contour, median of 300 alternating calls): this kernel
    # 16.9 -> 20.4 us (+20 %, twice per steady frame), `side_sweeps` 12.0 -> 12.7 us, `offset_by_table`
    # (its arc length by index too) 38.7 -> 50.7 us.
    for k in range(count):
        if k + _AHEAD < count:  # as in `side_sweeps`
            at = chain[ahead, 0] * cols + chain[ahead, 1]
            prefetch_read(flat_gx, at)
            prefetch_read(flat_gy, at)
            ahead += direction
            if ahead == n:
                ahead = 0
            elif ahead < 0:
                ahead = n - 1
        if k < keep_head or k >= tail or ((k - keep_head) & 1) == 0:
            x = max(sweeps[k], 0.0) / step_px
            j = min(int(x), last)
            shift = table[last]
            if j < last:
                shift = table[j] + (x - j) * (table[j + 1] - table[j])
            place_along_gradient(points, chain, i, gx, gy, polarity, shift, out_poly, out)
            out += 1
        i += direction
        if i == n:
            i = 0
        elif i < 0:
            i = n - 1
    return out


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, f4_2d_ro, float32, f4_1d_ro, int32, float32,
          float32, f4_1d_ro, f4_2d)
)  # fmt: skip
def offset_by_table(
    points, chain, n, i_start, i_stop, direction, gx, gy, polarity, sweeps, local, sweep_tip_px, step_px, table,
    out_poly,
):  # fmt: skip
    """Copy the contour from `i_start` to `i_stop` (stepping `direction`, cyclic) into `out_poly`, each point moved
    into the rope along ``polarity`` times its gradient direction by the modelled offset from the band's edge to
    the rope's axis: ``table[d / step_px]`` (linear interpolation, the last entry beyond) for the local sweep d,
    which is ``sweeps[k]`` when `local` is 1 (`offset_by_table_thinned` keeping every point), else
    ``sweep_tip_px * s / total`` (rotation about the fixed end, s the arc length from `i_start`). Returns the
    number of points written or FULL."""
    count = (i_stop - i_start) * direction
    count = (count % n + n) % n + 1
    if local == 1:
        return offset_by_table_thinned(
            points, chain, n, i_start, i_stop, direction, gx, gy, polarity, sweeps, step_px, table, np.int32(count),
            np.int32(0), out_poly,
        )  # fmt: skip
    if count > out_poly.shape[0]:
        return FULL
    total = chain_length(points, n, i_start, count, direction)
    last = table.shape[0] - 1
    s = 0.0
    i = (i_start + n * 4) % n
    ip = i
    flat_gx = gx.reshape(gx.size)
    flat_gy = gy.reshape(gy.size)
    cols = gx.shape[1]
    ahead = (i_start + _AHEAD * direction + 4 * n) % n
    for k in range(count):  # `offset_by_table_thinned`'s walk and lookup (see the comment there)
        if k + _AHEAD < count:
            at = chain[ahead, 0] * cols + chain[ahead, 1]
            prefetch_read(flat_gx, at)
            prefetch_read(flat_gy, at)
            ahead += direction
            if ahead == n:
                ahead = 0
            elif ahead < 0:
                ahead = n - 1
        if k > 0:
            s += vector_length(points[i, 0] - points[ip, 0], points[i, 1] - points[ip, 1])
        d = sweep_tip_px * s / total if total > 0.0 else 0.0
        x = max(d, 0.0) / step_px
        j = min(int(x), last)
        shift = table[last]
        if j < last:
            shift = table[j] + (x - j) * (table[j + 1] - table[j])
        place_along_gradient(points, chain, i, gx, gy, polarity, shift, out_poly, k)
        ip = i
        i += direction
        if i == n:
            i = 0
        elif i < 0:
            i = n - 1
    return count


@kernel(float64(f8_1d, int64, int64))
def _select(values, m, rank):
    """Return the value of rank `rank` (0-based) of ``values[:m]``, partially reordering them in place so that
    ``values[:rank]`` holds values not above it (quickselect, median-of-three pivots; no recursion, no
    allocation). The same value as ``np.sort(values[:m])[rank]``."""
    lo = 0
    hi = m - 1
    while hi > lo:
        mid = (lo + hi) // 2
        # Median of three as the pivot, moved to values[lo].
        if values[mid] < values[lo]:
            values[mid], values[lo] = values[lo], values[mid]
        if values[hi] < values[lo]:
            values[hi], values[lo] = values[lo], values[hi]
        if values[hi] < values[mid]:
            values[hi], values[mid] = values[mid], values[hi]
        values[lo], values[mid] = values[mid], values[lo]
        pivot = values[lo]
        # Hoare partition of values[lo + 1 .. hi] around the pivot.
        i = lo + 1
        j = hi
        while True:
            while i <= j and values[i] < pivot:
                i += 1
            while i <= j and values[j] > pivot:
                j -= 1
            if i >= j:
                break
            values[i], values[j] = values[j], values[i]
            i += 1
            j -= 1
        values[lo], values[j] = values[j], values[lo]
        if j == rank:
            return values[j]
        if j < rank:
            lo = j + 1
        else:
            hi = j - 1
    return values[rank]


@kernel(
    float64(i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, float32, float32, float32, f8_1d_ro, f8_1d_ro, int32, f8_1d)
)
def slope_sweep_median(
    chain, n, i_fix, i_seg, direction, mag, lo_frac, hi_frac, contrast, ratios, sweeps, to_tip, work
):  # fmt: skip
    """Return one side's tip sweep read from the edge slope: over the chain pixels from `i_fix` stepping
    `direction` to `i_seg` whose arc fraction f (by index) lies in [lo_frac, hi_frac), the local sweep d of the
    gradient height ``mag / contrast`` (float32, as NumPy divides a float32 array by a Python float; then
    `np.interp` on (`ratios`, `sweeps`)), extrapolated to the tip as d / f when `to_tip` is 1 (0: the local sweep
    d itself); the median of those (as `np.median`). `work` holds the values (reordered in place: `_select`). nan
    with fewer than 6 samples or a full `work`. The same as sampling the magnitudes and taking the median with
    NumPy (the tests' reference), without ~150 us of NumPy calls."""
    count = ((i_seg - i_fix) * direction % n + n) % n + 1
    if count < 2:
        return np.nan
    m_table = ratios.shape[0]
    m = 0
    lo = 0
    i = (i_fix - direction + 4 * n) % n
    for k in range(count):
        i += direction  # (i_fix + k direction) mod n, without a modulo per point
        if i == n:
            i = 0
        elif i < 0:
            i = n - 1
        frac = k / (count - 1)
        if frac < lo_frac or frac >= hi_frac:
            continue
        if 2 * m + 1 >= 2 * work.shape[0]:
            return np.nan
        x = float(mag[chain[i, 0], chain[i, 1]] / contrast)
        if m_table == 0:
            return np.nan
        if x >= ratios[m_table - 1]:
            d = sweeps[m_table - 1]
        elif x < ratios[0]:
            d = sweeps[0]
        else:
            while lo > 0 and ratios[lo] > x:
                lo -= 1
            while lo < m_table - 2 and ratios[lo + 1] <= x:
                lo += 1
            if ratios[lo] == x:
                d = sweeps[lo]
            else:
                slope = (sweeps[lo + 1] - sweeps[lo]) / (ratios[lo + 1] - ratios[lo])
                d = slope * (x - ratios[lo]) + sweeps[lo]
        work[m] = d / float(np.float32(frac)) if to_tip == 1 else d
        m += 1
    if m < 6:
        return np.nan
    upper = _select(work, m, m // 2)
    if m % 2 == 1:
        return upper
    lower = work[0]  # the largest of the values below rank m // 2
    for k in range(1, m // 2):
        lower = max(lower, work[k])
    return (lower + upper) / 2.0
