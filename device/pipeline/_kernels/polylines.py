"""Polylines and material points: length, resampling, tracking by arc length, trimming and extending the free end."""

from __future__ import annotations

import math
from typing import Final

from numba import float32, float64, int32, int64, types

from ropecam.device.pipeline._kernels._common import FULL, INVALID
from ropecam.shared.jit import (
    f4_2d,
    f4_2d_ro,
    f8_1d,
    f8_1d_ro,
    kernel,
)


@kernel(float64(f4_2d_ro, int32))
def polyline_length(poly, n):
    """Return the length of the polyline of the first `n` points, eq. (9)."""
    total = 0.0
    for i in range(1, n):
        total += math.hypot(float(poly[i, 0]) - float(poly[i - 1, 0]), float(poly[i, 1]) - float(poly[i - 1, 1]))
    return total


@kernel(int32(f4_2d_ro, int32, float32, f4_2d))
def resample_polyline(poly, n, step_px, out_poly):
    """Resample the polyline at equal arc-length steps of at most `step_px`, keeping both ends; returns the count
    or FULL."""
    if n < 1:
        return 0
    total = polyline_length(poly, n)
    segments = max(1, math.ceil(total / step_px)) if total > 0.0 else 0
    if segments + 1 > out_poly.shape[0]:
        return FULL
    out_poly[0, 0] = poly[0, 0]
    out_poly[0, 1] = poly[0, 1]
    if segments == 0:
        return 1
    step = total / segments
    j = 0
    acc = 0.0
    seg_len = math.hypot(poly[1, 0] - poly[0, 0], poly[1, 1] - poly[0, 1]) if n > 1 else 0.0
    for k in range(1, segments):
        target = k * step
        while acc + seg_len < target and j + 2 < n:
            acc += seg_len
            j += 1
            seg_len = math.hypot(poly[j + 1, 0] - poly[j, 0], poly[j + 1, 1] - poly[j, 1])
        t = (target - acc) / seg_len if seg_len > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        out_poly[k, 0] = poly[j, 0] + t * (poly[j + 1, 0] - poly[j, 0])
        out_poly[k, 1] = poly[j, 1] + t * (poly[j + 1, 1] - poly[j, 1])
    out_poly[segments, 0] = poly[n - 1, 0]
    out_poly[segments, 1] = poly[n - 1, 1]
    return segments + 1


@kernel(int32(f4_2d_ro, int32, f8_1d_ro, float64, f4_2d))
def track_material_points(poly, n, arc_px, length0_px, out_points):
    """Locate material points on the polyline (fixed end first) by arc length with uniform stretch, eqs. (9)-(12).

    ``arc_px[k]`` is the unstretched distance of point k from the fixed end; with the polyline's length Lc and
    the unstretched length `length0_px` (Lc0) it sits at ``l' = arc_px[k] * Lc / Lc0``, interpolated between the
    polyline points bracketing it; beyond the ends it is clamped to them. Writes `out_points` (row, col); returns
    the number of points or INVALID (empty polyline, Lc0 <= 0).
    """
    m = arc_px.shape[0]
    if n < 1 or not length0_px > 0.0 or out_points.shape[0] < m:
        return INVALID
    total = polyline_length(poly, n)
    ratio = total / length0_px
    for k in range(m):
        target = arc_px[k] * ratio
        if n == 1 or target <= 0.0:
            out_points[k, 0] = poly[0, 0]
            out_points[k, 1] = poly[0, 1]
            continue
        acc = 0.0
        done = False
        for j in range(n - 1):
            seg = math.hypot(float(poly[j + 1, 0]) - float(poly[j, 0]), float(poly[j + 1, 1]) - float(poly[j, 1]))
            if acc + seg > target and seg > 0.0:
                t = (target - acc) / seg
                out_points[k, 0] = poly[j, 0] + t * (poly[j + 1, 0] - poly[j, 0])
                out_points[k, 1] = poly[j, 1] + t * (poly[j + 1, 1] - poly[j, 1])
                done = True
                break
            acc += seg
        if not done:
            out_points[k, 0] = poly[n - 1, 0]
            out_points[k, 1] = poly[n - 1, 1]
    return m


@kernel(int32(f4_2d, int32, float32))
def trim_polyline_end(poly, n, cut_px):
    """Shorten the polyline of `n` points in place by `cut_px` of arc length at its end (the new last point is
    interpolated); returns the new count, or 0 when the polyline is not longer than `cut_px`."""
    remaining = cut_px
    k = n - 1
    while k > 0:
        seg = math.hypot(poly[k, 0] - poly[k - 1, 0], poly[k, 1] - poly[k - 1, 1])
        if seg >= remaining and seg > 0.0:
            t = remaining / seg
            poly[k, 0] = poly[k, 0] + t * (poly[k - 1, 0] - poly[k, 0])
            poly[k, 1] = poly[k, 1] + t * (poly[k - 1, 1] - poly[k, 1])
            return k + 1
        remaining -= seg
        k -= 1
    return 0


