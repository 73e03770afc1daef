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

import numpy as np
from numba import boolean, float64, int32, int64, types

from ropecam.shared.jit import i4_1d, i4_1d_ro, kernel, u1_1d, u1_2d, u1_2d_ro

MASK_FREE: Final = 0
"""Mask value: edges kept."""
MASK_ALWAYS: Final = 1
"""Mask value: edges always dropped (a mask given by the user)."""
MASK_STATIC: Final = 2
"""Mask value: edges dropped while the neighbourhood's grey levels stay inside the learned range."""
_u1_1d_ro: Final = types.Array(types.uint8, 1, "C", readonly=True)
NEAR_BLOCK: Final = 64
"""Pixels of the flat mask (``row * width + col``) per block of its summary (`mark_near_blocks`): a cache line."""
_NEAR_SHIFT: Final = np.uint64(6)  # a flat index's block: ``index >> _NEAR_SHIFT`` (NEAR_BLOCK = 2**6)


def near_blocks(height: int, width: int) -> int:
    """The number of blocks of `mark_near_blocks`' summary of a `height` x `width` mask."""
    return (height * width + NEAR_BLOCK - 1) // NEAR_BLOCK


@kernel(int64(u1_2d_ro, u1_1d))
def mark_near_blocks(mask, out_near):
    """Summarise the mask for the per-frame kernels: ``out_near[b]`` 1 when a pixel of the flat mask's block `b`
    (pixels ``b * NEAR_BLOCK`` on, `near_blocks` of them) or one of its 8 neighbours is masked (not `MASK_FREE`),
    else 0. A pixel of a block marked 0 is free and has no masked neighbour: `drop_static_edges` keeps it and
    `seal_cut_ends` takes it for no cut end without reading the mask (most of a steady frame's edge pixels: the
    mask is mostly free, and its lines are cold). Neighbours are taken on the flat array (a row's last pixel next
    to the next row's first), which only marks more blocks. Whoever writes the mask marks its blocks again.
    Returns the blocks marked 1, or -1 when `out_near` is shorter than `near_blocks`."""
    height = mask.shape[0]
    width = mask.shape[1]
    total = height * width
    blocks = (total + NEAR_BLOCK - 1) // NEAR_BLOCK
    if out_near.shape[0] < blocks:
        return -1
    flat = mask.reshape(total)
    marked = 0
    for b in range(blocks):
        first = b * NEAR_BLOCK
        last = min(first + NEAR_BLOCK, total) - 1
        hit = np.uint8(0)
        for row in range(-1, 2):
            shift = row * width
            for k in range(max(first + shift - 1, 0), min(last + shift + 1, total - 1) + 1):
                hit |= flat[k]
        out_near[b] = 1 if hit != 0 else 0
        marked += 1 if hit != 0 else 0
    return marked


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


# The frame read-only (a mapped capture buffer) or writable (a frame a reader made, through Numba's safe
# conversion), as `detect_and_trace`.
@kernel(int32(u1_2d_ro, u1_2d_ro, u1_2d_ro, u1_2d_ro, _u1_1d_ro, u1_2d, i4_1d, int64))
def drop_static_edges(frame, mask, low, high, near, edges, edge_list, n_edges):
    """Drop the listed edge pixels (flat indices ``row * width + col``, the first `n_edges` of `edge_list`) that
    the mask excludes: `MASK_ALWAYS` pixels, and `MASK_STATIC` pixels whose 3x3 neighbourhood (inside the image)
    lies inside the learned range [`low`, `high`] at every pixel. Clears `edges` at the dropped pixels and
    compacts `edge_list` in its order; returns the edge pixels kept. When `mask` is not of the frame's shape (a
    1x1 placeholder: no mask) nothing is dropped. `near` is the mask's summary (`mark_near_blocks`): the mask is
    read only in its blocks marked 1 (`near` shorter than `near_blocks`: everywhere)."""
    height = frame.shape[0]
    width = frame.shape[1]
    if mask.shape[0] != height or mask.shape[1] != width:
        return int32(n_edges)
    if low.shape[0] != height or low.shape[1] != width or high.shape[0] != height or high.shape[1] != width:
        return int32(n_edges)
    # The mask's code first, by the flat index (most edge pixels are free): the row and column (an integer
    # division, ~40 cycles) only for a masked pixel.
    codes = mask.reshape(height * width)
    summary = near.shape[0] >= (height * width + NEAR_BLOCK - 1) // NEAR_BLOCK
    kept = 0
    for t in range(n_edges):
        k = edge_list[t]
        if summary and near[np.uint64(k) >> _NEAR_SHIFT] == 0:  # free, as its block
            edge_list[kept] = k
            kept += 1
            continue
        code = codes[np.uint64(k)]
        drop = code == MASK_ALWAYS
        if code == MASK_STATIC:
            r = k // width
            c = k - r * width
            drop = True
            for rr in range(max(r - 1, 0), min(r + 2, height)):
                for cc in range(max(c - 1, 0), min(c + 2, width)):
                    v = frame[rr, cc]
                    if v < low[rr, cc] or v > high[rr, cc]:
                        drop = False
        if drop:
            r = k // width
            edges[r, k - r * width] = 0
        else:
            edge_list[kept] = k
            kept += 1
    return int32(kept)


