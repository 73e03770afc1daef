"""Smoothing of the rope centrelines across their direction (local quadratic regression along the arc)."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import float32, float64, int32, int64, types

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.shared.jit import f4_2d, f4_2d_ro, f8_1d, kernel

_SUMS: Final = types.UniTuple(float64, 10)
"""The power sums of `_power_sums`: (U0, ..., U4) of the rows, then of the columns."""
_NO_SUMS: Final = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@kernel(_SUMS(f4_2d_ro, int64, int64, int64, float64, float64, float64, _SUMS))
def _power_sums(poly, i, o_first, o_last, sign, org_r, org_c, sums):
    """Return `sums` + `sign` x ``U_e = sum(o**e * (P[i + o] - org))`` for e = 0..4 over o = `o_first`..`o_last`,
    of the rows and of the columns (a window's moments about its middle point, as sums over its points; `sign`
    -1.0 takes points out of the window, bit for bit as subtracting each term)."""
    u0r, u1r, u2r, u3r, u4r, u0c, u1c, u2c, u3c, u4c = sums
    for o in range(o_first, o_last + 1):
        qr = sign * (float(poly[i + o, 0]) - org_r)
        qc = sign * (float(poly[i + o, 1]) - org_c)
        f = float(o)
        f2 = f * f
        u0r += qr
        u0c += qc
        u1r += f * qr
        u1c += f * qc
        u2r += f2 * qr
        u2c += f2 * qc
        u3r += f2 * f * qr
        u3c += f2 * f * qc
        u4r += f2 * f2 * qr
        u4c += f2 * f2 * qc
    return u0r, u1r, u2r, u3r, u4r, u0c, u1c, u2c, u3c, u4c


_SMOOTH_BLOCK: Final = 3
"""Points per fit of `smooth_polyline`."""
_SLIDES: Final = 32
"""Runs after which `smooth_polyline` recomputes the power sums instead of sliding them (bounds the rounding)."""
_EVEN_TOLERANCE: Final = 0.1
"""Largest difference (in mean point spacings) between the arc offset of a window's end points from its middle
and the offset of evenly spaced points for which `smooth_polyline` takes the window as evenly spaced."""


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

    Evenly spaced windows (resampled centrelines): a window centred on its point with K points on each side,
    whose end points lie within `_EVEN_TOLERANCE` mean spacings Δ of the offsets ±KΔ, is fitted at the positions
    oΔ (o = -K..K) instead of the chord projections: the weights and the normal equations are then the same for
    every such window, and its sums are linear in the points: they follow from the power sums
    ``sum(o**e P[i + o])`` (e <= 4, `_power_sums`), which slide from one run to the next by 3 x 2 points
    (recomputed every `_SLIDES` runs and after any other window). On a bend the even positions are the better
    ones: the quadratic in arc offset leaves a third of the chord projection's flattening.

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
    spacing = total / (n - 1)
    tolerance = _EVEN_TOLERANCE * spacing
    even_count = -1
    m0 = m2 = m4 = 0.0
    lo = 0
    hi = 0
    # The power sums are taken about the first point (smaller numbers), in float64: Numba's float() keeps a
    # float32 a float32, and a float32 difference would round (the sums are exact in float64).
    org_r = np.float64(poly[0, 0])
    org_c = np.float64(poly[0, 1])
    slide_i = -1
    slide_count = -1
    slides = 0
    u0r = u1r = u2r = u3r = u4r = 0.0
    u0c = u1c = u2c = u3c = u4c = 0.0
    for first in range(0, n, _SMOOTH_BLOCK):
        last = min(first + _SMOOTH_BLOCK, n) - 1
        i = (first + last) // 2
        centre = 0.5 * total if short else min(max(arc[i], half), total - half)
        while arc[lo] < centre - half and lo < i:
            lo += 1
        hi = max(hi, i)
        while hi + 1 < n and (arc[hi + 1] - centre) * inv_half <= limit:
            hi += 1
        half_count = i - lo
        even = (
            not short
            and centre == arc[i]
            and hi - i == half_count
            and half_count >= 2
            and abs(arc[hi] - arc[i] - half_count * spacing) <= tolerance
            and abs(arc[i] - arc[lo] - half_count * spacing) <= tolerance
        )
        if even:
            if half_count != even_count:
                # The even window's moments: the same for every window of this size.
                even_count = half_count
                m0 = 1.0
                m2 = 0.0
                m4 = 0.0
                for o in range(1, half_count + 1):
                    x = o * spacing * inv_half
                    w = 1.0 - 0.9 * x * x
                    m0 += 2.0 * w
                    m2 += 2.0 * w * x * x
                    m4 += 2.0 * w * x * x * x * x
            if i - slide_i == 3 and half_count == slide_count and slides < _SLIDES:
                # Drop the 3 points before the new window, add the 3 after the old one (offsets from the old
                # middle), then move the offsets by 3: (o - 3)**e expanded. A third of the work of new sums.
                slides += 1
                sums = (u0r, u1r, u2r, u3r, u4r, u0c, u1c, u2c, u3c, u4c)
                sums = _power_sums(poly, slide_i, -half_count, -half_count + 2, -1.0, org_r, org_c, sums)
                u0r, u1r, u2r, u3r, u4r, u0c, u1c, u2c, u3c, u4c = _power_sums(
                    poly, slide_i, half_count + 1, half_count + 3, 1.0, org_r, org_c, sums
                )
                u4r = u4r - 12.0 * u3r + 54.0 * u2r - 108.0 * u1r + 81.0 * u0r
                u4c = u4c - 12.0 * u3c + 54.0 * u2c - 108.0 * u1c + 81.0 * u0c
                u3r = u3r - 9.0 * u2r + 27.0 * u1r - 27.0 * u0r
                u3c = u3c - 9.0 * u2c + 27.0 * u1c - 27.0 * u0c
                u2r = u2r - 6.0 * u1r + 9.0 * u0r
                u2c = u2c - 6.0 * u1c + 9.0 * u0c
                u1r = u1r - 3.0 * u0r
                u1c = u1c - 3.0 * u0c
            else:
                slides = 0
                slide_count = half_count
                u0r, u1r, u2r, u3r, u4r, u0c, u1c, u2c, u3c, u4c = _power_sums(
                    poly, i, -half_count, half_count, 1.0, org_r, org_c, _NO_SUMS
                )
            slide_i = i
            # The fit at the even positions x = o step, w = 1 - a o**2: the offsets across the chord are linear in
            # the points, so sum(w x**k y) = normal . (sum(w x**k P) - M_k P_i) (M_1 = 0), from the power sums.
            chord_r = float(poly[hi, 0]) - float(poly[lo, 0])
            chord_c = float(poly[hi, 1]) - float(poly[lo, 1])
            chord = math.sqrt(chord_r * chord_r + chord_c * chord_c)
            ok = along_r = along_c = c0 = c1 = c2 = 0.0
            if chord > 0.5 * (arc[hi] - arc[lo]):  # else a hairpin: the run is left as it is
                step = spacing * inv_half
                a = 0.9 * step * step
                pr = float(poly[i, 0]) - org_r
                pc = float(poly[i, 1]) - org_c
                along_r = chord_r / chord
                along_c = chord_c / chord
                r0 = (u0c - a * u2c - m0 * pc) * along_r - (u0r - a * u2r - m0 * pr) * along_c
                r1 = step * ((u1c - a * u3c) * along_r - (u1r - a * u3r) * along_c)
                r2 = (step * step * (u2c - a * u4c) - m2 * pc) * along_r - (
                    step * step * (u2r - a * u4r) - m2 * pr
                ) * along_c
                det = m0 * m4 - m2 * m2
                ok = 1.0
                c0 = (r0 * m4 - r2 * m2) / det
                c1 = r1 / m2
                c2 = (m0 * r2 - m2 * r0) / det
        else:
            ok, along_r, along_c, c0, c1, c2 = _fit_across(poly, arc, lo, hi, i, centre, inv_half)
        run_ok, run_r, run_c, run_c0, run_c1, run_c2 = ok, along_r, along_c, c0, c1, c2
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
                ok, along_r, along_c, c0, c1, c2 = run_ok, run_r, run_c, run_c0, run_c1, run_c2
    return n
