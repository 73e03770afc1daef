"""The band prediction's measured error: how far each part of the contour found lay from the predicted contour."""

from __future__ import annotations

import math

from numba import boolean, float64, int32, int64

from ropecam.device.pipeline._kernels._common import INVALID
from ropecam.shared.jit import f4_2d_ro, f8_1d, f8_2d, kernel


@kernel(float64(f4_2d_ro, int64, float64, float64))
def _dist2(points, j, r, c):
    """Squared distance (px^2) from (r, c) to point `j`."""
    dr = float(points[j, 0]) - r
    dc = float(points[j, 1]) - c
    return dr * dr + dc * dc


@kernel(int64(int64, int64))
def _wrap(k, n):
    """Index `k` (at most one round off) wrapped into ``[0, n)``."""
    if k < 0:
        return k + n
    if k >= n:
        return k - n
    return k


@kernel(int32(f4_2d_ro, int64, f4_2d_ro, int64, int64, float64, float64, float64, float64, boolean, f8_2d, f8_1d))
def need_profile(
    moved, n_moved, found, n_found, margin_px, fixed_r, fixed_c, gain, floor_px, motion_held, need_hist, out_profile
):
    """Measure how much of the band's uncertainty this frame needed, per part of the rope, and write the cap on the
    next frame's uncertainty (`spans_around_chain`'s profile).

    `moved` holds the predicted contour (the last contour moved by the predicted motion; a closed chain of
    `n_moved` (row, col) points), `found` the contour found in this frame (a closed chain of `n_found` points).
    Each found point is matched to a near predicted point q: the point one step on (in the direction the match
    last moved) from the last match when it lies within `margin_px` (the point needs nothing, whichever predicted
    point is its nearest), else by walking along the predicted chain from the last match while that gets nearer
    (one point at a time, on in the direction of the last move or back; the first found point is matched to its
    nearest predicted point): the distance to
    q is never smaller than to the nearest predicted point, so the need is never underestimated. The need of
    q's bin (``s = |q - fixed| / max |moved - fixed|``, ``bins = need_hist.shape[1]`` equal bins of [0, 1]) is
    the largest ``max(0, distance - margin_px)`` there.

    `need_hist` (2, bins) keeps this frame's needs in row 0 and the previous frame's in row 1; `out_profile`
    (bins,) gets ``gain * max(need of both frames over the bin and its two neighbours) + floor_px`` (px), or inf
    (no profile) unless `motion_held` (the motion model held at least ``MOTION_FRAMES - 1`` frames when `moved` was
    predicted): the next frame's prediction, from fewer than `MOTION_FRAMES` frames, is of another kind than the
    one measured (and the fixed end still a guess).

    Returns the found points matched, or INVALID (nothing written) when a chain is empty or the arrays do not fit.
    """
    bins = need_hist.shape[1]
    if n_moved < 1 or n_found < 1 or moved.shape[0] < n_moved or found.shape[0] < n_found:
        return INVALID
    if need_hist.shape[0] < 2 or bins < 1 or out_profile.shape[0] != bins:
        return INVALID
    d2_max = 1e-12
    best = math.inf
    j = 0
    r0 = float(found[0, 0])
    c0 = float(found[0, 1])
    for k in range(n_moved):
        mr = float(moved[k, 0])
        mc = float(moved[k, 1])
        dr = mr - fixed_r
        dc = mc - fixed_c
        d2 = dr * dr + dc * dc
        if d2 > d2_max:
            d2_max = d2
        d = _dist2(moved, k, r0, c0)
        if d < best:
            best = d
            j = k
    inv_d_max = 1.0 / math.sqrt(d2_max)
    for b in range(bins):
        need_hist[1, b] = need_hist[0, b]
        need_hist[0, b] = 0.0
    margin2 = float(margin_px) * float(margin_px)
    step = 1  # the direction the match last moved along the predicted chain
    matched = n_found  # less the invalid points
    for i in range(n_found):
        r = float(found[i, 0])
        c = float(found[i, 1])
        # The usual case first: the point one step on from the last match lies within the margin. Then the
        # point needs nothing, whichever predicted point is its nearest. (Tested before the found point's
        # validity: a NaN fails it, and a point within the margin of a predicted one is valid; 1.9 us per frame.)
        k = j + step
        if k >= n_moved:
            k = 0
        elif k < 0:
            k = n_moved - 1
        d = _dist2(moved, k, r, c)  # (the walk's ties compare distances of this one helper: keep it)
        if d <= margin2:
            j = k
            continue
        if not (abs(r) < 1e9 and abs(c) < 1e9):
            matched -= 1
            continue
        # Else walk along the chain one point at a time while that gets nearer: on from there in the same
        # direction, or back the other way when the last match is nearer than the point one step on.
        dj = _dist2(moved, j, r, c)
        if dj < d:
            k = j
            d = dj
            back = _wrap(j - step, n_moved)
            db = _dist2(moved, back, r, c)
            if db < d:
                step = -step
                k = back
                d = db
        for _ in range(n_moved):  # at most once round the chain
            kk = _wrap(k + step, n_moved)
            dk = _dist2(moved, kk, r, c)
            if not dk < d:
                break
            d = dk
            k = kk
        j = k
        qr = float(moved[j, 0]) - fixed_r
        qc = float(moved[j, 1]) - fixed_c
        b = min(bins - 1, int(math.sqrt(qr * qr + qc * qc) * inv_d_max * bins))
        need = math.sqrt(d) - margin_px
        if need > need_hist[0, b]:
            need_hist[0, b] = need
    for b in range(bins):
        if not motion_held:
            out_profile[b] = math.inf
            continue
        worst = 0.0
        for bb in range(max(0, b - 1), min(bins, b + 2)):
            worst = max(worst, need_hist[0, bb], need_hist[1, bb])
        out_profile[b] = gain * worst + floor_px
    return matched