SEAL_REACH_PX: Final = 6
"""How far apart (px, per axis) two cut ends may lie to be sealed: a rope's two sides where it leaves a clamp are
a rope width (up to about 4 px) plus a pixel or two apart. A larger reach also seals the stub of a rod (7 px and
wider) below its mask into a cap wider than the rope's, which the fixed-end guess then takes for the free end."""
_CUT: Final = 3  # an edge pixel marked as a cut end while the ends are paired (edges are 1 otherwise)


@kernel(boolean(u1_2d, int64, int64, int64))
def ends_line(edges, r, c, value):
    """Whether the edge pixel (`r`, `c`) (not on the image border) ends a line of `edges`' pixels of `value` (0:
    of any nonzero value): it has one such neighbour, or two that touch each other."""
    count = 0
    first_r = 0
    first_c = 0
    touching = True
    for dr in range(-1, 2):
        for dc in range(-1, 2):
            v = edges[r + dr, c + dc]
            if (dr != 0 or dc != 0) and v != 0 and (value == 0 or v == value):
                count += 1
                if count == 1:
                    first_r = dr
                    first_c = dc
                elif abs(dr - first_r) > 1 or abs(dc - first_c) > 1:
                    touching = False
    return count == 1 or (count == 2 and touching)


@kernel(boolean(u1_2d, u1_2d_ro, int64, int64))
def is_cut_end(edges, mask, r, c):
    """Whether the edge pixel (`r`, `c`) (not on the image border) ends a line where the mask cut it: it ends a
    line (`ends_line`) and has a masked neighbour."""
    for dr in range(-1, 2):
        for dc in range(-1, 2):
            if (dr != 0 or dc != 0) and mask[r + dr, c + dc] != MASK_FREE:
                return ends_line(edges, r, c, np.int64(0))
    return False


@kernel(int64(u1_2d, int64, int64, int64))
def nearest_cut_end(edges, r, c, reach):
    """Flat index of the cut end (marked `_CUT` in `edges`) nearest (`r`, `c`) within `reach` px per axis and at
    least 2 px away (a line's own neighbouring pixel is not another end), or -1."""
    height = edges.shape[0]
    width = edges.shape[1]
    best = np.int64(-1)
    best_d = np.int64(4 * reach * reach + 1)
    for rr in range(max(r - reach, 1), min(r + reach + 1, height - 1)):
        for cc in range(max(c - reach, 1), min(c + reach + 1, width - 1)):
            if edges[rr, cc] != _CUT:
                continue
            d = (rr - r) * (rr - r) + (cc - c) * (cc - c)
            if d >= 4 and d < best_d:
                best_d = d
                best = np.int64(rr) * width + cc
    return best


