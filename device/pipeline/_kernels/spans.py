"""Row-span regions of interest: grow, build around a polyline, test membership."""

from __future__ import annotations

import math

import numpy as np
from numba import boolean, float32, int32

from ropecam.shared.jit import (
    f4_2d_ro,
    i4_1d,
    i4_1d_ro,
    i4_2d,
    kernel,
    u1_2d_ro,
)


@kernel(int32(i4_1d_ro, i4_1d_ro, int32, int32, i4_1d, i4_1d))
def grow_spans(lo, hi, rows_apart, cols_apart, out_lo, out_hi):
    """Write into `out_lo`/`out_hi` the union over rows ``r - rows_apart .. r + rows_apart`` of the spans `lo`/`hi`,
    widened by `cols_apart` columns and clipped to ``[0, width)`` where width is ``max(hi) + cols_apart + 1``.

    The width of the image is not known here, so clipping to the right is left to the caller through `hi` being
    already clipped; ``out_hi`` may exceed it by `cols_apart` and is clipped with the image width by the caller's
    kernels. Returns the number of non-empty rows.
    """
    n_rows = lo.shape[0]
    count = 0
    for r in range(n_rows):
        best_lo = 2147483647
        best_hi = -1
        for rr in range(max(0, r - rows_apart), min(n_rows, r + rows_apart + 1)):
            if hi[rr] >= lo[rr]:
                if lo[rr] < best_lo:
                    best_lo = lo[rr]
                if hi[rr] > best_hi:
                    best_hi = hi[rr]
        if best_hi >= 0:
            out_lo[r] = max(0, best_lo - cols_apart)
            out_hi[r] = best_hi + cols_apart
            count += 1
        else:
            out_lo[r] = 1
            out_hi[r] = 0
    return count


@kernel(int32(f4_2d_ro, int32, int32, float32, float32, float32, float32, float32, int32, int32, i4_1d, i4_1d))
def spans_around_points(
    points, n_points, margin_px, motion_px, rot_a, rot_b, fixed_r, fixed_c, height, width, out_lo, out_hi
):
    """Write the row spans covering a disc around each of the first `n_points` (row, col) `points`, each moved
    by a rotation and scaling about the fixed end, clipped to the image; returns the number of non-empty rows.

    Seen as complex numbers ``z = (row - fixed_r) + 1j * (col - fixed_c)``, each point moves to
    ``(rot_a + 1j * rot_b) * z`` (1, 0: no motion): the predicted swing of the rope about its fixed end
    (fixed_r, fixed_c). With d the point's distance from the fixed end and d_max the largest such distance, the
    disc's radius is ``m = margin_px + ceil(motion_px * d / d_max)``: `motion_px` is the uncertainty of the
    prediction at the farthest point. Row r gets the columns ``floor(c - h) .. ceil(c + h)`` with
    ``h = sqrt(m**2 - (r - row)**2)`` (discs, not squares: a band along a diagonal rope is 30 % narrower).
    Points closer than half the radius (L1) to the last one used are skipped (the chain is 8-connected, so
    every point keeps at least half its radius).
    """
    for r in range(height):
        out_lo[r] = width
        out_hi[r] = -1
    d2_max = 1e-12
    for i in range(n_points):
        dr = points[i, 0] - fixed_r
        dc = points[i, 1] - fixed_c
        d2 = dr * dr + dc * dc
        if d2 > d2_max:
            d2_max = d2
    d_max = math.sqrt(d2_max)
    last_r = -1e9
    last_c = -1e9
    for i in range(n_points):
        pr = points[i, 0]
        pc = points[i, 1]
        if not (pr == pr and pc == pc):
            continue
        zr = pr - fixed_r
        zc = pc - fixed_c
        share = math.sqrt(zr * zr + zc * zc) / d_max
        m = margin_px + math.ceil(motion_px * share)
        if i != n_points - 1 and abs(pr - last_r) + abs(pc - last_c) < 0.5 * m:
            continue
        last_r = pr
        last_c = pc
        qr = fixed_r + rot_a * zr - rot_b * zc
        qc = fixed_c + rot_b * zr + rot_a * zc
        if not (abs(qr) < 1e9 and abs(qc) < 1e9):
            continue
        r0 = max(0, math.ceil(qr - m))
        r1 = min(height - 1, math.floor(qr + m))
        for r in range(r0, r1 + 1):
            dy = r - qr
            half = math.sqrt(max(0.0, m * m - dy * dy))
            c0 = max(0, math.floor(qc - half))
            c1 = min(width - 1, math.ceil(qc + half))
            if c1 < c0:
                continue
            if c0 < out_lo[r]:
                out_lo[r] = c0
            if c1 > out_hi[r]:
                out_hi[r] = c1
    count = 0
    for r in range(height):
        if out_hi[r] >= out_lo[r]:
            count += 1
        else:
            out_lo[r] = 1
            out_hi[r] = 0
    return count


@kernel(boolean(int32, int32, i4_1d_ro, i4_1d_ro))
def in_spans(r, c, lo, hi):
    """Return True when pixel (r, c) lies inside the row spans `lo`/`hi`."""
    if r < 0 or r >= lo.shape[0]:
        return False
    return lo[r] <= c <= hi[r]


