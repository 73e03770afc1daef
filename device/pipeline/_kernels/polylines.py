"""Polylines: length, resampling, trimming and extending the free end, anchoring the fixed end, smoothing."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import float32, float64, int32, types

from ropecam.device.pipeline._kernels._common import FULL, vector_length
from ropecam.device.pipeline._kernels.geometry import sample_bilinear
from ropecam.shared.jit import (
    f4_2d,
    f4_2d_ro,
    f8_1d_ro,
    kernel,
)


@kernel(float64(f4_2d_ro, int32))
def polyline_length(poly, n):
    """Return the length of the polyline of the first `n` points, eq. (9)."""
    total = 0.0
    for i in range(1, n):
        total += vector_length(float(poly[i, 0]) - float(poly[i - 1, 0]), float(poly[i, 1]) - float(poly[i - 1, 1]))
    return total


@kernel(int32(f4_2d_ro, int32, float64, float32, f4_2d))
def resample_polyline_of_length(poly, n, total, step_px, out_poly):
    """`resample_polyline` for a polyline whose length `total` (`polyline_length`) the caller has already."""
    if n < 1:
        return 0
    segments = max(1, math.ceil(total / step_px)) if total > 0.0 else 0
    if segments + 1 > out_poly.shape[0]:
        return FULL
    out_poly[0, 0] = poly[0, 0]
    out_poly[0, 1] = poly[0, 1]
    if segments == 0:
        return 1
    step = total / segments
    # A walk to an arc length like `_points_at`'s (material points, `_kernels/tracking.py`), kept apart on purpose:
    # here the segment lengths are float64, the target on a vertex stays on the segment before it (t = 1) and a
    # zero-length segment gives its start; there the lengths are rounded to float32 (`_segment_lengths`) and the
    # first segment of positive length passing the target is taken. One walk would move either's points by
    # float32 roundings (outputs not bit-identical).
    j = 0
    acc = 0.0
    seg_len = vector_length(poly[1, 0] - poly[0, 0], poly[1, 1] - poly[0, 1]) if n > 1 else 0.0
    for k in range(1, segments):
        target = k * step
        while acc + seg_len < target and j + 2 < n:
            acc += seg_len
            j += 1
            seg_len = vector_length(poly[j + 1, 0] - poly[j, 0], poly[j + 1, 1] - poly[j, 1])
        t = (target - acc) / seg_len if seg_len > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        out_poly[k, 0] = poly[j, 0] + t * (poly[j + 1, 0] - poly[j, 0])
        out_poly[k, 1] = poly[j, 1] + t * (poly[j + 1, 1] - poly[j, 1])
    out_poly[segments, 0] = poly[n - 1, 0]
    out_poly[segments, 1] = poly[n - 1, 1]
    return segments + 1


@kernel(int32(f4_2d_ro, int32, float32, f4_2d))
def resample_polyline(poly, n, step_px, out_poly):
    """Resample the polyline at equal arc-length steps of at most `step_px`, keeping both ends; returns the count
    or FULL."""
    if n < 1:
        return 0
    return resample_polyline_of_length(poly, n, polyline_length(poly, n), step_px, out_poly)


@kernel(int32(f4_2d, int32, float32, float32, float32, float32, int32))
def anchor_start(poly, n, point_r, point_c, skip_px, span_px, through):
    """Start the polyline `poly` (n points) at the foot of (`point_r`, `point_c`) on its own axis, in place; with
    `through` 1 at the point itself (a fixed end that is given, not found: the rope is held there, and where a
    clamp hides its first pixels the straight line from the point to the axis point A below is the rope there;
    the foot missed the given point by the fitted axis' angle error times the hidden length).

    The axis is the line through the polyline's points at arc lengths `skip_px` and `skip_px + span_px` from its
    start (interpolated); the points before `skip_px` are dropped and the foot of the point on that line becomes
    the first point. Used at the fixed end: the inward offset moves the contour's end-cap points along the rope,
    so the side's first points lie inside the rope, while the rope's end is the cap's edge (the point).
    Returns the new count; `n` unchanged when the polyline is shorter than ``skip_px + span_px``, the foot would
    not lie before the kept points, or `poly` has no room for the new count."""
    if n < 3 or not span_px > 0.0 or not skip_px >= 0.0:
        return n
    s = 0.0
    k = 1
    a_r = poly[0, 0]
    a_c = poly[0, 1]
    found_a = skip_px == 0.0
    k_a = 0
    b_r = 0.0
    b_c = 0.0
    while k < n:
        seg = vector_length(poly[k, 0] - poly[k - 1, 0], poly[k, 1] - poly[k - 1, 1])
        if seg > 0.0:
            if not found_a and s + seg >= skip_px:
                f = (skip_px - s) / seg
                a_r = poly[k - 1, 0] + f * (poly[k, 0] - poly[k - 1, 0])
                a_c = poly[k - 1, 1] + f * (poly[k, 1] - poly[k - 1, 1])
                found_a = True
                k_a = k
            if found_a and s + seg >= skip_px + span_px:
                f = (skip_px + span_px - s) / seg
                b_r = poly[k - 1, 0] + f * (poly[k, 0] - poly[k - 1, 0])
                b_c = poly[k - 1, 1] + f * (poly[k, 1] - poly[k - 1, 1])
                break
        s += seg
        k += 1
    if k >= n:
        return n
    if skip_px == 0.0:
        k_a = 1
    d_r = b_r - a_r
    d_c = b_c - a_c
    norm = math.sqrt(d_r * d_r + d_c * d_c)
    if norm <= 0.0:
        return n
    d_r /= norm
    d_c /= norm
    t = (point_r - a_r) * d_r + (point_c - a_c) * d_c
    if t >= 0.0:
        return n
    foot_r = a_r + t * d_r
    foot_c = a_c + t * d_c
    if through == 1:
        foot_r = np.float64(point_r)
        foot_c = np.float64(point_c)
    # Keep the points from the first one at or beyond the axis point A (k_a); A itself joins them when it
    # differs from that point, so the shape between the foot and the kept points is the axis line.
    out = 1
    first_r = poly[k_a, 0]
    first_c = poly[k_a, 1]
    if vector_length(first_r - a_r, first_c - a_c) > 1e-6:
        out = 2
    count = out + (n - k_a)
    if count > poly.shape[0]:
        return n  # no room for the new start: leave the polyline as it is
    # Shift the kept points in place, in the order that never overwrites a point still to be read.
    shift = k_a - out
    if shift >= 0:
        for j in range(k_a, n):
            poly[j - shift, 0] = poly[j, 0]
            poly[j - shift, 1] = poly[j, 1]
    else:
        for j in range(n - 1, k_a - 1, -1):
            poly[j - shift, 0] = poly[j, 0]
            poly[j - shift, 1] = poly[j, 1]
    poly[0, 0] = foot_r
    poly[0, 1] = foot_c
    if out == 2:
        poly[1, 0] = a_r
        poly[1, 1] = a_c
    return count


@kernel(int32(f4_2d, int32, float32))
def trim_polyline_end(poly, n, cut_px):
    """Shorten the polyline of `n` points in place by `cut_px` of arc length at its end (the new last point is
    interpolated); returns the new count, or 0 when the polyline is not longer than `cut_px`."""
    remaining = cut_px
    k = n - 1
    while k > 0:
        seg = vector_length(poly[k, 0] - poly[k - 1, 0], poly[k, 1] - poly[k - 1, 1])
        if seg >= remaining and seg > 0.0:
            t = remaining / seg
            poly[k, 0] = poly[k, 0] + t * (poly[k - 1, 0] - poly[k, 0])
            poly[k, 1] = poly[k, 1] + t * (poly[k - 1, 1] - poly[k, 1])
            return k + 1
        remaining -= seg
        k -= 1
    return 0


@kernel(float32(f4_2d_ro, float32, float32, float32, float32, float32, float32, float32))
def half_level_crossing(image, base_r, base_c, dir_r, dir_c, guess, reach_px, flank_px):
    """Return where the intensity along a line drops halfway from its inside to its outside level.

    The line runs from (`base_r`, `base_c`) along the unit vector (`dir_r`, `dir_c`); `image` is sampled bilinearly
    every 0.25 px, averaged over three parallel lines 0.5 px apart. The inside level is the mean over
    [guess - reach - flank, guess - reach], the outside level over [guess + reach, guess + reach + flank]; the
    result is the crossing of their mean nearest to `guess` within +-`reach_px` (linear interpolation), as a
    distance along the line. Returns nan when the two levels differ by less than 2 grey levels or no crossing is
    found."""
    inside = 0.0
    outside = 0.0
    count = 0
    t = -reach_px - flank_px
    while t <= -reach_px:
        for lateral in (-0.5, 0.0, 0.5):
            r = base_r + (guess + t) * dir_r + lateral * dir_c
            c = base_c + (guess + t) * dir_c - lateral * dir_r
            inside += sample_bilinear(image, r, c)
            r = base_r + (guess - t) * dir_r + lateral * dir_c
            c = base_c + (guess - t) * dir_c - lateral * dir_r
            outside += sample_bilinear(image, r, c)
        count += 3
        t += 0.25
    inside /= count
    outside /= count
    if abs(inside - outside) < 2.0:
        return np.float32(np.nan)
    half = 0.5 * (inside + outside)
    sign = 1.0 if inside > outside else -1.0
    best = np.float32(np.nan)
    best_gap = 1e30
    prev = 0.0
    t = -reach_px
    k = 0
    while t <= reach_px:
        value = 0.0
        for lateral in (-0.5, 0.0, 0.5):
            r = base_r + (guess + t) * dir_r + lateral * dir_c
            c = base_c + (guess + t) * dir_c - lateral * dir_r
            value += sample_bilinear(image, r, c)
        value = sign * (value / 3.0 - half)
        if k > 0 and prev > 0.0 >= value:
            cross = t - 0.25 + 0.25 * prev / (prev - value)
            if abs(cross) < best_gap:
                best_gap = abs(cross)
                best = np.float32(guess + cross)
        prev = value
        t += 0.25
        k += 1
    return best


RAMP_DEPTH_PX: Final = 6.0
"""How far behind the half-level crossing (px along the axis) `ramp_end_crossing` reads the band's own level: a tip
that slides along the rope during the exposure ends the band in a ramp as long as that slide (4-11 px on the
simulated late swing's whipping frames, tuning seed), longer than `half_level_crossing`'s reach (3 blur + 1)."""
RAMP_RISE: Final = 0.15
"""The band's level that far behind must exceed the level just behind the crossing by this fraction of the band's
contrast for the end to count as a ramp (a braided rope's brightness varies by about 5 % along it)."""


@kernel(float32(f4_2d_ro, float32, float32, float32, float32, float32, float32, float32))
def _line_level(image, base_r, base_c, dir_r, dir_c, t_from, t_to, lateral_px):
    """The mean of `image` (bilinear) along the line from (`base_r`, `base_c`) along (`dir_r`, `dir_c`) between
    `t_from` and `t_to`, every 0.25 px, over three parallel lines `lateral_px` apart."""
    total = 0.0
    count = 0
    t = t_from
    while t <= t_to:
        for lateral in (-lateral_px, np.float32(0.0), lateral_px):
            total += sample_bilinear(image, base_r + t * dir_r + lateral * dir_c, base_c + t * dir_c - lateral * dir_r)
            count += 1
        t += np.float32(0.25)
    return np.float32(total / count) if count > 0 else np.float32(np.nan)


@kernel(float32(f4_2d_ro, float32, float32, float32, float32, float32, float32, float32))
def ramp_end_crossing(image, base_r, base_c, dir_r, dir_c, end, reach_px, flank_px):
    """Return where the intensity along a line drops halfway from the band's level `RAMP_DEPTH_PX` behind `end`
    (a distance along the line from (`base_r`, `base_c`) along the unit (`dir_r`, `dir_c`): the half-level
    crossing `half_level_crossing` found with `reach_px`, `flank_px`) to the outside level beyond it, when the
    band's end is a ramp longer than that reach: nan otherwise.

    Levels are read as `half_level_crossing` reads them (three lines 0.5 px apart, over `flank_px`): near over
    [end - reach - flank, end - reach], deep over [end - depth - flank, end - depth], outside over
    [end + reach, end + reach + flank]. A ramp is a deep level beyond the near one (towards the band's side) by
    `RAMP_RISE` of the deep level's contrast with the outside; the crossing of their mean nearest to `end`, within
    [end - depth, end + reach], is returned (linear interpolation). A ramp longer than about the depth puts the
    deep level on it too, and the crossing then lies between the ramp's middle and `end` (a 10 px ramp under a
    0.7 px blur: 0.4 px past its middle, against 2.6 px)."""
    depth = np.float32(RAMP_DEPTH_PX)
    if not reach_px < depth:
        return np.float32(np.nan)
    half_px = np.float32(0.5)
    near = _line_level(image, base_r, base_c, dir_r, dir_c, end - reach_px - flank_px, end - reach_px, half_px)
    deep = _line_level(image, base_r, base_c, dir_r, dir_c, end - depth - flank_px, end - depth, half_px)
    outside = _line_level(image, base_r, base_c, dir_r, dir_c, end + reach_px, end + reach_px + flank_px, half_px)
    contrast = abs(deep - outside)
    sign = 1.0 if deep > outside else -1.0
    if not (contrast >= 2.0 and sign * (deep - near) > RAMP_RISE * contrast):
        return np.float32(np.nan)
    half = 0.5 * (deep + outside)
    # The crossing search is `half_level_crossing`'s, written out on purpose: that one (the steady tip fit's)
    # samples at float64 positions and averages in float64, this one reads through `_line_level` in float32. One
    # loop for both changes one of them: `half_level_crossing` with its levels and samples read by `_line_level`
    # gave other values on 259 of 400 random blurred ends (up to 0.009 px; script, session 18).
    best = np.float32(np.nan)
    best_gap = 1e30
    prev = 0.0
    t = -depth
    k = 0
    while t <= reach_px:
        value = sign * (_line_level(image, base_r, base_c, dir_r, dir_c, end + t, end + t, half_px) - half)
        if k > 0 and prev > 0.0 >= value:
            cross = t - 0.25 + 0.25 * prev / (prev - value)
            if abs(cross) < best_gap:
                best_gap = abs(cross)
                best = np.float32(end + cross)
        prev = value
        t += np.float32(0.25)
        k += 1
    return best


_AXIS: Final = types.UniTuple(float64, 5)
"""`_band_axis`'s return: (ok, base_r, base_c, dir_r, dir_c)."""


@kernel(_AXIS(f4_2d_ro, int32, float32, float32))
def _band_axis(poly, n, skip_px, span_px):
    """The axis `extend_to_band_end` carries on: the least-squares line through the points of `poly` (n points)
    between `skip_px` and ``skip_px + span_px`` of arc from its end, pointed towards the end, and its base (the
    foot of the point `skip_px` from the end). Returns (1.0, base_r, base_c, dir_r, dir_c), or ok 0.0 when fewer
    than 3 points lie in that window."""
    # Arc position of each point from the end, walked backwards; accumulate the fit window's moments.
    back = 0.0
    k = n - 1
    m = 0
    sr = 0.0
    sc = 0.0
    srr = 0.0
    scc = 0.0
    src = 0.0
    base_k = -1
    while k > 0:
        if back >= skip_px and base_k < 0:
            base_k = k
        if back >= skip_px:
            if back > skip_px + span_px:
                break
            r = float(poly[k, 0])
            c = float(poly[k, 1])
            m += 1
            sr += r
            sc += c
            srr += r * r
            scc += c * c
            src += r * c
        back += vector_length(poly[k, 0] - poly[k - 1, 0], poly[k, 1] - poly[k - 1, 1])
        k -= 1
    if m < 3 or base_k < 1:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    mr = sr / m
    mc = sc / m
    var_r = srr / m - mr * mr
    var_c = scc / m - mc * mc
    cov = src / m - mr * mc
    # Principal direction of the 2x2 covariance, pointed towards the free end.
    angle = 0.5 * math.atan2(2.0 * cov, var_c - var_r)
    dir_r = math.sin(angle)
    dir_c = math.cos(angle)
    chord_r = poly[n - 1, 0] - poly[k, 0]
    chord_c = poly[n - 1, 1] - poly[k, 1]
    if dir_r * chord_r + dir_c * chord_c < 0.0:
        dir_r = -dir_r
        dir_c = -dir_c
    t = (poly[base_k, 0] - mr) * dir_r + (poly[base_k, 1] - mc) * dir_c
    return 1.0, mr + t * dir_r, mc + t * dir_c, dir_r, dir_c


WIDE_SWEEP_WIDTHS: Final = 3.0
"""Edge spacings across the axis between the band's two far corners (the segmentation points, on the corners the
smoothing rounds: about the sweep at the tip less 0.6 of a width) beyond which the tip fit does not take the
half-level crossing nearer the fixed end than the contour's end less the smoothing's sigma (`_band_tip`)."""


@kernel(
    int32(f4_2d, int32, f4_2d_ro, float64, float64, float64, float64, float64, float32, float32, float32, float32,
          float32, float32)
)  # fmt: skip
def _band_tip(poly, n, smooth, base_r, base_c, dir_r, dir_c, best, width_px, cap_px, skip_px, blur_px, gap_r, gap_c):
    """`extend_to_band_end` once the axis (`_band_axis`) and the contour's farthest point along it (`best`) are
    known: the flat end's refinement on `smooth`, the cut and the new tip. Returns the new count or `n`."""
    if cap_px == 0.0:
        # A flat end moving sideways covers (lateral ramp) x (step at the end) near its corner; the smoothed image
        # is that product blurred, so along the axis it falls halfway to the background exactly at the end (the
        # contour's corner itself is rounded inward by the smoothing). An end that also moves along the rope
        # shifts this crossing; the split corrects that from both tips (`tip_geometry.correct_slant`).
        reach = np.float32(3.0 * blur_px + 1.0)
        end = half_level_crossing(smooth, np.float32(base_r), np.float32(base_c), np.float32(dir_r),
                                  np.float32(dir_c), np.float32(best), reach, np.float32(2.0))  # fmt: skip
        if not math.isnan(end):
            # A tip sliding along the rope ends the band in a ramp longer than the reach: the level just behind
            # the crossing is still on it, and the crossing lies towards the ramp's outer end (simulated late
            # swing, tuning seed, frames 50-53: 0.7-1.7 px). The band's level farther behind gives the ramp's middle,
            # the tip at mid-exposure.
            ramp = ramp_end_crossing(smooth, np.float32(base_r), np.float32(base_c), np.float32(dir_r),
                                     np.float32(dir_c), end, reach, np.float32(2.0))  # fmt: skip
            if not math.isnan(ramp):
                end = ramp
            # Near the corner of a sweep of many widths the rope covers the axis for a small part of the exposure
            # (a fourth at 4 widths), and a textured or noisy plate moves the crossing there, mostly nearer the fixed
            # end (simulated `texture = 0.2`, tuning seed, frame 32: 3.2 px short, the contour's end 0.6 px;
            # `read noise = 10 DN` frame 36: 2.8 and 0.8 px). The smoothing rounds the corner inward by about its
            # sigma, so the crossing is not taken nearer than that to the contour's end there. A narrow sweep keeps
            # the crossing: a whipping tip's band ends in a ramp its contour runs beyond (lab-rolling's sweeps of
            # at most 1.7 widths, where the bound put tips up to 0.8 px farther off).
            if abs(gap_r * dir_c - gap_c * dir_r) > WIDE_SWEEP_WIDTHS * width_px:
                end = max(end, np.float32(best - blur_px))
            best = end
    extent = max(best - cap_px, 0.0)
    count = trim_polyline_end(poly, n, np.float32(skip_px))
    if count < 2:
        return n
    poly[count, 0] = base_r + extent * dir_r
    poly[count, 1] = base_c + extent * dir_c
    return count + 1


@kernel(
    int32(f4_2d, int32, f4_2d_ro, int32, f4_2d_ro, float32, float32, float32, float32, float32, float32, float32)
)  # fmt: skip
def extend_to_band_end(poly, n, points, n_points, smooth, width_px, cap_px, skip_px, span_px, blur_px, gap_r, gap_c):
    """Replace the free end of the axis polyline `poly` (n points) by the axis carried on to where the band ends.

    The last `skip_px` of arc are the band's rounded corner (smoothing and the end's blur pull the edge inward
    there), so the axis is the least-squares line through the polyline points between `skip_px` and
    ``skip_px + span_px`` of arc from the end; its base is the foot of the point `skip_px` from the end.
    The band's end along that line is the farthest of the contour `points` lying within half a width of it (and
    within -2 to `skip_px` + 4 widths of the base); for a flat end (`cap_px` 0) it is refined to where the smoothed
    image `smooth` falls halfway from the band to the background along the line (`half_level_crossing`, reach
    ``3 blur_px + 1``), but, where the band's far corners lie more than `WIDE_SWEEP_WIDTHS` edge spacings apart
    across the line (``(gap_r, gap_c)``: corner B less corner A, the segmentation points; 0, 0 for a still rope),
    not to less than that farthest point less `blur_px`; the tip goes `cap_px` short of it (half a width for a
    round end). The polyline is cut `skip_px` from its end and the tip appended, in place. Returns the new point
    count, or `n` unchanged when the polyline is too short or no band end is found.
    """
    if n < 3 or n >= poly.shape[0]:
        return n
    ok, base_r, base_c, dir_r, dir_c = _band_axis(poly, n, skip_px, span_px)
    if ok == 0.0:
        return n
    best = -1e30
    for i in range(n_points):
        rel_r = points[i, 0] - base_r
        rel_c = points[i, 1] - base_c
        along = rel_r * dir_r + rel_c * dir_c
        across = abs(rel_r * dir_c - rel_c * dir_r)
        if across < 0.5 * width_px and -2.0 < along < skip_px + 4.0 * width_px and along > best:
            best = along
    if best < -1e29:
        return n
    return _band_tip(
        poly, n, smooth, base_r, base_c, dir_r, dir_c, best, width_px, cap_px, skip_px, blur_px, gap_r, gap_c
    )


@kernel(
    int32(f4_2d, int32, f4_2d_ro, int32, f4_2d_ro, float32, float32, float32, float32, float32, float32, float32,
          f8_1d_ro, float32, float32)
)  # fmt: skip
def extend_to_band_end_near(
    poly, n, points, n_points, smooth, width_px, cap_px, skip_px, span_px, blur_px, gap_r, gap_c, fixed_dist,
    fixed_r, fixed_c,
):  # fmt: skip
    """`extend_to_band_end` (same results) looking for the band's end only among the contour points whose distance
    from (`fixed_r`, `fixed_c`), given in ``fixed_dist[:n_points]`` (`find_segmentation_points`' distances from
    that point), is within the reach of the search from the axis' base (plus 1 px for roundings): a point
    farther cannot lie within half a width of the axis and `skip_px` + 4 widths of the base (triangle
    inequality), so the full computation runs on the few points near the tip. A `fixed_dist` shorter than
    `n_points` checks every point (as `extend_to_band_end`).
    """
    if n < 3 or n >= poly.shape[0]:
        return n
    if fixed_dist.shape[0] < n_points:
        return extend_to_band_end(
            poly, n, points, n_points, smooth, width_px, cap_px, skip_px, span_px, blur_px, gap_r, gap_c
        )
    ok, base_r, base_c, dir_r, dir_c = _band_axis(poly, n, skip_px, span_px)
    if ok == 0.0:
        return n
    reach = max(2.0, skip_px + 4.0 * width_px)
    radius = math.sqrt(reach * reach + 0.25 * width_px * width_px) + 1.0
    d_base = vector_length(base_r - fixed_r, base_c - fixed_c)
    near = d_base - radius
    far = d_base + radius
    best = -1e30
    for i in range(n_points):
        d = fixed_dist[i]
        if d < near or d > far:  # false for nan: such a point is checked
            continue
        # `extend_to_band_end`'s test, written out on purpose: as a step kernel both loops call it cost 11.8 ->
        # 12.1 us per call here, 11.0 -> 12.0 us there (a 1400-point contour; script, session 10), on the steady
        # frame's split.
        rel_r = points[i, 0] - base_r
        rel_c = points[i, 1] - base_c
        along = rel_r * dir_r + rel_c * dir_c
        across = abs(rel_r * dir_c - rel_c * dir_r)
        if across < 0.5 * width_px and -2.0 < along < skip_px + 4.0 * width_px and along > best:
            best = along
    if best < -1e29:
        return n
    return _band_tip(
        poly, n, smooth, base_r, base_c, dir_r, dir_c, best, width_px, cap_px, skip_px, blur_px, gap_r, gap_c
    )
