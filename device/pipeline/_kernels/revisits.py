"""Kernel of the outline check: a blurred band's outer contour visits each of its pixels once; a contour that walks
pixels twice went out along a spur and back, i.e. the band's edge is broken (a faint far side on a textured plate)
and the contour is a tree walk, not the outline the split reads the two shapes from."""

from __future__ import annotations

from typing import Final

import numpy as np
from numba import float64, int32, int64, uint8

from ropecam.shared.jit import i4_1d, i4_2d, i4_2d_ro, kernel, u1_2d

BROKEN_OUTLINE: Final = 0.15
"""Largest part of the contour's pixels walked twice (spurs of noise and texture) before it is no band outline."""
JOINED_REVISITS: Final = 0.05
"""Part of the contour's pixels walked twice above which an open outline's two ends are tried for a join
(`join_open_ends`, session 16: sides two pixels thick walk 5-15 % twice), and the largest part once they are joined
(`close_open_outline`): the join made a ring, with a few spurs."""
VISITED: Final = 0x80
"""Bit of the edge map that marks a pixel the contour has walked (cleared again before returning)."""


@kernel(int64(i4_2d_ro, int32, u1_2d))
def count_revisits(chain, n, edges):
    """Return how many of the first `n` chain pixels (int32 row, col) the contour had walked already (the pixel
    it starts and closes on counts once). `edges` is the edge map the chain was traced on: bit `VISITED` is set on
    each pixel walked and cleared again, so the map is left as it was. -1 for a pixel outside it."""
    height = edges.shape[0]
    width = edges.shape[1]
    mark = uint8(VISITED)
    keep = uint8(0x7F)
    for k in range(n):
        r = chain[k, 0]
        c = chain[k, 1]
        if r < 0 or r >= height or c < 0 or c >= width:
            return -1
    revisits = 0
    for k in range(n):
        r = chain[k, 0]
        c = chain[k, 1]
        if edges[r, c] & mark:
            revisits += 1
        else:
            edges[r, c] |= mark
    for k in range(n):
        edges[chain[k, 0], chain[k, 1]] &= keep
    if n > 1 and chain[n - 1, 0] == chain[0, 0] and chain[n - 1, 1] == chain[0, 1]:
        revisits -= 1  # the closing pixel
    return revisits


MAX_EXCURSION: Final = 64
"""Longest walk (chain points) from a pixel back to the same pixel that `prune_excursions` takes out: a spur of up
to 32 px walked out and back, or a small loop hung on the outline. Noise edges joined to a band's side make such
walks (simulated `read noise = 10 DN`, tuning seed, frame 26: a 28 px spur along a side next to the tip, whose
turnaround the split took for a corner). A broken band edge walked out and back is hundreds of points long: it
stays whole, with whatever hangs on it, for the outline check (`BROKEN_OUTLINE`)."""

EXCURSION_AREA_PX2: Final = 8.0
"""Area (px^2) a walk back may enclose beyond half a pixel per point to be taken out (`prune_excursions`): a spur
encloses none, a ring of noise a few pixels (frame 26 above: 4 px^2 in 28 points); a 12 px clamp's outline hung on
the rope's over 100."""


@kernel(float64(i4_2d, int64, int64))
def walk_area(chain, first, last):
    """The area (px^2, unsigned) the walk `chain[first : last + 1]` encloses, closed from its last point to its
    first (the shoelace formula): 0 for a spur walked out and back on the same pixels."""
    twice = 0.0
    for k in range(first, last + 1):
        j = k + 1 if k < last else first
        twice += float(chain[k, 1]) * float(chain[j, 0]) - float(chain[j, 1]) * float(chain[k, 0])
    return 0.5 * abs(twice)


@kernel(int32(i4_2d, i4_1d, int32, int64, i4_1d))
def prune_excursions(chain, codes, n, width, scratch):
    """Take out of a contour the walks that leave a pixel and come back to it within `MAX_EXCURSION` points, in
    place.

    `chain` (n, 2) row, col and `codes` (n) are a trace of an image `width` px wide. Each pixel's last visit is
    written into `scratch` (flat ``row * width + col``; its other slots are not read); from a pixel's first
    visit, a walk back to it within `MAX_EXCURSION` points that encloses at most `EXCURSION_AREA_PX2` plus half a
    pixel per point (a spur out and back, a small loop of noise hung on the outline at one pixel; `walk_area`) is
    dropped when the walk goes on elsewhere after it (the points before and after it more than a pixel apart: a
    branch off a line, not the far end of an arm walked out and back) and the pixel kept once, with the code of
    its last visit (a code is the step to the next point). A longer or wider walk back (a
    clamp's outline hung on the rope's before the mask is learned: `clamp size = 12 px` lost frames 0-10 when it
    was taken out) is kept whole, with the short ones inside it: a spur is not eaten from its tip.
    The last point is not taken for a revisit of the first (a trace closed on its start). A trace that starts
    inside a walk out and back (a pixel of its first `MAX_EXCURSION` points visited again within its last
    `MAX_EXCURSION`: an open curve or a tree walked from one of its arms; the ring's wrap hides the enclosing
    walk) is left whole. Returns the new count
    (`n` when no pixel is walked twice, or a pixel lies outside `scratch`: nothing taken out); the points and
    codes past it are left as they were.
    """
    if n < 8:
        return n
    size = scratch.shape[0]
    for k in range(n - 1):
        flat = np.int64(chain[k, 0]) * width + chain[k, 1]
        if flat < 0 or flat >= size:
            return n
        scratch[flat] = k
    for k in range(min(MAX_EXCURSION, n - 1)):
        last = np.int64(scratch[np.int64(chain[k, 0]) * width + chain[k, 1]])
        if last > k and last >= n - 1 - MAX_EXCURSION:
            return n  # the trace starts inside a walk out and back that ends with the chain: a tree walk, left whole
    kept = 0
    protect = -1
    k = 0
    while k < n:
        last = k
        if k < n - 1:
            last = np.int64(scratch[np.int64(chain[k, 0]) * width + chain[k, 1]])
        jump = k
        if last > k and k > protect:
            if (
                last - k <= MAX_EXCURSION
                and walk_area(chain, k, last) <= EXCURSION_AREA_PX2 + 0.5 * (last - k)
                and k > 0
                and last < n - 1
                and max(abs(chain[last + 1, 0] - chain[k - 1, 0]), abs(chain[last + 1, 1] - chain[k - 1, 1])) > 1
            ):
                jump = last
            else:
                protect = last
        if kept != k or jump != k:
            chain[kept, 0] = chain[k, 0]
            chain[kept, 1] = chain[k, 1]
            codes[kept] = codes[jump]
        kept += 1
        k = jump + 1
    return int32(kept)
