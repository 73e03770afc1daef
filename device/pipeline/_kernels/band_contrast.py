"""The rope's contrast read across the band at each point of a side (`contrast_gains`).

The local sweep comes from the edge's slope divided by the rope's contrast (`side_sweeps`). One contrast per
frame, read near the fixed end, misreads the sweep wherever the rope is brighter or darker than there (uneven
lighting, a braid's or a dyed rope's pattern): where the sweep is below about the rope's width the inward offset
depends on it, and the two shapes are pushed apart along one stretch and together along the next. Across the band
the time-averaged coverage integrates to the rope's width whatever the sweep and the blur, so the integral of the
frame across the band at each point, divided by the width, is the rope's contrast there.

The readings are taken at every `CONTRAST_STRIDE`-th point first. Where they spread along the side (where it sweeps
less than `GATE_WIDTHS` spacings) no more than an evenly bright rope's do (`MIN_SPREAD`), the frame's contrast stands
and the caller keeps the sweeps it read with it; else the other points are read too and the gains are those of
every point.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import float32, float64, int32

from ropecam.device.pipeline._kernels._common import FULL, f4_1d_ro
from ropecam.shared.jit import f4_1d, f4_2d_ro, f8_1d, i4_2d_ro, kernel, u1_2d_ro

REACH_WIDTHS: Final = 3.0
"""Points whose sweep (read with the frame's contrast) exceeds this many rope widths keep the frame's contrast:
there the inward offset hardly depends on the sweep, and the band is wide enough to hold other structures."""
MARGIN_PX: Final = 3.0
"""Samples taken beyond each side of the band (px): the background on both sides, past the lens blur's tails."""
STEP_PX: Final = 0.5
"""Spacing of the samples across the band (px)."""
CONTRAST_POINTS: Final = 10
"""Readings averaged on each side of a point (contour points about 1 px apart). Below about the blur the edge
slope changes little with the sweep, so the sweep read from it is steep in the contrast (on a 3 px rope sweeping
0.6 px, 1 % of contrast is 0.15 px of sweep): the readings' noise (mostly the background level, read over
`BACKGROUND_PX` on either side) must average to well below 1 %, while a rope's brightness pattern is followed (the
simulator's `rope_unevenness`: 3-20 cm, 12-80 px along the `lab` rope, whose error wave was the 80 px one)."""
BACKGROUND_PX: Final = 2.0
"""The background's level on either side of the band: the mean of the samples within this distance of its end."""
MIN_GAIN: Final = 0.5
MAX_GAIN: Final = 2.0
"""A point's reading that puts the contrast below half or above twice the frame's is not the rope's own (a
section along the rope at its end cap, another structure in the band): dropped before the average."""


CONTRAST_STRIDE: Final = 8
"""The first readings are taken at every this many points (each gain then the mean of the ~2-3 of them among the
``2 CONTRAST_POINTS + 1`` points around it): enough to tell an uneven rope from an even one (`MIN_SPREAD`) at an
eighth of the time of reading every point (~80 us per side on the synthetic rig frames)."""
GATE_WIDTHS: Final = 1.0
"""The first readings tell an uneven rope from an even one where the sweep (read with the frame's contrast) is at
most this many edge spacings: there the offset depends most on it, and there an even rope's readings are its
contrast. Beyond it they come out low as the sweep grows (simulated `rig`, an even rope: the readings over the
expected 0.96-1.01 below one spacing, 0.88-0.92 at two), an error the gate would take for unevenness."""
MIN_SPREAD: Final = 0.036
"""The spread (standard deviation over mean) of the first readings' gains within `GATE_WIDTHS` below which the rope
is taken as evenly bright and the frame's contrast stands. Read every 8th point, an even rope's gains spread
0.004-0.026 there (simulated `rig`, `rig-soft` and the synthetic rig frames, 88 sides each, 6-44 readings per side:
the readings' own error; applied on an even rope such errors had put `rig`'s centreline 0.06 -> 0.08 px off), a
rope with the simulator's `rope_unevenness` 0.15 on the `rig` scene 0.051-0.080, the `lab` presets' braided rope
(unevenness 0.15 and its photo texture) 0.055-0.132; the threshold is near the geometric mean of the even ropes'
largest and the uneven ones' smallest. By the sweep's sensitivity alone no threshold separates them: 1 % of
contrast is 0.15 px of sweep on a 3 px rope sweeping 0.6 px, so an even rope's 1-2 % would count as uneven."""
MAX_MEAN_OFFSET: Final = 0.03
"""However evenly they spread, first readings whose gains (within `GATE_WIDTHS`) average further than this from 1
mean the frame's contrast is not this frame's rope's (the contrast is read on the first frames: a light flickering
at 100 Hz changes every frame's; simulated `flicker` 0.1 / 0.2 on the `rig` scene: means 0.955-1.108 / 0.89-1.18,
spreads below 0.02); every point is then read. An even rope's average 0.996-1.040 there on `rig`, `rig-soft` and the
synthetic rig frames (median 1.016: the readings' own bias, low), 1.016-1.071 on `rig` seed 3 from 200 ms, whose
sides are then mostly read in full (77 %): outputs as before the gate, at its cost."""
MIN_GATE_READINGS: Final = 4
"""Fewer first readings within `GATE_WIDTHS` than this cannot tell the two apart: every point is then read."""


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, u1_2d_ro, f4_2d_ro, f4_2d_ro, float32, f4_1d_ro, float32,
          float64, int32, int32, f4_1d)
)  # fmt: skip
def read_contrast(
    points, chain, n, i_start, count, direction, frame, gx, gy, polarity, sweeps, spacing_px, expected, stride, skip,
    work,
):  # fmt: skip
    """Write the reading of the rope's contrast times its width at the side's points ``first, first + stride, ...``
    below `count` (``first`` = ``int(spacing_px + 2)``, past the fixed end's cap: see `contrast_gains`; the k-th
    point is chain index ``i_start + k direction``, cyclic over `n`; `stride` below `n`) into ``work[k]``, nan where
    there is none, but for every `skip`-th of them from ``first`` when `skip` > 1 (read before); the other entries
    are left alone. Returns the number written."""
    if stride < 1 or stride >= n:
        return 0
    first = int(spacing_px + 2.0)
    height = frame.shape[0]
    cols = frame.shape[1]
    reach = REACH_WIDTHS * spacing_px
    edge_samples = int(BACKGROUND_PX / STEP_PX) + 1
    written = 0
    step = stride * direction
    i = ((i_start + first * direction) % n + n) % n - step
    phase = -1
    for k in range(first, count, stride):
        # One walk along the side (neighbouring points read the same pixels: one pass keeps them in the cache).
        i += step
        if i >= n:
            i -= n
        elif i < 0:
            i += n
        phase += 1
        if phase == skip:
            phase = 0
        if skip > 1 and phase == 0:
            continue
        work[k] = np.nan
        written += 1
        d = max(float(sweeps[k]), 0.0)
        if d > reach:
            continue
        r = chain[i, 0]
        c = chain[i, 1]
        g_r = float(gy[r, c]) * polarity
        g_c = float(gx[r, c]) * polarity
        norm = math.sqrt(g_r * g_r + g_c * g_c)
        if norm <= 0.0:
            continue
        u_r = g_r / norm
        u_c = g_c / norm
        t0 = -MARGIN_PX
        steps = int((spacing_px + d + 2.0 * MARGIN_PX) / STEP_PX) + 1
        p_r = float(points[i, 0])
        p_c = float(points[i, 1])
        t1 = t0 + (steps - 1) * STEP_PX
        inside = True
        for t in (t0, t1):
            q_r = p_r + t * u_r
            q_c = p_c + t * u_c
            if not (0.0 <= q_r <= height - 1.001 and 0.0 <= q_c <= cols - 1.001):
                inside = False
        if not inside or steps <= 2 * edge_samples:
            continue
        total = 0.0
        first_level = 0.0
        last_level = 0.0
        for j in range(steps):
            t = t0 + j * STEP_PX
            q_r = p_r + t * u_r
            q_c = p_c + t * u_c
            r0 = int(q_r)
            c0 = int(q_c)
            f_r = q_r - r0
            f_c = q_c - c0
            v = (
                (1.0 - f_r) * ((1.0 - f_c) * frame[r0, c0] + f_c * frame[r0, c0 + 1])
                + f_r * ((1.0 - f_c) * frame[r0 + 1, c0] + f_c * frame[r0 + 1, c0 + 1])
            )  # fmt: skip
            total += v
            if j < edge_samples:
                first_level += v
            if j >= steps - edge_samples:
                last_level += v
        # The background: the line through the two end levels, summed over the samples.
        background = 0.5 * (first_level + last_level) / edge_samples * steps
        reading = polarity * (total - background) * STEP_PX
        if MIN_GAIN * reading <= expected <= MAX_GAIN * reading:
            work[k] = reading
    return written


