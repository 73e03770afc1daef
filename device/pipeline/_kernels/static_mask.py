"""Kernels of the static mask: what does not move in the view (clamp, rod, plate edge, brackets, scratches, dust)
is learned over the first frames as each pixel's range of grey levels, and its edges are dropped before the rope's
component is chosen.

A pixel of the mask is `MASK_ALWAYS` (given by the user: its edges are never the rope's) or `MASK_STATIC`
(learned: its edges are dropped only while the frame's 3x3 neighbourhood stays inside the grey levels learned
there, so that the rope's own edges survive where it crosses a static structure: the rope changes the grey
levels, the structure alone does not).
"""

from __future__ import annotations

from typing import Final

from numba import float64, int32, int64

from ropecam.shared.jit import i4_1d, kernel, u1_2d, u1_2d_ro

MASK_FREE: Final = 0
"""Mask value: edges kept."""
MASK_ALWAYS: Final = 1
"""Mask value: edges always dropped (a mask given by the user)."""
MASK_STATIC: Final = 2
"""Mask value: edges dropped while the neighbourhood's grey levels stay inside the learned range."""


@kernel(int64(u1_2d_ro, u1_2d, u1_2d))
def learn_static_range(frame, out_low, out_high):
    """Widen each pixel's learned grey-level range [`out_low`, `out_high`] to include `frame` (all three of one
    shape; start from low 255 and high 0). Writes `out_low`, `out_high`; returns the pixels visited, or -1 when
    the shapes differ."""
    height = frame.shape[0]
    width = frame.shape[1]
    if out_low.shape[0] != height or out_low.shape[1] != width:
        return -1
    if out_high.shape[0] != height or out_high.shape[1] != width:
        return -1
    for r in range(height):
        for c in range(width):
            v = frame[r, c]
            if v < out_low[r, c]:
                out_low[r, c] = v
            if v > out_high[r, c]:
                out_high[r, c] = v
    return int64(height) * width


@kernel(int64(u1_2d, u1_2d, float64, float64, int32, u1_2d))
def mark_static(low, high, base_dn, relative, margin_dn, out_mask):
    """Mark as `MASK_STATIC` in `out_mask` the pixels whose learned range ``high - low`` is at most
    ``base_dn + relative * high`` (noise and flicker: the grey levels of a pixel the rope crossed span the rope's
    contrast), keeping `MASK_ALWAYS` pixels; then widen every learned range by `margin_dn` (saturating) so that
    the per-frame test allows for noise beyond what the learning frames showed. Writes `out_mask`, `low`,
    `high`; returns the number of static pixels, or -1 when the shapes differ."""
    height = low.shape[0]
    width = low.shape[1]
    if high.shape[0] != height or high.shape[1] != width:
        return -1
    if out_mask.shape[0] != height or out_mask.shape[1] != width:
        return -1
    count = 0
    for r in range(height):
        for c in range(width):
            lo = int32(low[r, c])
            hi = int32(high[r, c])
            if out_mask[r, c] != MASK_ALWAYS:
                if hi >= lo and hi - lo <= base_dn + relative * hi:
                    out_mask[r, c] = MASK_STATIC
                    count += 1
                else:
                    out_mask[r, c] = MASK_FREE
            low[r, c] = max(lo - margin_dn, 0)
            high[r, c] = min(hi + margin_dn, 255)
    return count


# The frame read-only (a mapped capture buffer) or writable (a frame a reader made), as `detect_and_trace`.
@kernel([int32(frame, u1_2d_ro, u1_2d_ro, u1_2d_ro, u1_2d, i4_1d, int64) for frame in (u1_2d_ro, u1_2d)])
def drop_static_edges(frame, mask, low, high, edges, edge_list, n_edges):
    """Drop the listed edge pixels (flat indices ``row * width + col``, the first `n_edges` of `edge_list`) that
    the mask excludes: `MASK_ALWAYS` pixels, and `MASK_STATIC` pixels whose 3x3 neighbourhood (inside the image)
    lies inside the learned range [`low`, `high`] at every pixel. Clears `edges` at the dropped pixels and
    compacts `edge_list` in its order; returns the edge pixels kept. When `mask` is not of the frame's shape (a
    1x1 placeholder: no mask) nothing is dropped."""
    height = frame.shape[0]
    width = frame.shape[1]
    if mask.shape[0] != height or mask.shape[1] != width:
        return int32(n_edges)
    if low.shape[0] != height or low.shape[1] != width or high.shape[0] != height or high.shape[1] != width:
        return int32(n_edges)
    kept = 0
    for t in range(n_edges):
        k = edge_list[t]
        r = k // width
        c = k - r * width
        code = mask[r, c]
        drop = code == MASK_ALWAYS
        if code == MASK_STATIC:
            drop = True
            for rr in range(max(r - 1, 0), min(r + 2, height)):
                for cc in range(max(c - 1, 0), min(c + 2, width)):
                    v = frame[rr, cc]
                    if v < low[rr, cc] or v > high[rr, cc]:
                        drop = False
        if drop:
            edges[r, c] = 0
        else:
            edge_list[kept] = k
            kept += 1
    return int32(kept)
