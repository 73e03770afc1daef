"""Kernel for an open outline: the rope's edges cut where a static mask (a clamp, its rod) drops them.

A rope's edge component is normally a closed ring (both sides joined by the end caps), and its Moore trace visits
each pixel once. Where the mask drops the clamp's outline, the rope's two sides end at the mask: the component is
an open curve (a U from one side's cut end round the free tip to the other side's), and the trace walks it out and
back, each pixel twice. `keep_open_once` keeps the walk once, from one cut end to the other, so that the chain is a
ring again whose closing step (the cut, about a rope width) lies at the clamp, as a fixed-end cap would.
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numba import boolean, int32, int64, types

from ropecam.device.pipeline._kernels.groups import CONTOUR
from ropecam.device.pipeline._kernels.revisits import JOINED_REVISITS, count_revisits
from ropecam.device.pipeline._kernels.static_mask import MASK_FREE, ends_line
from ropecam.shared.jit import i4_1d, i4_1d_ro, i4_2d, kernel, u1_2d, u1_2d_ro

OPEN_RATIO: Final = 1.6
"""A chain at least this many times longer than its component's pixel count was walked out and back (an open
curve: about 2; a closed ring with a few one-pixel spurs: a little over 1)."""


@kernel(boolean(i4_2d, int32, int32))
def turns_back(chain, n, i):
    """Whether the walk `chain` (n points, a ring) comes back the way it went at point `i`: the points one and
    two steps before and after it are at most one pixel apart (the end of a one-pixel line; of a line two pixels
    thick at its end, where the walk returns on the neighbouring pixel). A corner of a closed outline turns by
    90 degrees at most per pixel: its points two steps away are two pixels apart."""
    for k in (1, 2):
        p = (i - k) % n
        q = (i + k) % n
        if abs(chain[p, 0] - chain[q, 0]) > 1 or abs(chain[p, 1] - chain[q, 1]) > 1:
            return False
    return True


@kernel(int32(i4_2d, i4_1d, int32, int32))
def keep_open_once(chain, codes, n, size):
    """Keep an out-and-back walk of an open edge curve once, in place.

    `chain` (n, 2) row, col and `codes` (n) are a Moore trace of an 8-connected component of `size` pixels. When
    the chain is at least `OPEN_RATIO` x `size` long (the component is an open curve, walked out and back), its
    turnarounds (`turns_back`: the curve's ends, and the tips of one-pixel spurs) are paired: the pair whose walk
    between them is nearest half the chain are the curve's two ends, and the walk from the first to the second
    is moved to the chain's start. Writes `chain` and `codes`; returns the new count, or `n` unchanged (a closed
    outline, or no such pair within an eighth of the chain of the half).
    """
    if n < 8 or not n >= OPEN_RATIO * size:
        return n
    half = n // 2
    best = n // 8 + 1
    best_i = -1
    best_j = -1
    for i in range(n):
        if not turns_back(chain, n, i):
            continue
        for j in range(i + 1, n):
            d = abs(j - i - half)
            if d < best and turns_back(chain, n, j):
                best = d
                best_i = i
                best_j = j
    if best_i < 0:
        return n
    m = best_j - best_i + 1
    for k in range(m):  # forward: a point is read before it is overwritten
        chain[k, 0] = chain[best_i + k, 0]
        chain[k, 1] = chain[best_i + k, 1]
        codes[k] = codes[best_i + k]
    return int32(m)


@kernel(boolean(u1_2d_ro, i4_2d, int32))
def touches_mask(mask, chain, n):
    """Whether a point of the first `n` of `chain` (row, col) has a masked 8-neighbour (`mask` not `MASK_FREE`);
    False for a mask of another size than the image's (a 1x1 placeholder: no mask)."""
    height = mask.shape[0]
    width = mask.shape[1]
    for k in range(n):
        r = chain[k, 0]
        c = chain[k, 1]
        for rr in range(max(r - 1, 0), min(r + 2, height)):
            for cc in range(max(c - 1, 0), min(c + 2, width)):
                if mask[rr, cc] != MASK_FREE:
                    return True
    return False


JOIN_REACH_PX: Final = 8
"""How far apart (px, per axis) the two ends of a band's outline that is open at one end may lie to be joined
(`pick_open_ends`): a blurred band's far end is a ramp where its tip moves along the rope's axis, too faint for an
edge, and its two sides end there a rope width (2-2.5 px on the simulated lab presets) plus a pixel apart, or up to
7 px where the tip also sweeps sideways (simulated `lab late swing` frame 39, `lab` 240 frames frame 158). 4 px
left those two frames `LOST_TRACK`; 8 px measured no other row changed but plate edge 0.7 (one more frame
measured, flagged or within 3 px; docs/robustness.md)."""