@kernel(int32(f4_1d_ro, int32, int32, float64, f8_1d))
def average_readings(work, count, need, expected, out_gains):
    """Write into ``out_gains[:count]`` `expected` over the mean of the finite ``work`` readings among the
    ``2 CONTRAST_POINTS + 1`` points centred on each point (a running sum), where there are at least `need` of them
    and their mean is positive, else 1; the points before the first such average take it. Returns `count`."""
    half = CONTRAST_POINTS
    acc = 0.0
    found = 0
    for j in range(min(half, count - 1) + 1):
        if math.isfinite(work[j]):
            acc += work[j]
            found += 1
    first = -1
    for k in range(count):
        out_gains[k] = 1.0
        if found >= need and acc > 0.0:
            out_gains[k] = expected / (acc / found)
            if first < 0:
                first = k
                for j in range(k):  # the cap's points: the first average beyond it
                    out_gains[j] = out_gains[k]
        enter = k + half + 1
        if enter < count and math.isfinite(work[enter]):
            acc += work[enter]
            found += 1
        leave = k - half
        if leave >= 0 and math.isfinite(work[leave]):
            acc -= work[leave]
            found -= 1
    return count


@kernel(
    int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, u1_2d_ro, f4_2d_ro, f4_2d_ro, float32, f4_1d_ro, float32,
          float64, int32, f4_1d, f8_1d)
)  # fmt: skip
def contrast_gains(
    points, chain, n, i_start, i_stop, direction, frame, gx, gy, polarity, sweeps, spacing_px, expected, stride, work,
    out_gains,
):  # fmt: skip
    """Write, for each contour point of one side (from `i_start` stepping `direction` to `i_stop`, cyclic), the
    frame's contrast over the rope's contrast at that point into `out_gains` (the factor `side_sweeps` applies
    to the frame's inverse contrast), when the rope's contrast varies along the side.

    The point's contrast is the integral of `frame` (bilinear, every `STEP_PX`) along ``polarity`` times its
    gradient (into the rope), from `MARGIN_PX` outside the side to the band's far side (the edges lie `spacing_px`
    apart, the point sweeps ``sweeps[k]``) + `MARGIN_PX`, less a line through the levels of the first and the last
    `BACKGROUND_PX` of samples (the background); `expected` is that integral for the frame's contrast (the frame's
    contrast times the rope's own width, the edge model's for that spacing, as the frame's contrast is read:
    `BandMeasure.contrast`). The first ``spacing_px + 2`` points (the
    fixed end's cap, or the seal across a clamp's exit: sections along the rope) are not read; any other point
    without a reading (its sweep beyond `REACH_WIDTHS` spacings, its section leaving the frame, a gain outside
    [`MIN_GAIN`, `MAX_GAIN`]) counts as none.

    Every `stride`-th point is read first (`read_contrast`) and each point's gain is taken from the mean of the
    readings among the ``2 CONTRAST_POINTS + 1`` points centred on it (`average_readings`; at least ``(CONTRAST_POINTS
    + 1) / stride`` of them, rounded up). When those gains at the points read whose sweep is at most `GATE_WIDTHS`
    spacings (`MIN_GATE_READINGS` of them or more) spread (standard deviation over mean) less than `MIN_SPREAD`
    and average within `MAX_MEAN_OFFSET` of 1, or no point was read, the frame's contrast stands: returns 0
    (`out_gains` is then not to be applied). Else the other points are read too (one walk) and the gains written
    are those of every point's readings (at least ``CONTRAST_POINTS + 1`` of them, the points before the first
    average taking it, 1 where none). With `stride` 1 every point is read and its gains written whatever their
    spread (no gate). An empty `frame` or an `expected` of 0 (no rope width: a strong lens blur) returns 0.
    `work` (float32, the side's length) keeps the raw readings. Returns the number of points when the gains are to
    be applied, 0, or FULL.
    """
    count = ((i_stop - i_start) * direction % n + n) % n + 1
    if count > out_gains.shape[0] or count > work.shape[0]:
        return FULL
    if frame.shape[0] <= 1 or frame.shape[1] <= 1 or not expected > 0.0 or stride < 1:
        return 0
    half = CONTRAST_POINTS
    for k in range(count):
        work[k] = np.nan
    # The side's first points are the fixed end's cap (or the seal across a clamp's exit): sections there run
    # along the rope. They take the contrast read just beyond.
    cap = int(spacing_px + 2.0)
    read_contrast(points, chain, n, i_start, count, direction, frame, gx, gy, polarity, sweeps, spacing_px,
                  expected, stride, np.int32(0), work)  # fmt: skip
    average_readings(work, count, np.int32((half + stride) // stride), expected, out_gains)
    total = 0.0
    squares = 0.0
    found = 0
    read = 0
    gate = GATE_WIDTHS * spacing_px
    for k in range(cap, count, stride):
        if math.isfinite(work[k]):
            read += 1
            if sweeps[k] <= gate:
                g = out_gains[k]
                total += g
                squares += g * g
                found += 1
    if read == 0:
        return 0
    if stride > 1 and found >= MIN_GATE_READINGS:
        mean = total / found
        spread = math.sqrt(max(squares / found - mean * mean, 0.0))
        if spread < MIN_SPREAD * mean and abs(mean - 1.0) < MAX_MEAN_OFFSET:
            return 0
    if stride > 1:  # the points between, in one walk
        read_contrast(points, chain, n, i_start, count, direction, frame, gx, gy, polarity, sweeps, spacing_px,
                      expected, np.int32(1), stride, work)  # fmt: skip
        average_readings(work, count, np.int32(half + 1), expected, out_gains)
    return count