@kernel(int32(i4_1d_ro, i4_1d_ro, i4_1d, i4_1d))
def union_spans(lo, hi, out_lo, out_hi):
    """Widen the row spans `out_lo`/`out_hi` to also cover `lo`/`hi` (an empty span has ``hi < lo``); returns the
    number of non-empty rows (one span per row: the union of two disjoint spans also covers the gap)."""
    count = 0
    for r in range(out_lo.shape[0]):
        if hi[r] >= lo[r]:
            if out_hi[r] < out_lo[r]:
                out_lo[r] = lo[r]
                out_hi[r] = hi[r]
            else:
                out_lo[r] = min(out_lo[r], lo[r])
                out_hi[r] = max(out_hi[r], hi[r])
        if out_hi[r] >= out_lo[r]:
            count += 1
    return count


@kernel(int32(u1_2d_ro, int32, int32, int32, int32, i4_2d, i4_2d, i4_1d, i4_1d, i4_1d))
def coarse_spans(frame, block, step_sum, min_cells, dilate, out_sums, out_labels, stack, out_lo, out_hi):
    """Find where the rope may be from block sums, without edge detection: write row spans covering it.

    The frame is cut into `block` x `block` cells (the last partial row and column of cells are left out) whose
    sums go into `out_sums` (at least (height // block, width // block)). A cell is active when a 4-neighbour's
    sum differs from its own by at least `step_sum` (an intensity step of ``step_sum / block**2`` grey levels).
    Of the 8-connected groups of active cells (labels in `out_labels`, `stack` needs one slot per cell) those of
    at least `min_cells` cells are kept; the spans cover them grown by `dilate` cells on every side (and reach the
    image border where they touch the left-out partial cells). Returns the number of kept cells (0: empty spans).
    """
    height = frame.shape[0]
    width = frame.shape[1]
    gh = height // block
    gw = width // block
    if gh < 1 or gw < 1 or out_sums.shape[0] < gh or out_sums.shape[1] < gw:
        return 0
    if out_labels.shape[0] < gh or out_labels.shape[1] < gw or stack.shape[0] < gh * gw:
        return 0
    if stack.shape[0] < width:
        return 0
    size = height * width
    f = frame.reshape(size)
    acc = stack[:width]  # column sums of one row of cells (the stack is free until the flood fill)
    for i in range(gh):
        for c in range(width):
            acc[c] = 0
        for r in range(i * block, (i + 1) * block):
            base = np.uint64(r * width)
            for c in range(width):
                acc[c] += np.int32(f[base + np.uint64(c)])
        for j in range(gw):
            total = np.int32(0)
            for k in range(j * block, (j + 1) * block):
                total += acc[k]
            out_sums[i, j] = total
    for i in range(gh):
        for j in range(gw):
            s = out_sums[i, j]
            step = 0
            if j > 0:
                step = max(step, abs(out_sums[i, j - 1] - s))
            if j < gw - 1:
                step = max(step, abs(out_sums[i, j + 1] - s))
            if i > 0:
                step = max(step, abs(out_sums[i - 1, j] - s))
            if i < gh - 1:
                step = max(step, abs(out_sums[i + 1, j] - s))
            active = step >= step_sum
            out_labels[i, j] = -1 if active else 0
    # Flood-fill the active cells; a group too small is marked -2 (kept as visited), a group kept gets 1.
    kept = 0
    for i0 in range(gh):
        for j0 in range(gw):
            if out_labels[i0, j0] != -1:
                continue
            out_labels[i0, j0] = -3
            stack[0] = i0 * gw + j0
            top = 1
            first = 0
            while first < top:  # breadth first: the stack holds the whole group afterwards
                i = stack[first] // gw
                j = stack[first] - i * gw
                first += 1
                for di in range(-1, 2):
                    for dj in range(-1, 2):
                        ii = i + di
                        jj = j + dj
                        if 0 <= ii < gh and 0 <= jj < gw and out_labels[ii, jj] == -1:
                            out_labels[ii, jj] = -3
                            stack[top] = ii * gw + jj
                            top += 1
            mark = 1 if top >= min_cells else -2
            for t in range(top):
                i = stack[t] // gw
                out_labels[i, stack[t] - i * gw] = mark
            if mark == 1:
                kept += top
    for r in range(height):
        out_lo[r] = width
        out_hi[r] = -1
    if kept == 0:
        for r in range(height):
            out_lo[r] = 1
            out_hi[r] = 0
        return 0
    for i in range(gh):
        j_min = gw
        j_max = -1
        for j in range(gw):
            if out_labels[i, j] == 1:
                if j < j_min:
                    j_min = j
                j_max = j
        if j_max < 0:
            continue
        c0 = max(0, (j_min - dilate) * block)
        c1 = (j_max + 1 + dilate) * block - 1
        if j_max + 1 + dilate >= gw:
            c1 = width - 1
        c1 = min(c1, width - 1)
        r0 = max(0, (i - dilate) * block)
        r1 = (i + 1 + dilate) * block - 1
        if i + 1 + dilate >= gh:
            r1 = height - 1
        r1 = min(r1, height - 1)
        for r in range(r0, r1 + 1):
            if c0 < out_lo[r]:
                out_lo[r] = c0
            if c1 > out_hi[r]:
                out_hi[r] = c1
    for r in range(height):
        if out_hi[r] < out_lo[r]:
            out_lo[r] = 1
            out_hi[r] = 0
    return kept