@kernel(types.UniTuple(int64, 2)(u1_2d, i4_2d, int32, int64, i4_1d))
def pick_open_ends(edges, chain, n, reach, scratch):
    """The two ends of an outline walked out and back along a curve open at one end (a band whose far end has no
    edge): of the chain's points that end a line of the component (`ends_line` of value 1), the pair within `reach` px
    (per axis) of each other whose walk between them is longest the shorter way round the chain and at least a
    quarter of it (its two ends, about half the chain apart; not a spur's tip and a side). `chain` (n points, row
    and col) is the component's trace in `edges` (1 on its pixels); `scratch` holds the line ends' chain indices
    (as many as it has slots). Returns the two chain indices, smaller first, or (-1, -1) when no such pair."""
    height = edges.shape[0]
    width = edges.shape[1]
    ends = 0
    for i in range(n):
        r = np.int64(chain[i, 0])
        c = np.int64(chain[i, 1])
        if r < 1 or c < 1 or r > height - 2 or c > width - 2 or ends >= scratch.shape[0]:
            continue
        if ends_line(edges, r, c, np.int64(1)):
            scratch[ends] = i
            ends += 1
    best = -1
    best_i = np.int64(-1)
    best_j = np.int64(-1)
    for a in range(ends):
        i = np.int64(scratch[a])
        for b in range(a + 1, ends):
            j = np.int64(scratch[b])
            if abs(chain[j, 0] - chain[i, 0]) > reach or abs(chain[j, 1] - chain[i, 1]) > reach:
                continue
            walk = min(j - i, n - (j - i))
            if walk > best and 4 * walk >= n:
                best = walk
                best_i = i
                best_j = j
    return best_i, best_j


@kernel(types.UniTuple(int64, 2)(u1_2d, i4_1d_ro, i4_1d_ro, int64, int64, int64))
def draw_join(edges, lo, hi, a, b, undo):
    """Join the flat pixels `a` and `b` (``row * width + col``) of the traced component with a straight line of
    its pixels (value 1 in `edges`), inside the spans `lo`/`hi` and off the image border, as `seal_cut_ends`
    draws; or, with `undo` >= 0 (what the drawing returned), put back what it changed. Returns what changed (bit
    ``2 s`` of the line's step `s`: set to 1; bit ``2 s + 1``: it was another component's, 2) and the first
    pixel set in raster order (the flat index; -1: none)."""
    height = edges.shape[0]
    width = edges.shape[1]
    r = a // width
    c = a - r * width
    r2 = b // width
    c2 = b - r2 * width
    steps = max(abs(r2 - r), abs(c2 - c))
    changed = np.int64(0)
    first = np.int64(-1)
    for s in range(1, min(steps, 31)):
        pr = np.int64(np.floor(r + (r2 - r) * s / steps + 0.5))
        pc = np.int64(np.floor(c + (c2 - c) * s / steps + 0.5))
        if undo >= 0:
            if (undo >> (2 * s)) & 1:
                edges[pr, pc] = 2 if (undo >> (2 * s + 1)) & 1 else 0
            continue
        if pr < 1 or pr > height - 2 or pc < 1 or pc > width - 2 or pc < lo[pr] or pc > hi[pr]:
            continue
        v = edges[pr, pc]
        if v == 1:
            continue
        changed |= np.int64(1) << (2 * s)
        if v == 2:
            changed |= np.int64(1) << (2 * s + 1)
        edges[pr, pc] = 1
        k = pr * width + pc
        first = k if first < 0 else min(first, k)
    return changed, first


@kernel(int64(int64))
def joined_pixels(changed):
    """The pixels `draw_join` set, from what it returned."""
    count = 0
    while changed != 0:
        count += changed & 1
        changed >>= 2
    return count


@kernel(types.UniTuple(int64, 4)(u1_2d, i4_1d_ro, i4_1d_ro, u1_2d_ro, int32, CONTOUR))
def join_open_ends(edges, lo, hi, static_mask, n, contour):
    """Join the two ends of a band's outline that is open at one end, in the edge map.

    The traced component (1 in `edges`; its `n`-point chain, start and size ``counts[0]`` in `contour`) is
    walked out and back along a curve when the band's far end has no edge (a blurred tip moving along the rope's
    axis: a ramp too faint for an edge; simulated `lab`, tuning seed, 240 frames, frame 90: the sides end 2.5 px
    apart), and the outline check then finds more than `BROKEN_OUTLINE` of the chain's pixels walked twice; where
    the sides are two pixels thick along most of their length the walks out and back take different pixels and
    fewer are walked twice (simulated `plate edge = 0.7`, tuning seed, frame 27: 14.5 %, the band's side cut by the
    plate's masked bevel). Such a chain (longer than the component, more than `JOINED_REVISITS` of its pixels
    walked twice: the walk comes back) that touches `static_mask` (its other end sealed at the
    clamp, `seal_cut_ends`; a learned mask is empty while it is learned, and a still rope's outline open at its
    clamp then is what the clamp's search reads, `structure_points`) has its two ends (`pick_open_ends`, within
    `JOIN_REACH_PX`; ``contour.stack`` as scratch) joined by a line of the component's pixels (`draw_join`), as a
    cap would close it. Returns the two ends (flat ``row * width + col``), what `draw_join` changed (0: nothing
    joined, the map as it was) and the joined component's first pixel in raster order (where to trace it from)."""
    chain = contour.chain
    none = (np.int64(-1), np.int64(-1), np.int64(0), np.int64(-1))
    if n <= contour.counts[0] or count_revisits(chain, n, edges) <= JOINED_REVISITS * n:
        return none
    if not touches_mask(static_mask, chain, n):
        return none
    i, j = pick_open_ends(edges, chain, n, np.int64(JOIN_REACH_PX), contour.stack)
    if i < 0:
        return none
    width = edges.shape[1]
    a = np.int64(chain[i, 0]) * width + chain[i, 1]
    b = np.int64(chain[j, 0]) * width + chain[j, 1]
    changed, first = draw_join(edges, lo, hi, a, b, np.int64(-1))
    if changed == 0:
        return none
    return a, b, changed, min(np.int64(contour.start[0]) * width + contour.start[1], first)