@kernel(int64(u1_2d_ro, _u1_1d_ro, i4_1d_ro, i4_1d_ro, u1_2d, i4_1d, int64))
def seal_cut_ends(mask, near, lo, hi, edges, edge_list, n_edges):
    """Join the ends of edge lines that the mask cut, in pairs, with a straight line of edge pixels (after
    `drop_static_edges`).

    Where a rope leaves a clamp whose outline the mask dropped, its two sides end at the mask: the rope's outline
    is open there (and, with its free end blurred open too, falls apart into its two sides). A cut end
    (`is_cut_end`) is joined to the nearest other cut end within `SEAL_REACH_PX` when each is the other's nearest:
    the outline is closed across the clamp's exit as a fixed-end cap would close it. The line's pixels inside the
    spans `lo`/`hi` and off the image border are set in `edges` and appended to `edge_list` (the first `n_edges`
    are the kept edge pixels, flat ``row * width + col``). `near` is the mask's summary (`mark_near_blocks`): a
    pixel of a block marked 0 has no masked neighbour, so no cut end (`near` shorter than `near_blocks`: every
    pixel tested). Returns the new edge count; `n_edges` when `mask` is not of the frame's shape (no mask) or
    `edge_list` is full."""
    height = edges.shape[0]
    width = edges.shape[1]
    if mask.shape[0] != height or mask.shape[1] != width:
        return n_edges
    # Flat access (`flat[k]`), the row and column (an integer division) only where needed: a cut end has one
    # edge neighbour or two (`is_cut_end`), so the neighbours are counted first and only such pixels tested
    # (a contour's pixels have two apart, or more: the same ends, at a fraction of the work).
    flat = edges.reshape(height * width)
    inner_first = width + 1  # the flat range whose 8 neighbours lie inside the map (rows 1 .. height - 2)
    inner_end = (height - 1) * width - 1
    summary = near.shape[0] >= (height * width + NEAR_BLOCK - 1) // NEAR_BLOCK
    cuts = 0
    for t in range(n_edges):
        k = np.int64(edge_list[t])
        if k < inner_first or k >= inner_end:
            continue  # on the first or last row (or next to them): not tested
        u = np.uint64(k)
        if summary and near[u >> _NEAR_SHIFT] == 0:
            continue  # no masked neighbour
        w = np.uint64(width)
        around = (
            np.int64(flat[u - w - 1] != 0) + np.int64(flat[u - w] != 0) + np.int64(flat[u - w + 1] != 0)
            + np.int64(flat[u - 1] != 0) + np.int64(flat[u + 1] != 0)
            + np.int64(flat[u + w - 1] != 0) + np.int64(flat[u + w] != 0) + np.int64(flat[u + w + 1] != 0)
        )  # fmt: skip
        if around == 0 or around > 2:
            continue
        r = k // width
        c = k - r * width
        if r < 1 or r > height - 2 or c < 1 or c > width - 2:
            continue
        if is_cut_end(edges, mask, r, c):
            flat[u] = _CUT
            cuts += 1
    if cuts < 2:
        for t in range(n_edges if cuts > 0 else 0):
            u = np.uint64(edge_list[t])
            if flat[u] == _CUT:
                flat[u] = 1
        return n_edges
    count = n_edges
    reach = np.int64(SEAL_REACH_PX)
    for t in range(n_edges):
        k = np.int64(edge_list[t])
        if flat[np.uint64(k)] != _CUT:
            continue
        r = k // width
        c = k - r * width
        other = nearest_cut_end(edges, r, c, reach)
        if other <= k or nearest_cut_end(edges, other // width, other - other // width * width, reach) != k:
            continue  # each pair once (from its smaller index), and only mutual nearest ends
        r2 = other // width
        c2 = other - r2 * width
        steps = max(abs(r2 - r), abs(c2 - c))
        for s in range(1, steps):
            rr = r + (r2 - r) * s / steps
            cc = c + (c2 - c) * s / steps
            pr = np.int64(np.floor(rr + 0.5))
            pc = np.int64(np.floor(cc + 0.5))
            if pr < 1 or pr > height - 2 or pc < 1 or pc > width - 2 or pc < lo[pr] or pc > hi[pr]:
                continue
            if edges[pr, pc] != 0 or count >= edge_list.shape[0]:
                continue
            edges[pr, pc] = 1
            edge_list[count] = np.int32(pr * width + pc)
            count += 1
    for t in range(n_edges):
        u = np.uint64(edge_list[t])
        if flat[u] == _CUT:
            flat[u] = 1
    return count
