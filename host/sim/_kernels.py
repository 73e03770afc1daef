"""Numba kernels of the rope rasteriser: nearest-centreline geometry per sub-frame, then coverage accumulation.

The rope seen by the camera is a band of (slowly varying) half-width ``r`` around its projected centreline, with flat
cut ends. Its image is that band convolved with a Gaussian of standard deviation ``sigma`` (the lens blur and the
pixel's area, see `ropecam.host.sim.render`), which across a locally straight band at distance ``d`` from the
centreline is the closed form ``Phi((r - d) / sigma) - Phi((-r - d) / sigma)`` and, past a flat end at signed
distance ``e`` inside the end, is multiplied by ``Phi(e / sigma)``.

Two passes per sub-frame keep the error function off the inner loop: `stamp_centreline` records for every pixel
near the rope the nearest centreline segment's distance, half-width, brightness and end factor; `accumulate_cover`
turns those into coverage, adds the time-weighted coverage and coverage x brightness into the exposure sums and
clears the scratch buffers for the next sub-frame.

Pixel coordinates are OpenCV's (u, v) = (column, row) with (0, 0) at the centre of the top-left pixel, in float64
(the ground truth's precision).
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import float64, int32

from ropecam.shared.jit import f4_2d, f4_2d_ro, f8_1d_ro, f8_2d_ro, i4_1d, kernel

FAR: Final = np.float32(1e30)
"""Distance stored in the scratch buffer for pixels no segment has touched."""
REACH_SIGMAS: Final = 5.0
"""Pixels farther than ``r + REACH_SIGMAS * sigma`` from the centreline get no coverage (Phi(-5) = 3e-7)."""
INVALID: Final = -2
"""Return code: bad argument shapes or values (same value as `KernelStatus.INVALID`)."""


@kernel(float64(float64))
def normal_cdf(x):
    """Return the standard normal cumulative distribution at `x`."""
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


@kernel(int32(f8_2d_ro, f8_1d_ro, f8_1d_ro, float64, f4_2d_ro, float64, int32, int32, f4_2d, f4_2d, f4_2d, f4_2d,
             i4_1d))  # fmt: skip
def stamp_centreline(
    points_px, radius_px, level, sigma_px, texture, texture_rows_per_sample, row_first, row_last, out_dist,
    out_radius, out_level, out_cut, out_box,
):  # fmt: skip
    """Record, per pixel near the polyline, the nearest segment's distance, half-width, brightness and end factor.

    Parameters
    ----------
    points_px
        (S, 2) centreline points (u, v) in pixels, S >= 2, in arc-length order (first = fixed end, last = tip).
    radius_px
        (S,) apparent half-width of the rope at each point, pixels.
    level
        (S,) rope brightness at each point (any unit; carried to `out_level`).
    sigma_px
        Standard deviation of the edge blur, pixels (> 0).
    texture
        (A, B) relative brightness of the rope's surface: rows along the rope (periodic, `texture_rows_per_sample`
        rows per centreline sample), columns across it from the side to the left of the direction of travel
        (fixed end to tip, image axes) to the right; read bilinearly and multiplied into the level. (1, 1) = plain
        rope, not read.
    texture_rows_per_sample
        Texture rows per centreline sample (>= 0).
    row_first, row_last
        Only image rows in this inclusive range are stamped (a rolling shutter's sub-frame counts for some rows
        only); 0 and H - 1 for all.
    out_dist, out_radius, out_level, out_cut
        (H, W) scratch buffers, written where a segment is nearer (in distance minus half-width) than what they hold.
        `out_dist` must hold `FAR` where untouched (as `accumulate_cover` leaves it).
    out_box
        (4,) int32: updated in place to the union of its content and the touched pixels, as
        (u_min, v_min, u_max, v_max) inclusive; pass (W, H, -1, -1) for an empty box.

    Returns
    -------
    int
        Number of segments stamped, or `INVALID` for inconsistent shapes or a non-positive sigma.
    """
    n = points_px.shape[0]
    height, width = out_dist.shape
    if n < 2 or points_px.shape[1] != 2 or radius_px.shape[0] != n or level.shape[0] != n or not sigma_px > 0:
        return INVALID
    if out_radius.shape != out_dist.shape or out_level.shape != out_dist.shape or out_cut.shape != out_dist.shape:
        return INVALID
    tex_rows, tex_cols = texture.shape
    textured = tex_rows > 1 or tex_cols > 1
    if tex_rows < 1 or tex_cols < 1 or not texture_rows_per_sample >= 0:
        return INVALID
    # End factors apply to the segments within reach of a flat end along the rope (their round joins would
    # otherwise poke out past the cut); found by walking the arc from each end.
    reach_end = 0.0
    for i in range(n):
        reach_end = max(reach_end, radius_px[i])
    reach_end += REACH_SIGMAS * sigma_px + 1.0
    first_free = 0
    walked = 0.0
    while first_free < n - 1 and walked < reach_end:
        walked += math.hypot(
            points_px[first_free + 1, 0] - points_px[first_free, 0],
            points_px[first_free + 1, 1] - points_px[first_free, 1],
        )
        first_free += 1
    last_free = n - 2
    walked = 0.0
    while last_free > 0 and walked < reach_end:
        walked += math.hypot(
            points_px[last_free + 1, 0] - points_px[last_free, 0],
            points_px[last_free + 1, 1] - points_px[last_free, 1],
        )
        last_free -= 1
    # Unit tangents at the two ends (pointing into the rope at the start, out of it at the tip).
    su = points_px[1, 0] - points_px[0, 0]
    sv = points_px[1, 1] - points_px[0, 1]
    slen = math.hypot(su, sv)
    eu = points_px[n - 1, 0] - points_px[n - 2, 0]
    ev = points_px[n - 1, 1] - points_px[n - 2, 1]
    elen = math.hypot(eu, ev)
    if slen > 0:
        su /= slen
        sv /= slen
    if elen > 0:
        eu /= elen
        ev /= elen
    u_lo, v_lo, u_hi, v_hi = out_box[0], out_box[1], out_box[2], out_box[3]
    for i in range(n - 1):
        au = points_px[i, 0]
        av = points_px[i, 1]
        du = points_px[i + 1, 0] - au
        dv = points_px[i + 1, 1] - av
        length2 = du * du + dv * dv
        reach = max(radius_px[i], radius_px[i + 1]) + REACH_SIGMAS * sigma_px
        c0 = max(0, math.floor(min(au, au + du) - reach))
        c1 = min(width - 1, math.ceil(max(au, au + du) + reach))
        r0 = max(row_first, math.floor(min(av, av + dv) - reach))
        r1 = min(row_last, height - 1, math.ceil(max(av, av + dv) + reach))
        if c0 > c1 or r0 > r1:
            continue
        u_lo = min(u_lo, c0)
        v_lo = min(v_lo, r0)
        u_hi = max(u_hi, c1)
        v_hi = max(v_hi, r1)
        cut_start = i < first_free
        cut_end = i > last_free
        for row in range(r0, r1 + 1):
            for col in range(c0, c1 + 1):
                pu = col - au
                pv = row - av
                t = (pu * du + pv * dv) / length2 if length2 > 0 else 0.0
                # The end segments extend as their lines past the flat ends (the end factor fades them out).
                if t < 0.0 and i != 0:
                    t = 0.0
                if t > 1.0 and i != n - 2:
                    t = 1.0
                qu = pu - t * du
                qv = pv - t * dv
                dist = math.sqrt(qu * qu + qv * qv)
                tc = min(max(t, 0.0), 1.0)
                radius = radius_px[i] + tc * (radius_px[i + 1] - radius_px[i])
                if dist - radius >= out_dist[row, col] - out_radius[row, col]:
                    continue
                cut = 1.0
                if cut_start:
                    cut *= normal_cdf(((col - points_px[0, 0]) * su + (row - points_px[0, 1]) * sv) / sigma_px)
                if cut_end:
                    inside = (points_px[n - 1, 0] - col) * eu + (points_px[n - 1, 1] - row) * ev
                    cut *= normal_cdf(inside / sigma_px)
                out_dist[row, col] = dist
                out_radius[row, col] = radius
                value = level[i] + tc * (level[i + 1] - level[i])
                if textured:
                    # Material coordinate along (periodic) and signed position across, -1..1 edge to edge.
                    tr = ((i + tc) * texture_rows_per_sample) % tex_rows
                    side = dist / radius if radius > 0 else 0.0
                    if du * qv - dv * qu < 0:
                        side = -side
                    tcol = (min(max(side, -1.0), 1.0) + 1.0) * 0.5 * (tex_cols - 1)
                    ra = int(tr)
                    rb = ra + 1 if ra + 1 < tex_rows else 0
                    ca = min(int(tcol), tex_cols - 1)
                    cb = min(ca + 1, tex_cols - 1)
                    fr = tr - ra
                    fc = tcol - ca
                    top = texture[ra, ca] + fc * (texture[ra, cb] - texture[ra, ca])
                    bottom = texture[rb, ca] + fc * (texture[rb, cb] - texture[rb, ca])
                    value *= top + fr * (bottom - top)
                out_level[row, col] = value
                out_cut[row, col] = cut
    out_box[0] = u_lo
    out_box[1] = v_lo
    out_box[2] = u_hi
    out_box[3] = v_hi
    return n - 1


@kernel(int32(f4_2d, f4_2d, f4_2d, f4_2d, i4_1d, float64, f8_1d_ro, f4_2d, f4_2d))
def accumulate_cover(dist, radius, level, cut, box, sigma_px, row_weight, out_cover_sum, out_signal_sum):
    """Add one sub-frame's coverage (times its row's weight) to the exposure sums and clear the scratch buffers.

    Parameters
    ----------
    dist, radius, level, cut
        (H, W) scratch buffers filled by `stamp_centreline`; reset here (`dist` to `FAR`, the others to 0) inside
        `box`.
    box
        (4,) int32 (u_min, v_min, u_max, v_max) inclusive, as left by `stamp_centreline`; reset to empty here.
    sigma_px
        Edge blur standard deviation, pixels (> 0).
    row_weight
        (H,) quadrature weight of this sub-frame for each image row (one row's weights over an exposure sum to 1).
        A global shutter gives every row the same weight; a rolling shutter exposes each row over its own
        interval, so a sub-frame counts for the rows whose exposure it falls in (weight 0 elsewhere).
    out_cover_sum
        (H, W): += row_weight[row] * coverage.
    out_signal_sum
        (H, W): += row_weight[row] * coverage * level.

    Returns
    -------
    int
        Number of pixels with non-zero coverage, or `INVALID` for inconsistent shapes or a non-positive sigma.
    """
    height, width = dist.shape
    if radius.shape != dist.shape or level.shape != dist.shape or cut.shape != dist.shape or not sigma_px > 0:
        return INVALID
    if out_cover_sum.shape != dist.shape or out_signal_sum.shape != dist.shape or row_weight.shape[0] != height:
        return INVALID
    u0 = max(box[0], 0)
    v0 = max(box[1], 0)
    u1 = min(box[2], width - 1)
    v1 = min(box[3], height - 1)
    count = 0
    scale = 1.0 / (sigma_px * math.sqrt(2.0))
    for row in range(v0, v1 + 1):
        weight = row_weight[row]
        for col in range(u0, u1 + 1):
            d = dist[row, col]
            if d < FAR:
                r = radius[row, col]
                cover = 0.5 * (math.erf((r - d) * scale) + math.erf((r + d) * scale)) * cut[row, col]
                if cover > 0.0:
                    out_cover_sum[row, col] += weight * cover
                    out_signal_sum[row, col] += weight * cover * level[row, col]
                    count += 1
                dist[row, col] = FAR
                radius[row, col] = 0.0
                level[row, col] = 0.0
                cut[row, col] = 0.0
    box[0] = width
    box[1] = height
    box[2] = -1
    box[3] = -1
    return count
