"""Where a traced contour touches the border of its region of interest or of the image (`count_roi_contacts`,
`count_border_contacts`)."""

from __future__ import annotations

import math

from numba import boolean, float32, int32, int64

from ropecam.shared.jit import i4_1d_ro, i4_2d_ro, kernel


@kernel(boolean(int64, int64, i4_1d_ro, i4_1d_ro, int64, int64))
def touches_roi_border(r, c, lo, hi, width, height):
    """Return whether pixel (r, c) has an 8-neighbour inside the `height` x `width` image but outside the row
    spans `lo`/`hi`."""
    left = c - 1
    right = c + 1
    cm = max(left, 0)
    cp = min(right, width - 1)
    # Row r: the two side neighbours; rows r - 1 and r + 1: the 1-3 neighbours form one interval.
    a = lo[r]
    b = hi[r]
    touches = (left >= 0 and (left < a or left > b)) or (right < width and (right < a or right > b))
    if r > 0 and (cm < lo[r - 1] or cp > hi[r - 1]):
        touches = True
    if r < height - 1 and (cm < lo[r + 1] or cp > hi[r + 1]):
        touches = True
    return touches


@kernel(boolean(int64, int64, int64, int64))
def on_image_border(r, c, height, width):
    """Return whether pixel (r, c) lies on the border of a `height` x `width` image."""
    return r == 0 or r == height - 1 or c == 0 or c == width - 1


@kernel(int32(i4_2d_ro, int32, i4_1d_ro, i4_1d_ro, int32))
def count_roi_contacts(chain, n, lo, hi, width):
    """Return how many of the first `n` chain pixels have an 8-neighbour inside the image but outside the row
    spans `lo`/`hi` (the contour reaches the border of the region of interest; `touches_roi_border`)."""
    height = lo.shape[0]
    count = 0
    for i in range(n):
        if touches_roi_border(chain[i, 0], chain[i, 1], lo, hi, width, height):
            count += 1
    return count


@kernel(int32(i4_2d_ro, int32, int32, int32, float32, float32, float32))
def count_border_contacts(chain, n, height, width, fixed_r, fixed_c, exclude_px):
    """Return how many of the first `n` chain pixels lie on the image border (row 0 or height - 1, column 0 or
    width - 1) farther than `exclude_px` from (fixed_r, fixed_c) (a rope hanging from the border is not leaving
    the image there)."""
    count = 0
    for i in range(n):
        r = chain[i, 0]
        c = chain[i, 1]
        if on_image_border(r, c, height, width) and math.hypot(r - fixed_r, c - fixed_c) > exclude_px:
            count += 1
    return count
