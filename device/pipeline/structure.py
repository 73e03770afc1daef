"""The structure a still rope runs into at its fixed end (a clamp, the rod holding it), found from the shape of the
rope's first outline: the region the static mask takes out of every later frame from the start, before it has
learned the structure from stillness (`StaticMask`).

On the first frames of a stream the rope hangs still, and so does the clamp it is fixed in: the static mask cannot
yet tell them apart, and the rope's outline runs round the clamp (and up its rod). The split then reads one side
along the clamp's outline (the two shapes differ in length: no split) or a centreline out along the rope and back.
The outline itself shows where the rope ends: from its free tip the rope's two sides run a rope's width apart up to
where the rope leaves the clamp, and there they part (`zip_sides`: both sides walked together from the tip). The
outline's other points are the structure's (a shaded clamp's bevels, a bolt, a rod walked out and back included);
their convex hull is its region.

The region is kept after the learning: the part of the clamp's outline the still rope covered while the mask was
learned is not still in the learned ranges (the rope was there), so it would join the rope's outline as a whisker
once the rope swings off it; it lies inside the region (the rope leaves the region where it left the clamp).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ACROSS_WIDTHS",
    "across_distances",
    "convex_hull",
    "fill_polygon",
    "grow",
    "structure_points",
    "zip_sides",
]

ACROSS_WIDTHS = 1.6
"""The rope's two sides, walked together from the free tip, are the rope's while they lie within this many rope
widths (+1 px) of each other (a rope at rest: a width apart); where the rope leaves a clamp they part. The smallest
clamp simulated (12 x 7.2 px against a 2.5 px rope, edge spacing 2.6-3.2 px) is 7.2 px across, above
1.6 x 3.2 + 1 = 6.1."""
SAME_PLACE_PX = 1.5
"""Points of the outline nearer each other than this are one place walked twice (an outline that is a tree: the
trace walks a line out and back, on the line's own or its neighbouring pixels); a rope's sides lie a rope width,
2 px or more, apart."""
EXIT_WIDTHS = 2.5
"""The two points where the rope leaves the structure lie at most this many rope widths (+2 px) apart (the rope's
width across, a pixel or two more where the sides part at a slant)."""
STRUCTURE_AREA_WIDTHS = 4.0
"""A structure's region (the convex hull of its outline and the rope's exit) covers at least this many squared
rope widths (the smallest clamp simulated, 12 x 7.2 px, about ten)."""
WIDENING_PX = 0.5
"""A rope's band narrows towards its fixed end (the sweep grows with the distance from it); walked from the free
tip towards a structure, its sides may not lie more than this much farther apart over the walk's second half than
over its first (median). Walked from the fixed end of a swinging rope, they part as the band widens."""
STRUCTURE_ROPE_RATIO = 0.5
"""A structure is at most this fraction of the rope's length across (the walk from the tip along each side). Walked
from its fixed end, a swinging rope's band widens beyond a rope's width part of the way out: the rest, the band's
far part, is no structure and is as large as the rope."""
_SPACING_SAMPLES = 128
"""Outline points the rope's edge spacing is read at (`structure_points`: a cold path, kept to a few ms)."""
_BLOCK = 256
"""Rows of the distance matrices computed at a time (a cold path: the first frames only)."""


def across_distances(points: NDArray[np.float64], gap: int, every: int = 1) -> NDArray[np.float64]:
    """Return, for every `every`-th point of a closed outline (`points` (n, 2)), the distance to the nearest point
    of the outline at least `gap` places away along it (either way round) and not at the same place
    (`SAME_PLACE_PX`): across the rope, the other side."""
    n = len(points)
    index = np.arange(n)
    chosen = index[::every]
    out = np.empty(len(chosen))
    for start in range(0, len(chosen), _BLOCK):
        rows = chosen[start : start + _BLOCK]
        d2 = ((points[rows, None, :] - points[None, :, :]) ** 2).sum(axis=2)
        ring = np.abs(rows[:, None] - index[None, :])
        d2[(np.minimum(ring, n - ring) < gap) | (d2 < SAME_PLACE_PX**2)] = np.inf
        out[start : start + len(rows)] = np.sqrt(d2.min(axis=1))
    return out


