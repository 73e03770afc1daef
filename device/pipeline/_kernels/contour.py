"""Component selection and the closed contour: keep the largest edge component, trace its chain, count its
contacts with the ROI border."""

from __future__ import annotations

from typing import Final

import numba
import numpy as np
from numba import boolean, float64, int32, int64, types

from ropecam.device.pipeline._kernels._common import DIR_COL, DIR_ROW, FULL, NOT_FOUND
from ropecam.device.pipeline._kernels.contacts import count_border_contacts, count_roi_contacts
from ropecam.device.pipeline._kernels.geometry import refine_subpixel
from ropecam.device.pipeline._kernels.groups import CONTOUR
from ropecam.device.pipeline._kernels.outline import (
    OPEN_RATIO,
    draw_join,
    join_open_ends,
    joined_pixels,
    keep_open_once,
    touches_mask,
)
from ropecam.device.pipeline._kernels.revisits import JOINED_REVISITS, count_revisits, prune_excursions
from ropecam.device.pipeline._kernels.spans import in_spans
from ropecam.shared.jit import (
    f4_2d,
    f4_2d_ro,
    i4_1d,
    i4_1d_ro,
    i4_2d,
    kernel,
    u1_1d,
    u1_2d,
    u1_2d_ro,
)


@kernel(types.UniTuple(int64, 2)(u1_2d_ro, i4_1d_ro, i4_1d_ro, int64, int64, i4_2d, i4_1d))
def flood_labels(edges, lo, hi, seed, label, out_labels, stack):
    """Label with `label` the edge pixels (nonzero `edges`, inside the spans `lo`/`hi`, label 0 so far) joined
    8-connected to the flat pixel `seed` (``row * width + col``, labelled already), depth first through `stack`.

    Writes `out_labels` at them; returns their count and the smallest flat index among them (the component's
    first pixel in raster order)."""
    height = edges.shape[0]
    width = edges.shape[1]
    stack[0] = seed
    top = 1
    size = 0
    first = seed
    while top > 0:
        top -= 1
        here = np.int64(stack[top])
        first = min(first, here)
        size += 1
        pr = here // width
        pc = here - pr * width
        for k in range(8):
            rr = pr + DIR_ROW[k]
            cc = pc + DIR_COL[k]
            if rr < 0 or rr >= height or cc < lo[rr] or cc > hi[rr] or cc >= width:
                continue
            if edges[rr, cc] != 0 and out_labels[rr, cc] == 0:
                out_labels[rr, cc] = label
                stack[top] = rr * width + cc
                top += 1
    return size, first


@kernel(types.Tuple((int64, int64, boolean))(u1_1d, int64, int64, i4_1d, int64))
def flood_flat(edges, width, seed, stack, tail):
    """Flood breadth first, through the flat map `edges` (rows of `width`), the pixels of value 1 joined
    8-connected to the pixel `seed` (value 1; none of them on the image border): each is set to 3 and appended
    to `stack` from index `tail`, the seed first.

    Returns the new tail, the smallest flat index flooded (the component's first pixel in raster order) and
    whether a flooded pixel has a neighbour of value 2."""
    offsets = (-width - 1, -width, -width + 1, -1, 1, width - 1, width, width + 1)
    edges[seed] = 3
    stack[tail] = seed
    head = tail
    tail += 1
    first = seed
    touches = False
    while head < tail:
        here = np.int64(stack[head])
        head += 1
        first = min(first, here)
        for o in offsets:
            k = np.uint64(here + o)
            v = edges[k]
            if v == 1:
                edges[k] = 3
                stack[tail] = np.int32(k)
                tail += 1
            touches |= v == 2
    return tail, first, touches


