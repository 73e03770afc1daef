"""Kernel of the outline check: a blurred band's outer contour visits each of its pixels once; a contour that walks
pixels twice went out along a spur and back, i.e. the band's edge is broken (a faint far side on a textured plate)
and the contour is a tree walk, not the outline the split reads the two shapes from."""

from __future__ import annotations

from typing import Final

from numba import int32, int64, uint8

from ropecam.shared.jit import i4_2d_ro, kernel, u1_2d

BROKEN_OUTLINE: Final = 0.15
"""Largest part of the contour's pixels walked twice (spurs of noise and texture) before it is no band outline."""
JOINED_REVISITS: Final = 0.05
"""Largest part of the contour's pixels walked twice once an open outline's two ends are joined
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
