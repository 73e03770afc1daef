"""Kernel for an open outline: the rope's edges cut where a static mask (a clamp, its rod) drops them.

A rope's edge component is normally a closed ring (both sides joined by the end caps), and its Moore trace visits
each pixel once. Where the mask drops the clamp's outline, the rope's two sides end at the mask: the component is
an open curve (a U from one side's cut end round the free tip to the other side's), and the trace walks it out and
back, each pixel twice. `keep_open_once` keeps the walk once, from one cut end to the other, so that the chain is a
ring again whose closing step (the cut, about a rope width) lies at the clamp, as a fixed-end cap would.
"""

from __future__ import annotations

from typing import Final

from numba import boolean, int32

from ropecam.device.pipeline._kernels.static_mask import MASK_FREE
from ropecam.shared.jit import i4_1d, i4_2d, kernel, u1_2d_ro

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