def zip_sides(points: NDArray[np.float64], tip: int, limit_px: float, close_px: float) -> tuple[int, int, float, float]:
    """Walk a closed outline's two sides together from the point `tip` (an index of `points`, (n, 2)): one step at
    a time on the side whose step keeps the two walkers nearer, while they lie within `limit_px` of each other and,
    once they have been `close_px` apart, no nearer than that.

    Returns
    -------
    tuple[int, int, float, float]
        The steps walked forward and backward (the walkers stop where the sides part, as a rope's where it leaves a
        clamp, or meet again, as where the rope's outline is closed across its end at the clamp or at its fixed
        end, and where a line is walked out and back), and the median distance between the walkers over the
        walk's first and second half (0 for a walk of fewer than 4 steps).
    """
    n = len(points)
    rows, cols = points[:, 0].tolist(), points[:, 1].tolist()  # Python floats: a step of the walk costs ~1 us
    forward = backward = 0
    gaps = []
    opened = False
    while forward + backward < n - 2:
        a0, b0 = (tip + forward) % n, (tip - backward) % n
        a1, b1 = (tip + forward + 1) % n, (tip - backward - 1) % n
        step_a = math.hypot(rows[a1] - rows[b0], cols[a1] - cols[b0])
        step_b = math.hypot(rows[a0] - rows[b1], cols[a0] - cols[b1])
        nearest = min(step_a, step_b)
        if nearest > limit_px or (opened and nearest < close_px):
            break
        opened = opened or nearest >= close_px
        if step_a <= step_b:
            forward += 1
            gaps.append(step_a)
        else:
            backward += 1
            gaps.append(step_b)
    walked = len(gaps)
    if walked < 4:
        return forward, backward, 0.0, 0.0
    return forward, backward, float(np.median(gaps[: walked // 2])), float(np.median(gaps[walked // 2 :]))


def structure_points(
    points: NDArray[np.float64], ends: tuple[int, int], width_px: float
) -> tuple[NDArray[np.bool_], int, int] | None:
    """Find the structure a still rope's outline runs round at one of its two `ends` (indices of `points`, (n, 2)
    row, col; a rope `width_px` wide, or a guess).

    The rope's free tip is the end from which its two sides walk together (`zip_sides`) farthest, a rope's width
    apart; they part where the rope leaves the structure. The structure is the rest of the outline, but what lies at
    the same place as a walked point (`SAME_PLACE_PX`: the rope's sides walked twice where the outline is a tree).

    Returns
    -------
    tuple[NDArray[np.bool_], int, int] | None
        Which points are the structure's, and the two points where the rope leaves it (indices); None when no
        rope leaves a structure cleanly (the sides never part, or part more than a rope's width apart, or the
        structure is smaller than a clamp: `STRUCTURE_AREA_WIDTHS`).
    """
    n = len(points)
    gap = max(12, math.ceil(3.0 * width_px + 4.0))
    if n < 4 * gap:
        return None
    # Most of the outline is the rope's two sides: the median across it, on a subsample, is their spacing.
    every = max(1, n // _SPACING_SAMPLES)
    spacing = float(np.median(across_distances(points, gap, every)))
    if not 0.5 * width_px <= spacing <= 2.0 * width_px:
        return None
    limit = ACROSS_WIDTHS * spacing + 1.0
    walks = [zip_sides(points, end, limit, 0.5 * spacing) for end in ends]
    k = 0 if walks[0][0] + walks[0][1] >= walks[1][0] + walks[1][1] else 1
    forward, backward, near_tip, near_structure = walks[k]
    if forward + backward < n // 4 or not 0.5 * spacing <= near_structure <= limit:
        return None  # no rope's two sides from that tip (a line walked out and back lies 0-1 px from itself)
    if near_structure > near_tip + WIDENING_PX:
        return None  # the band widens away from the tip: the fixed end of a swinging rope, not its free tip
    tip = ends[k]
    exit_a, exit_b = (tip + forward) % n, (tip - backward) % n
    if math.hypot(*(points[exit_a] - points[exit_b])) > EXIT_WIDTHS * spacing + 2.0:
        return None
    rope = np.zeros(n, bool)
    rope[(tip + np.arange(-backward, forward + 1)) % n] = True
    if rope.all():
        return None  # the rope's outline all round: no structure
    structure = ~rope
    walked = points[rope]
    exit_mid, along = _exit_axis(points, exit_a, exit_b, min(gap, forward, backward))
    candidates = np.flatnonzero(structure)
    for start in range(0, len(candidates), _BLOCK):
        block = candidates[start : start + _BLOCK]
        d2 = ((points[block, None, :] - walked[None, :, :]) ** 2).sum(axis=2).min(axis=1)
        # A point beyond the exits, within a width of the rope's sides, is the rope's band walked again: a short
        # edge across the band (an MJPEG block's step in the rope's brightness) closes a loop of the rope's sides
        # that the trace runs round, and its middle lies over SAME_PLACE_PX from both sides (simulated lab-mjpeg,
        # tuning seed, frame 0: a point 52 px along the rope put the region over the rope's first 52 px).
        inside = (d2 <= spacing * spacing) & ((points[block] - exit_mid) @ along > SAME_PLACE_PX)
        structure[block] = (d2 >= SAME_PLACE_PX**2) & ~inside
    if not structure.any():
        return None
    hull = convex_hull(np.concatenate([points[structure], points[[exit_a, exit_b]]]))
    rows, cols = hull[:, 0], hull[:, 1]
    area = 0.5 * abs(float(np.dot(rows, np.roll(cols, -1)) - np.dot(cols, np.roll(rows, -1))))
    if area < STRUCTURE_AREA_WIDTHS * spacing**2:
        return None
    extent = float(np.max(np.hypot(*(hull[:, None, :] - hull[None, :, :]).transpose(2, 0, 1))))
    if extent > STRUCTURE_ROPE_RATIO * 0.5 * (forward + backward):
        return None  # no small structure at a rope's end: the far part of a swinging rope's band, wider than a rope
    return structure, exit_a, exit_b


def _exit_axis(
    points: NDArray[np.float64], exit_a: int, exit_b: int, steps: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return the middle of the rope's exit (the points `exit_a` and `exit_b` of the outline `points`, where the
    rope's sides, walked from its tip, part: `zip_sides`) and the unit vector from it along the rope, towards the
    middle of the sides `steps` points back along each walk (at least 1)."""
    n = len(points)
    middle = 0.5 * (points[exit_a] + points[exit_b])
    back = max(1, steps)
    along = 0.5 * (points[(exit_a - back) % n] + points[(exit_b + back) % n]) - middle
    norm = math.hypot(float(along[0]), float(along[1]))
    return middle, (along / norm if norm > 0.0 else along)


def convex_hull(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the convex hull of `points` ((m, 2)) as its corners in order (Andrew's monotone chain)."""
    unique = np.unique(points, axis=0)
    if len(unique) < 3:
        return unique

    def half(order: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        chain: list[NDArray[np.float64]] = []
        for p in order:
            while len(chain) >= 2:
                (r0, c0), (r1, c1) = chain[-2], chain[-1]
                if (r1 - r0) * (p[1] - c0) - (c1 - c0) * (p[0] - r0) > 0:
                    break
                chain.pop()
            chain.append(p)
        return chain

    lower, upper = half(unique), half(unique[::-1])
    return np.array(lower[:-1] + upper[:-1])


def fill_polygon(polygon: NDArray[np.float64], shape: tuple[int, int]) -> NDArray[np.bool_]:
    """Return the pixels of an image of `shape` (height, width) whose centres lie inside the closed `polygon`
    ((m, 2) row, col; even-odd rule: a part walked out and back encloses nothing)."""
    height, width = shape
    region = np.zeros(shape, bool)
    r0 = max(math.ceil(float(polygon[:, 0].min())), 0)
    r1 = min(math.floor(float(polygon[:, 0].max())), height - 1)
    if r1 < r0:
        return region
    y0, x0 = polygon[:, 0], polygon[:, 1]
    y1, x1 = np.roll(y0, -1), np.roll(x0, -1)
    for r in range(r0, r1 + 1):
        cross = ((y0 <= r) & (y1 > r)) | ((y1 <= r) & (y0 > r))
        if not cross.any():
            continue
        xs = np.sort(x0[cross] + (r - y0[cross]) * (x1[cross] - x0[cross]) / (y1[cross] - y0[cross]))
        for left, right in zip(xs[0::2], xs[1::2], strict=False):
            c0, c1 = max(math.ceil(left), 0), min(math.floor(right), width - 1)
            if c1 >= c0:
                region[r, c0 : c1 + 1] = True
    return region


def grow(region: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Return `region` grown over each pixel's 3x3 neighbourhood."""
    rows = region.copy()
    rows[1:, :] |= region[:-1, :]
    rows[:-1, :] |= region[1:, :]
    grown = rows.copy()
    grown[:, 1:] |= rows[:, :-1]
    grown[:, :-1] |= rows[:, 1:]
    return grown