@kernel(int32(f4_2d, int32, f4_2d_ro, int32, float32, float32))
def extend_to_band_end(poly, n, points, n_points, width_px, cap_px):
    """Move the free end of the axis polyline `poly` (n points) to where the band ends along that axis.

    The axis direction is taken over the last 3 widths of arc; the band's end along it is the farthest of the
    contour `points` lying within half a width of the axis line (and within -2 to +4 widths of the current end);
    the tip goes `cap_px` short of it (half a width for a round rope end). The polyline is extended along the
    axis or shortened (`trim_polyline_end`) in place. Returns the new point count (unchanged when nothing is
    found).
    """
    if n < 3:
        return n
    back = 0.0
    k = n - 1
    while k > 0 and back < 3.0 * width_px:
        back += math.hypot(poly[k, 0] - poly[k - 1, 0], poly[k, 1] - poly[k - 1, 1])
        k -= 1
    base_r = poly[n - 1, 0]
    base_c = poly[n - 1, 1]
    dir_r = base_r - poly[k, 0]
    dir_c = base_c - poly[k, 1]
    norm = math.sqrt(dir_r * dir_r + dir_c * dir_c)
    if norm < 1e-6:
        return n
    dir_r /= norm
    dir_c /= norm
    best = -1e30
    for i in range(n_points):
        rel_r = points[i, 0] - base_r
        rel_c = points[i, 1] - base_c
        along = rel_r * dir_r + rel_c * dir_c
        across = abs(rel_r * dir_c - rel_c * dir_r)
        if across < 0.5 * width_px and -2.0 * width_px < along < 4.0 * width_px and along > best:
            best = along
    if best < -1e29:
        return n
    extent = best - cap_px
    if extent >= 0.0:
        poly[n - 1, 0] = base_r + extent * dir_r
        poly[n - 1, 1] = base_c + extent * dir_c
        return n
    count = trim_polyline_end(poly, n, -extent)
    return count if count >= 2 else n


_SMOOTH_BLOCK: Final = 3
"""Points per fit of `smooth_polyline`."""


@kernel(types.UniTuple(float64, 6)(f4_2d_ro, f8_1d, int64, int64, int64, float64, float64))
def _fit_across(poly, arc, lo, hi, i, centre, inv_half):
    """Fit the offset across the chord of points lo..hi as a weighted quadratic of the position along it, both
    relative to point i and scaled by `inv_half`; weights 1 - 0.9 d**2 with d the arc distance to `centre` (scaled).

    Returns (ok, along_r, along_c, c0, c1, c2): ok = 1.0 when fitted (a line when the quadratic is degenerate),
    0.0 when the window has fewer than 3 points or is a hairpin (chord shorter than half its arc).
    """
    chord_r = float(poly[hi, 0]) - float(poly[lo, 0])
    chord_c = float(poly[hi, 1]) - float(poly[lo, 1])
    chord = math.sqrt(chord_r * chord_r + chord_c * chord_c)
    if hi - lo < 2 or not chord > 0.5 * (arc[hi] - arc[lo]):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    along_r = chord_r / chord
    along_c = chord_c / chord
    base_r = float(poly[i, 0])
    base_c = float(poly[i, 1])
    m0 = m1 = m2 = m3 = m4 = 0.0
    r0 = r1 = r2 = 0.0
    for j in range(lo, hi + 1):
        d = min(abs(arc[j] - centre) * inv_half, 1.0)
        w = 1.0 - 0.9 * d * d
        dr = float(poly[j, 0]) - base_r
        dc = float(poly[j, 1]) - base_c
        x = (dr * along_r + dc * along_c) * inv_half
        y = dc * along_r - dr * along_c
        wx = w * x
        wx2 = wx * x
        m0 += w
        m1 += wx
        m2 += wx2
        m3 += wx2 * x
        m4 += wx2 * x * x
        r0 += w * y
        r1 += wx * y
        r2 += wx2 * y
    # y = c0 + c1 x + c2 x^2 by Cramer's rule on the normal equations; a line when they are degenerate.
    a = m2 * m4 - m3 * m3
    b = m1 * m4 - m2 * m3
    c = m1 * m3 - m2 * m2
    det = m0 * a - m1 * b + m2 * c
    if det > 1e-9 * m0 * m0 * m0:
        c0 = (r0 * a - r1 * b + r2 * c) / det
        c1 = (m0 * (r1 * m4 - m3 * r2) - r0 * b + m2 * (m1 * r2 - r1 * m2)) / det
        c2 = (m0 * (m2 * r2 - r1 * m3) - m1 * (m1 * r2 - r1 * m2) + r0 * c) / det
        return 1.0, along_r, along_c, c0, c1, c2
    det = m0 * m2 - m1 * m1
    if not det > 1e-9 * m0 * m0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return 1.0, along_r, along_c, (r0 * m2 - r1 * m1) / det, (m0 * r1 - m1 * r0) / det, 0.0