@kernel(boolean(i4_1d_ro, i4_1d_ro, int64, int64))
def spans_off_border(lo, hi, height, width):
    """Return whether every non-empty span of the first `height` rows of `lo`/`hi` keeps off the border of a
    `height` x `width` image (not in its first or last row, within columns 1 .. width - 2)."""
    for r in range(height):
        if hi[r] >= lo[r] and (r == 0 or r == height - 1 or lo[r] < 1 or hi[r] > width - 2):
            return False
    return True


@kernel(int32(u1_2d, i4_1d_ro, i4_1d_ro, int32, i4_2d, i4_1d, i4_1d))
def keep_largest_component(edges, lo, hi, min_pixels, out_labels, stack, out_start):
    """Mark the largest 8-connected component of `edges` (nonzero = edge) inside the spans with 1, the others
    with 2 (they still count as edges for width measurements, but the contour follows only 1).

    Writes `out_labels` (component number + 1, 0 = background, valid inside the spans), rewrites `edges` and
    writes the component's first pixel in raster order into `out_start` (row, col). Returns the component's pixel
    count, or NOT_FOUND when no component has at least `min_pixels` pixels (then every edge is marked 2).
    """
    height = edges.shape[0]
    width = edges.shape[1]
    for r in range(height):
        c0 = np.int64(lo[r])
        c1 = min(np.int64(hi[r]), width - 1)
        if c1 >= c0:
            out_labels[r, c0 : c1 + 1] = 0
    label = 0
    best_label = 0
    best_size = 0
    for r in range(height):
        c0 = np.int64(lo[r])
        c1 = min(np.int64(hi[r]), width - 1)
        if c1 < c0:
            continue
        e_in = edges[r, c0 : c1 + 1]
        l_in = out_labels[r, c0 : c1 + 1]
        for i in range(e_in.shape[0]):
            if e_in[i] == 0 or l_in[i] != 0:
                continue
            c = c0 + i
            label += 1
            out_labels[r, c] = label
            size, _ = flood_labels(edges, lo, hi, r * width + c, label, out_labels, stack)
            if size > best_size:
                best_size = size
                best_label = label
                out_start[0] = r
                out_start[1] = c
    found = best_size >= min_pixels and best_size > 0
    keep = best_label if found else -1
    for r in range(height):
        c0 = np.int64(lo[r])
        c1 = min(np.int64(hi[r]), width - 1)
        if c1 < c0:
            continue
        e_in = edges[r, c0 : c1 + 1]
        l_in = out_labels[r, c0 : c1 + 1]
        for i in range(e_in.shape[0]):
            if e_in[i] != 0:
                e_in[i] = 1 if l_in[i] == keep else 2
    return best_size if found else NOT_FOUND


