"""The band's search without a track: a known middle line turned and bent at joints to where a faint band lies.

Used by the offline band tracker (`tools/ropecam_tools/eval_band_track.py`, `lab-hard`: a blurred band whose edges
are below the noise) to check its lock and to re-seed a lost track; not on the device's per-frame path.
"""

from __future__ import annotations

import math

from numba import float64, int32, types

from ropecam.shared.jit import f8_2d, f8_2d_ro, kernel


@kernel(float64(f8_2d_ro, float64, float64))
def sample_or_zero(image, row, col):
    """Return `image` interpolated bilinearly at (`row`, `col`), 0 outside ``[0, height - 1] x [0, width - 1]``
    (scipy's ``map_coordinates(order=1, mode="constant", cval=0)``)."""
    height = image.shape[0]
    width = image.shape[1]
    if not (0.0 <= row <= height - 1.0 and 0.0 <= col <= width - 1.0):
        return 0.0
    r0 = int(row)
    c0 = int(col)
    r1 = min(r0 + 1, height - 1)
    c1 = min(c0 + 1, width - 1)
    fr = row - r0
    fc = col - c0
    top = image[r0, c0] * (1.0 - fc) + image[r0, c1] * fc
    bottom = image[r1, c0] * (1.0 - fc) + image[r1, c1] * fc
    return top * (1.0 - fr) + bottom * fr


@kernel(float64(f8_2d_ro, f8_2d_ro, int32, int32, int32, float64))
def turned_score(evidence, line, lo, hi, joint, angle_rad):
    """Return the mean of `evidence` along points ``lo..hi - 1`` of `line` ((n, 2) u, v), the part from point
    `joint` on turned by `angle_rad` about that point (the points before `joint` as they are); nan for no point."""
    if hi <= lo:
        return math.nan
    c = math.cos(angle_rad)
    s = math.sin(angle_rad)
    ju = line[joint, 0]
    jv = line[joint, 1]
    total = 0.0
    for i in range(lo, hi):
        u = line[i, 0]
        v = line[i, 1]
        if i >= joint:
            du = u - ju
            dv = v - jv
            u = ju + c * du - s * dv
            v = jv + s * du + c * dv
        total += sample_or_zero(evidence, v, u)
    return total / (hi - lo)


@kernel(int32(f8_2d, int32, float64))
def turn_from(line, joint, angle_rad):
    """Turn the part of `line` ((n, 2) u, v, written in place) from point `joint` on by `angle_rad` about that
    point; return the points moved."""
    c = math.cos(angle_rad)
    s = math.sin(angle_rad)
    ju = line[joint, 0]
    jv = line[joint, 1]
    for i in range(joint, line.shape[0]):
        du = line[i, 0] - ju
        dv = line[i, 1] - jv
        line[i, 0] = ju + c * du - s * dv
        line[i, 1] = jv + s * du + c * dv
    return line.shape[0] - joint


@kernel(types.UniTuple(float64, 2)(f8_2d_ro, f8_2d_ro, int32, int32, int32, float64, float64, int32, float64))
def best_turn(evidence, line, lo, hi, joint, from_deg, step_deg, steps, floor):
    """Return the highest `turned_score` (points ``lo..hi - 1`` of `line` turned from point `joint` on) above
    `floor` over the angles ``from_deg + k step_deg`` (k = 0..`steps`, degrees) and its angle (rad); (`floor`, 0)
    when none is above it. Ties keep the first angle."""
    best = floor
    chosen = 0.0
    for k in range(steps + 1):
        angle = math.radians(from_deg + k * step_deg)
        score = turned_score(evidence, line, lo, hi, joint, angle)
        if score > best:
            best = score
            chosen = angle
    return best, chosen


@kernel(float64(f8_2d_ro, f8_2d_ro, int32, float64, float64, float64, float64, float64, f8_2d))
def search_band_line(evidence, shape, joints, skip_fraction, turn_deg, step_deg, refine_deg, refine_step_deg, out_line):
    """Find the band in `evidence` (the frame minus its background, smoothed; the band brighter) by bending `shape`
    ((n, 2) u, v, fixed end first) at `joints` joints evenly spaced by point index from its first point, and write
    the line found into `out_line` ((n, 2)); return the mean evidence along it beyond the fraction `skip_fraction`
    of its points (nan for fewer than 2 points, a joint count outside ``1..n - 1`` or a short `out_line`).

    Traced from the fixed end: joint k is turned by ``-reach .. reach`` in steps of `step_deg` degrees (reach
    `turn_deg`, twice that at the first joint: the whole rope may have swung far), keeping the angle whose segment
    and the next (points ``max(k n // joints, skip n) .. (k + 2) n // joints``) have the highest mean evidence; then
    each joint in turn is refined by ``-refine_deg .. refine_deg`` in steps of `refine_step_deg` on the whole line
    beyond `skip_fraction`. Ties keep the first (the most negative) angle."""
    count = shape.shape[0]
    if count < 2 or joints < 1 or joints > count - 1 or out_line.shape[0] < count:
        return math.nan
    for i in range(count):
        out_line[i, 0] = shape[i, 0]
        out_line[i, 1] = shape[i, 1]
    line = out_line[:count]
    skip = int(skip_fraction * count)
    for joint in range(joints):
        at = joint * count // joints
        lo = max(at, skip)
        hi = min((joint + 2) * count // joints, count)
        reach = 2.0 * turn_deg if joint == 0 else turn_deg
        steps = int(2.0 * reach / step_deg + 0.5)
        best, chosen = best_turn(evidence, line, lo, hi, at, -reach, step_deg, steps, -math.inf)
        turn_from(line, at, chosen)
    best = turned_score(evidence, line, skip, count, 0, 0.0)
    steps = int(2.0 * refine_deg / refine_step_deg + 0.5)
    for joint in range(joints):
        at = joint * count // joints
        # each better angle is relative to the line as it stood before this joint's refinement
        best, chosen = best_turn(evidence, line, skip, count, at, -refine_deg, refine_step_deg, steps, best)
        turn_from(line, at, chosen)
    return best