@kernel(int32(f4_2d_ro, int32, float32, f8_1d, f4_2d))
def smooth_polyline(poly, n, half_width_px, work_arc_px, out_poly):
    """Smooth the polyline of `n` points across its direction by local quadratic regression (LOESS), into `out_poly`.

    A rope centreline has no pixel-scale wiggles: those are measurement noise. The points are taken in runs of
    `_SMOOTH_BLOCK`; for the middle point of a run, the window is the points within h = `half_width_px` of arc
    length from a centre: the point's own arc length, clamped to ``[h, L - h]`` (L the polyline's length), so near
    an end the window stays 2h long and one-sided and the end is not averaged inward. In the frame of the window's
    chord (first to last point), the offset across the chord is fitted by weighted least squares as a quadratic of
    the position along it (weights fall from 1 at the centre to 0.1 at the window's edge), and every point of the
    run is moved across the chord onto the fit, at its own position along it (LOESS evaluated at every third
    point: a third of the work); a point of the run outside that window (a gap longer than the window) gets a fit
    of its own. Points only move sideways: the tip keeps its measured extent along the rope, a
    quadratic is reproduced exactly, an arc of radius R is flattened by ~h**4 / R**3 at most. A window with fewer
    than three distinct positions falls back to a line (two) or leaves the run (one), and a window whose chord is
    shorter than half its arc length (a hairpin tighter than the window) leaves its run as it is.
    `half_width_px` <= 0 or n < 3 copies the points; a polyline shorter than 2h is one window.

    Writes the arc length of every point into ``work_arc_px[:n]`` and the result into ``out_poly[:n]`` (row, col);
    returns n, or INVALID when n < 0 or a buffer holds fewer than n rows.
    """
    if n < 0 or out_poly.shape[0] < n or poly.shape[0] < n or work_arc_px.shape[0] < n:
        return INVALID
    total = 0.0
    for i in range(n):
        out_poly[i, 0] = poly[i, 0]
        out_poly[i, 1] = poly[i, 1]
        if i > 0:
            dr = float(poly[i, 0]) - float(poly[i - 1, 0])
            dc = float(poly[i, 1]) - float(poly[i - 1, 1])
            total += math.sqrt(dr * dr + dc * dc)
        work_arc_px[i] = total
    if n < 3 or not half_width_px > 0.0 or not total > 0.0:
        return n
    arc = work_arc_px
    half = float(half_width_px)
    short = total <= 2.0 * half
    if short:
        half = 0.5 * total * (1.0 + 1e-6)  # one window over the whole polyline, its ends inside it
    inv_half = 1.0 / half
    limit = 1.0 + 1e-9  # the end points sit at the window's edge up to rounding: keep them
    lo = 0
    hi = 0
    for first in range(0, n, _SMOOTH_BLOCK):
        last = min(first + _SMOOTH_BLOCK, n) - 1
        i = (first + last) // 2
        centre = 0.5 * total if short else min(max(arc[i], half), total - half)
        while arc[lo] < centre - half and lo < i:
            lo += 1
        hi = max(hi, i)
        while hi + 1 < n and (arc[hi + 1] - centre) * inv_half <= limit:
            hi += 1
        ok, along_r, along_c, c0, c1, c2 = _fit_across(poly, arc, lo, hi, i, centre, inv_half)
        for k in range(first, last + 1):
            fit_i = i
            if k < lo or k > hi:
                # A gap longer than the window lies between k and the run's middle: k gets its own window and fit.
                fit_i = k
                own = 0.5 * total if short else min(max(arc[k], half), total - half)
                k_lo = k
                while k_lo > 0 and arc[k_lo - 1] >= own - half:
                    k_lo -= 1
                k_hi = k
                while k_hi + 1 < n and (arc[k_hi + 1] - own) * inv_half <= limit:
                    k_hi += 1
                ok, along_r, along_c, c0, c1, c2 = _fit_across(poly, arc, k_lo, k_hi, k, own, inv_half)
            if ok > 0.0:
                dr = float(poly[k, 0]) - float(poly[fit_i, 0])
                dc = float(poly[k, 1]) - float(poly[fit_i, 1])
                x = (dr * along_r + dc * along_c) * inv_half
                # Move the point along the normal (-along_c, along_r) from its own offset onto the fit.
                offset = c0 + (c1 + c2 * x) * x - (dc * along_r - dr * along_c)
                out_poly[k, 0] = float(poly[k, 0]) - offset * along_c
                out_poly[k, 1] = float(poly[k, 1]) + offset * along_r
            if fit_i != i:
                ok, along_r, along_c, c0, c1, c2 = _fit_across(poly, arc, lo, hi, i, centre, inv_half)
    return n
