"""The outline check: a contour that walks its pixels twice is no band outline (`count_revisits`)."""

from __future__ import annotations

import numpy as np

from ropecam.device.pipeline import _kernels as K


def _chain(pixels: list[tuple[int, int]]) -> np.ndarray:
    out = np.array(pixels, np.int32)
    out.flags.writeable = False
    return out


def test_a_loop_walks_each_pixel_once_and_a_spur_twice() -> None:
    edges = np.zeros((12, 12), np.uint8)
    loop = [(2, c) for c in range(2, 9)] + [(r, 8) for r in range(3, 6)] + [(5, c) for c in range(7, 1, -1)]
    loop += [(r, 2) for r in range(4, 2, -1)] + [(2, 2)]  # closed on its first pixel
    for r, c in loop:
        edges[r, c] = 1
    before = edges.copy()
    assert K.count_revisits(_chain(loop), np.int32(len(loop)), edges) == 0
    # the same edge pixels walked out along a spur and back (a broken band's tree walk)
    spur = [(2, c) for c in range(2, 9)] + [(2, c) for c in range(7, 1, -1)]
    assert K.count_revisits(_chain(spur), np.int32(len(spur)), edges) == 5  # (2, 3)..(2, 7); (2, 2) closes it
    np.testing.assert_array_equal(edges, before)  # the marks are cleared
    assert K.count_revisits(_chain([(2, 2), (20, 3)]), np.int32(2), edges) == -1
    np.testing.assert_array_equal(edges, before)