@kernel(int32(u1_1d, i4_1d_ro, int32, int32, int64, i4_1d, i4_1d))
def keep_largest_closed(edges, edge_list, n_edges, min_pixels, width, stack, out_start):
    """`keep_largest_listed` for a flat map `edges` (rows of `width`) holding 1 on the `n_edges` listed pixels
    and 0 on every other pixel next to them, none of them on the image border (as `detect_edges` leaves it).

    The components are flooded breadth first through the map itself (3 = visited), each one's pixels one after
    the other in `stack` (one slot per listed pixel); no label plane is needed. Rewrites the listed pixels (1 =
    the largest component, ties to the one first in raster order; 2 = the others), writes its first pixel in
    raster order into `out_start` (row, col) and returns its size, or NOT_FOUND when below `min_pixels`.
    """
    tail = 0
    best_size = 0
    best_first = 0
    best_begin = 0
    for t in range(n_edges):
        seed = edge_list[t]
        if edges[seed] != 1:
            continue
        begin = tail
        tail, first, _ = flood_flat(edges, width, seed, stack, tail)
        size = tail - begin
        if size > best_size or (size == best_size and first < best_first):
            best_size = size
            best_first = first
            best_begin = begin
    for t in range(n_edges):
        edges[edge_list[t]] = 2
    if best_size < min_pixels or best_size == 0:
        return NOT_FOUND
    for i in range(best_begin, best_begin + best_size):
        edges[stack[i]] = 1
    out_start[0] = best_first // width
    out_start[1] = best_first - (best_first // width) * width
    return best_size


@kernel(int32(u1_2d, i4_1d_ro, i4_1d_ro, i4_1d_ro, int32, int32, boolean, i4_2d, i4_1d, i4_1d))
def keep_largest_listed(edges, lo, hi, edge_list, n_edges, min_pixels, ring_clear, out_labels, stack, out_start):
    """`keep_largest_component` for an edge map whose edge pixels are listed: the first `n_edges` flat indices
    ``row * width + col`` of `edge_list`, in any order (as `detect_edges` leaves them). Same result (of equal
    components the one first in raster order wins, the start is the component's first pixel in raster order),
    in time proportional to the edges rather than to the pixels of the spans. `ring_clear`: the caller
    guarantees that the map is as `detect_edges` leaves it (1 on the listed pixels, 0 at every other pixel of
    the spans and next to them); then, when the spans keep off the image border, `keep_largest_closed` runs
    (no span or border tests, no labels).

    Writes `out_labels` at the listed pixels (not with `ring_clear`), rewrites `edges` there (1 = kept
    component, 2 = others) and `out_start`; returns the component's pixel count or NOT_FOUND.
    """
    height = edges.shape[0]
    width = edges.shape[1]
    labels = out_labels.reshape(height * width)
    flat_edges = edges.reshape(height * width)
    if ring_clear and spans_off_border(lo, hi, height, width):
        return keep_largest_closed(flat_edges, edge_list, n_edges, min_pixels, width, stack, out_start)
    for t in range(n_edges):
        labels[edge_list[t]] = 0
    label = 0
    best_label = 0
    best_size = 0
    best_first = 0
    for t in range(n_edges):
        seed = edge_list[t]
        if labels[seed] != 0:
            continue
        label += 1
        labels[seed] = label
        size, first = flood_labels(edges, lo, hi, seed, label, out_labels, stack)
        if size > best_size or (size == best_size and first < best_first):
            best_size = size
            best_label = label
            best_first = first
            out_start[0] = first // width
            out_start[1] = first - (first // width) * width
    found = best_size >= min_pixels and best_size > 0
    keep = best_label if found else -1
    for t in range(n_edges):
        k = edge_list[t]
        flat_edges[k] = 1 if labels[k] == keep else 2
    return best_size if found else NOT_FOUND


@kernel(int32(u1_2d_ro, i4_1d_ro, i4_1d_ro, int32, int32, i4_2d, i4_1d))
def trace_contour(edges, lo, hi, start_r, start_c, out_chain, out_codes):
    """Trace the outer boundary of the edge component containing (start_r, start_c), its first pixel in raster
    order, clockwise on screen (Moore-neighbour tracing; stops when the first move repeats).

    Writes the chain pixels (row, col) into `out_chain` and the Freeman code (0 = east, counter-clockwise on
    screen) of the move from each pixel to the next into `out_codes`. Returns the chain length or FULL.
    """
    capacity = out_chain.shape[0]
    if capacity < 1 or out_codes.shape[0] < capacity:
        return FULL
    width = edges.shape[1]
    pr = start_r
    pc = start_c
    b_idx = 4  # direction of the backtrack pixel seen from the current one: west of the start
    first_r = -1
    first_c = -1
    n = 0
    while True:
        found = -1
        for step in range(1, 9):
            k = (b_idx + step) & 7
            rr = pr + DIR_ROW[k]
            cc = pc + DIR_COL[k]
            if in_spans(rr, cc, lo, hi) and 0 <= cc < width and edges[rr, cc] == 1:
                found = k
                break
        if found < 0:
            out_chain[0, 0] = pr
            out_chain[0, 1] = pc
            out_codes[0] = 0
            return 1
        nr = pr + DIR_ROW[found]
        nc = pc + DIR_COL[found]
        if n == 0:
            first_r = nr
            first_c = nc
        elif pr == start_r and pc == start_c and nr == first_r and nc == first_c:
            return n
        if n >= capacity:
            return FULL
        out_chain[n, 0] = pr
        out_chain[n, 1] = pc
        out_codes[n] = (8 - found) & 7
        n += 1
        # The backtrack pixel is the neighbour checked before `found`, (found + 7) mod 8 from the old pixel;
        # seen from the new one it lies in direction N, N, E, E, S, S, W, W for found = E, SE, ..., NE.
        b_idx = ((found + 6) // 2 * 2) & 7
        pr = nr
        pc = nc


@kernel(int32(u1_1d, int64, int32, int32, i4_2d, i4_1d))
def trace_closed(edges, width, start_r, start_c, out_chain, out_codes):
    """`trace_contour` on a flat map `edges` (rows of `width`) whose traced component (value 1) has only
    pixels of the spans or 0 around it, none on the image border (as `keep_largest_closed` leaves it): no span
    or border test per neighbour. Same outputs and return value."""
    # A second copy of `trace_contour`'s walk, on purpose: the steady frame's trace runs here, and what this copy
    # leaves out is exactly the per-neighbour span and border tests (one load per neighbour instead of five
    # compares and two loads). A walk with the test as an argument would branch on it in the inner loop. Keep
    # the two in step: `test_trace_rope_equals_the_kernels_one_by_one` compares them on every kind of band.
    capacity = out_chain.shape[0]
    if capacity < 1 or out_codes.shape[0] < capacity:
        return FULL
    offsets = (1, width + 1, width, width - 1, -1, -width - 1, -width, -width + 1)  # E, SE, ..., NE
    start = np.int64(start_r) * width + start_c
    here = start
    pr = start_r
    pc = start_c
    b_idx = 4
    first = np.int64(-1)
    n = 0
    while True:
        found = -1
        for step in range(1, 9):
            k = (b_idx + step) & 7
            if edges[np.uint64(here + offsets[k])] == 1:
                found = k
                break
        if found < 0:
            out_chain[0, 0] = pr
            out_chain[0, 1] = pc
            out_codes[0] = 0
            return 1
        nxt = here + offsets[found]
        if n == 0:
            first = nxt
        elif here == start and nxt == first:
            return n
        if n >= capacity:
            return FULL
        out_chain[n, 0] = pr
        out_chain[n, 1] = pc
        out_codes[n] = (8 - found) & 7
        n += 1
        b_idx = ((found + 6) // 2 * 2) & 7
        here = nxt
        pr += DIR_ROW[found]
        pc += DIR_COL[found]


def _quotient(a, b):
    """Return ``a / b`` (inf or nan when `b` is 0)."""
    return a / b


def _quiet_quotient(a, b):
    with np.errstate(divide="ignore", invalid="ignore"):
        return a / b


quotient = _quiet_quotient if numba.config.DISABLE_JIT else kernel(float64(float64, float64))(_quotient)
"""``quotient(a, b)``: ``a / b`` for a result used only when `b` < 0: computed whatever `b` (a branch-free loop;
choosing a safe divisor first cost 8 % of `trace_rope`), without NumPy's division warnings when run without JIT."""


@kernel(int64(i4_1d_ro, int64))
def first_listed(edge_list, n_edges):
    """Return the smallest of the first `n_edges` (>= 1) flat indices of `edge_list`: the first edge pixel in
    raster order, so the first pixel of the component that holds it."""
    first = np.int64(edge_list[0])
    for t in range(n_edges):
        first = min(first, np.int64(edge_list[t]))
    return first


@kernel(int32(u1_1d, int64, i4_1d_ro, int64, int32, i4_2d, int32, i4_1d))
def keep_traced(edges, width, edge_list, n_edges, min_pixels, chain, n, stack):
    """`keep_largest_closed` after the trace: the `n` pixels of `chain` (row, col) are the outer boundary of the
    component of the first listed pixel in raster order, traced on the flat map `edges` as `keep_largest_closed`
    expects it (1 on the `n_edges` listed pixels, 0 around them, off the image border).

    A thin component (the rope's edges) is mostly its boundary: only the listed pixels the chain misses are
    flooded (one group of them at a time, through the map: 3 = seen), a group touching the chain belonging to
    the traced component, any other being a component of its own. The traced component wins ties (its first
    pixel comes first in raster order). Returns its size, with the listed pixels rewritten as
    `keep_largest_closed` leaves them (1 = traced component, 2 = others); NOT_FOUND when it is the largest but
    below `min_pixels` (every listed pixel 2); 0 when another component is larger (every listed pixel back to 1,
    for `keep_largest_closed`). `stack` needs one slot per listed pixel.
    """
    for i in range(n):
        edges[np.int64(chain[i, 0]) * width + chain[i, 1]] = 2
    tail = 0
    others = 0
    largest_other = 0
    for t in range(n_edges):
        seed = edge_list[t]
        if edges[seed] != 1:
            continue
        begin = tail
        tail, _, touches = flood_flat(edges, width, seed, stack, tail)
        if touches:  # pixels of the traced component inside its boundary
            for i in range(begin, tail):
                edges[stack[i]] = 2
        else:
            others += tail - begin
            largest_other = max(largest_other, tail - begin)
    size = n_edges - others
    if largest_other > size:
        for t in range(n_edges):
            edges[edge_list[t]] = 1
        return 0
    if size < min_pixels:
        for t in range(n_edges):
            edges[edge_list[t]] = 2
        return NOT_FOUND
    for t in range(n_edges):
        edges[edge_list[t]] -= 1  # traced component 2 -> 1, the others 3 -> 2
    return size


@kernel(int32(f4_2d_ro, f4_2d_ro, f4_2d_ro, i4_1d_ro, i4_1d_ro, i4_2d, int32, i4_1d, f4_2d))
def refine_inner(mag, gx, gy, lo, hi, chain, n, scratch, out_points):
    """`refine_subpixel` and `count_roi_contacts` of the first `n` chain pixels, all of them inside the spans
    `lo`/`hi` and off the image border (no border tests): the same float32 values, without branches (both
    neighbours along the chosen axis are read through one offset; a parabola without a maximum gives 0).

    Writes `out_points` and, per row of the chain, the columns a pixel must lie strictly between to have no
    8-neighbour outside the spans into ``scratch[:height]`` and ``scratch[height : 2 * height]``; returns the
    ROI contacts.
    """
    # Not `refine_subpixel` then `count_roi_contacts` (as `trace_rope` calls them for spans that touch the image
    # border): on the steady frame's path their per-pixel branches (border, no gradient, no maximum) and the
    # second pass over the chain are what this kernel saves.
    height = mag.shape[0]
    width = mag.shape[1]
    near_lo = scratch[:height]
    near_hi = scratch[height : 2 * height]
    r_min = height
    r_max = -1
    for i in range(n):
        r_min = min(r_min, chain[i, 0])
        r_max = max(r_max, chain[i, 0])
    # A chain pixel (c inside its row's span) touches the border of the spans when c - 1 or c + 1 leaves the
    # span of row r, r - 1 or r + 1 (an empty row: always). Clamped: an empty row's bounds may be extreme.
    for r in range(r_min, r_max + 1):
        near_lo[r] = min(np.int64(max(max(lo[r - 1], lo[r]), lo[r + 1])) + 1, width)
        near_hi[r] = max(np.int64(min(min(hi[r - 1], hi[r]), hi[r + 1])) - 1, -1)
    fmag = mag.reshape(height * width)
    fgx = gx.reshape(height * width)
    fgy = gy.reshape(height * width)
    zero = np.float32(0.0)
    contacts = 0
    for i in range(n):
        r = chain[i, 0]
        c = chain[i, 1]
        k = np.int64(r) * width + c
        g_r = fgy[k]
        g_c = fgx[k]
        m0 = fmag[k]
        horizontal = abs(g_c) >= abs(g_r)
        step = 1 if horizontal else width
        mm = fmag[np.uint64(k - step)]
        mp = fmag[np.uint64(k + step)]
        denom = mm - 2.0 * m0 + mp  # the expressions of `axis_offset`, in its order
        keep = (denom < 0.0) & ((g_r != 0.0) | (g_c != 0.0))
        delta = np.float32(min(max(quotient(0.5 * (mm - mp), denom), -1.0), 1.0))
        d = delta if keep else zero
        d_r = zero if horizontal else d
        d_c = d if horizontal else zero
        out_points[i, 0] = r + d_r
        out_points[i, 1] = c + d_c
        contacts += (c < near_lo[r]) | (c > near_hi[r])
    return contacts


@kernel(int32(u1_2d, i4_1d_ro, i4_1d_ro, u1_2d_ro, boolean, int32, CONTOUR))
def close_open_outline(edges, lo, hi, static_mask, inner, n, contour):
    """`join_open_ends` on the `n`-point trace in `contour`; the join kept when the component traced again (as
    `trace_rope` traces: `trace_closed` when `inner`) walks at most `JOINED_REVISITS` of its pixels twice (a
    ring), else taken out and the component traced as before. Writes `contour` as `trace_rope` (``counts[0]``:
    the component with the join's pixels); returns the chain length."""
    a, b, changed, start = join_open_ends(edges, lo, hi, static_mask, n, contour)
    if changed == 0:
        return n
    width = np.int64(edges.shape[1])
    chain = contour.chain
    m = n
    for attempt in range(2):
        r = int32(start // width)
        c = int32(start - r * width)
        if inner:
            m = trace_closed(edges.reshape(edges.shape[0] * width), width, r, c, chain, contour.codes)
        else:
            m = trace_contour(edges, lo, hi, r, c, chain, contour.codes)
        if attempt == 1 or (m > 0 and count_revisits(chain, m, edges) <= JOINED_REVISITS * m):
            break
        draw_join(edges, lo, hi, a, b, changed)  # not a ring: the line out again, the old trace
        start = np.int64(contour.start[0]) * width + contour.start[1]
        changed = 0
    if changed != 0:
        contour.start[0] = start // width
        contour.start[1] = start - start // width * width
        contour.counts[0] += joined_pixels(changed)
    return m


_NO_FIXED: Final = -1e9
"""A fixed end far off the image: `count_border_contacts` then counts every chain pixel on the image border."""


@kernel(
    int32(u1_2d, i4_1d_ro, i4_1d_ro, i4_1d_ro, int64, int32, boolean, u1_2d_ro, f4_2d_ro, f4_2d_ro, f4_2d_ro, CONTOUR)
)
def trace_rope(edges, lo, hi, edge_list, n_edges, min_pixels, ring_clear, static_mask, mag, gx, gy, contour):
    """The contour stage in one call: `keep_largest_listed`, `trace_contour` from the component's start,
    `keep_open_once` when the chain walks out and back along a curve that touches `static_mask` (the rope cut by
    the mask at its clamp: walked once; without a mask, a 1x1 placeholder, an out-and-back walk is a broken band
    edge or a photo's looped rope, kept as it is for the outline check; `close_open_outline` otherwise),
    `prune_excursions` (spurs and small loops of noise hung on the outline taken out; ``stack`` as scratch),
    `refine_subpixel` of the chain and `count_roi_contacts`; same outputs as those calls in that order. When
    `ring_clear` and the spans keep off the image border, the trace is `trace_closed` (no span tests), run
    first from the first listed pixel: `keep_traced` then floods only the pixels the chain missed (when another
    component is larger, the component is chosen again by `keep_largest_closed` and traced from its start),
    and `refine_inner` refines and counts without border tests.

    Arguments as for those kernels (`n_edges` is an int64: a Python int passes as it is; `edges` is
    rewritten). `contour` (`Contour`) gets the outputs: ``labels`` (with `ring_clear`: scratch), ``stack``,
    ``start``, ``chain``, ``codes`` and ``points`` as those kernels' (past the returned count, and after
    NOT_FOUND or FULL, the chain buffers hold no meaningful values), and ``counts`` (3 slots at least) the
    component's pixel count, the chain's ROI contacts and how many chain pixels lie on the image border (0
    means `count_border_contacts` is 0 too).
    Returns the chain length, NOT_FOUND (no component of `min_pixels`; counts 0) or FULL (chain longer than the
    buffers; ``counts[0]`` set).
    """
    out_labels = contour.labels
    stack = contour.stack
    out_start = contour.start
    out_chain = contour.chain
    out_codes = contour.codes
    out_points = contour.points
    out_counts = contour.counts
    out_counts[0] = 0
    out_counts[1] = 0
    out_counts[2] = 0
    height = edges.shape[0]
    width = edges.shape[1]
    inner = ring_clear and spans_off_border(lo, hi, height, width)
    flat = edges.reshape(height * width)
    scratch = out_labels.reshape(height * width)
    if inner and n_edges >= min_pixels and n_edges > 0:
        # Trace first, from the first edge pixel in raster order, then flood only what the chain missed: the
        # rope's component is the only one in a band and mostly its own boundary (`keep_traced`).
        first = first_listed(edge_list, n_edges)
        start_r = first // width
        start_c = first - start_r * width
        n = trace_closed(flat, width, start_r, start_c, out_chain, out_codes)
        if n >= 0:
            size = keep_traced(flat, width, edge_list, n_edges, min_pixels, out_chain, n, stack)
            if size < 0:
                return size
            if size > 0:
                out_start[0] = start_r
                out_start[1] = start_c
                out_counts[0] = size
                if n >= OPEN_RATIO * size and touches_mask(static_mask, out_chain, n):
                    n = keep_open_once(out_chain, out_codes, n, size)
                elif n > size:
                    n = close_open_outline(edges, lo, hi, static_mask, True, n, contour)
                n = prune_excursions(out_chain, out_codes, n, width, stack)
                out_counts[1] = refine_inner(mag, gx, gy, lo, hi, out_chain, n, scratch, out_points)
                return n
        # Another component is larger, or the chain overflows (its size is then reported): the general way.
    if inner:
        size = keep_largest_closed(flat, edge_list, n_edges, min_pixels, width, stack, out_start)
    else:
        size = keep_largest_listed(
            edges, lo, hi, edge_list, n_edges, min_pixels, ring_clear, out_labels, stack, out_start
        )
    if size < 0:
        return size
    out_counts[0] = size
    if inner:
        n = trace_closed(flat, width, out_start[0], out_start[1], out_chain, out_codes)
    else:
        n = trace_contour(edges, lo, hi, out_start[0], out_start[1], out_chain, out_codes)
    if n < 0:
        return n
    if n >= OPEN_RATIO * size and touches_mask(static_mask, out_chain, n):
        n = keep_open_once(out_chain, out_codes, n, size)
    elif n > size:
        n = close_open_outline(edges, lo, hi, static_mask, inner, n, contour)
    n = prune_excursions(out_chain, out_codes, n, width, stack)
    if inner:
        out_counts[1] = refine_inner(mag, gx, gy, lo, hi, out_chain, n, scratch, out_points)
        return n
    refine_subpixel(mag, gx, gy, out_chain, n, out_points)
    out_counts[1] = count_roi_contacts(out_chain, n, lo, hi, width)
    out_counts[2] = count_border_contacts(out_chain, n, height, width, _NO_FIXED, _NO_FIXED, 0.0)
    return n
