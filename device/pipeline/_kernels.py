"""Numba kernels of the rope pipeline: Canny on row spans, component selection, contour tracing, the paper's
segmentation operator and scoring, subpixel refinement, the blur split and material point tracking.

Conventions: images are (row, col); image points are float32 (row, col) with (0, 0) the centre of the top-left
pixel; a region of interest is one column span ``[lo[r], hi[r]]`` per row (empty when ``hi[r] < lo[r]``).
Kernels never allocate: every output is passed in (``out_*``, last) and the return value is a count or a negative
`KernelStatus`.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float32, float64, int32, int64, types

from ropecam.shared.jit import (
    KernelStatus,
    f4_1d,
    f4_2d,
    f4_2d_ro,
    f8_1d_ro,
    i4_1d,
    i4_1d_ro,
    i4_2d,
    i4_2d_ro,
    kernel,
    u1_2d,
    u1_2d_ro,
)

f4_1d_ro: Final = types.Array(types.float32, 1, "C", readonly=True)

FULL: Final = int(KernelStatus.FULL)
INVALID: Final = int(KernelStatus.INVALID)
NOT_FOUND: Final = int(KernelStatus.NOT_FOUND)

# Clockwise neighbour order on screen (rows point down), starting east: E, SE, S, SW, W, NW, N, NE.
DIR_ROW: Final = np.array([0, 1, 1, 1, 0, -1, -1, -1], dtype=np.int32)
DIR_COL: Final = np.array([1, 1, 0, -1, -1, -1, 0, 1], dtype=np.int32)

# The paper's segmentation operator, eq. (7).
OPERATOR: Final = np.array([[-3, 6, 2], [-5, 0, 5], [-2, -6, 3]], dtype=np.int32)

TAN_22_5: Final = np.float32(0.41421356237309503)
ZERO: Final = np.float32(0.0)
TWO: Final = np.float32(2.0)
EDGE_NONE: Final = 0
EDGE_WEAK: Final = 1
EDGE_STRONG: Final = 2


# --------------------------------------------------------------------------------------------------------------
# Spans
# --------------------------------------------------------------------------------------------------------------
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


@kernel(int32(f4_2d_ro, int32, int32, float32, float32, float32, int32, int32, i4_1d, i4_1d))
def spans_around_points(points, n_points, margin_px, motion_px, fixed_r, fixed_c, height, width, out_lo, out_hi):
    """Write the row spans covering a square around each of the first `n_points` (row, col) `points`, clipped to
    the image; returns the number of non-empty rows.

    The square's half-size is ``margin_px + motion_px * d / d_max`` where d is the point's distance from the fixed
    end (fixed_r, fixed_c) and d_max the largest such distance: a rope swinging about its fixed end moves in
    proportion to that distance. Points closer than half the half-size to the last one used are skipped (the
    chain is 8-connected, so the union is unchanged up to a pixel).
    """
    for r in range(height):
        out_lo[r] = width
        out_hi[r] = -1
    d_max = 1e-6
    for i in range(n_points):
        d = math.hypot(points[i, 0] - fixed_r, points[i, 1] - fixed_c)
        if d > d_max:
            d_max = d
    last_r = -1e9
    last_c = -1e9
    for i in range(n_points):
        pr = points[i, 0]
        pc = points[i, 1]
        if not (pr == pr and pc == pc):
            continue
        d = math.hypot(pr - fixed_r, pc - fixed_c)
        m = margin_px + math.ceil(motion_px * d / d_max)
        if i != n_points - 1 and abs(pr - last_r) + abs(pc - last_c) < 0.5 * m:
            continue
        last_r = pr
        last_c = pc
        r0 = max(0, math.floor(pr) - m)
        r1 = min(height - 1, math.ceil(pr) + m)
        c0 = max(0, math.floor(pc) - m)
        c1 = min(width - 1, math.ceil(pc) + m)
        for r in range(r0, r1 + 1):
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


# --------------------------------------------------------------------------------------------------------------
# Canny
# --------------------------------------------------------------------------------------------------------------
@kernel(
    int32(
        u1_2d_ro, f4_1d_ro, i4_1d_ro, i4_1d_ro, float32, float32, i4_2d, f4_2d, f4_2d, f4_2d, f4_2d, f4_2d, u1_2d, i4_1d
    )
)
def detect_edges(
    frame, weights, lo, hi, low, high, work_spans, out_tmp, out_smooth, out_gx, out_gy, out_mag, out_edges, stack
):
    """Canny edge detection (Gaussian smoothing, Sobel, non-maximum suppression, hysteresis) inside row spans.

    `weights` is a normalised odd-length 1-D smoothing kernel (``[1.0]`` disables smoothing, which makes the
    result comparable with ``cv2.Canny(frame, low, high, L2gradient=True)``). Gradients use the 3x3 Sobel with a
    replicated border, the magnitude is the L2 norm. Writes `work_spans` (rows 0-1: Sobel spans, rows 2-3:
    smoothing spans), `out_tmp`, `out_smooth`, `out_gx`, `out_gy`, `out_mag` (valid inside the Sobel spans) and
    `out_edges` (1 on edge pixels, 0 elsewhere, valid inside the spans `lo`/`hi`); `stack` needs one slot per
    pixel of the spans. Returns the number of edge pixels or INVALID (bad shapes).
    """
    height = frame.shape[0]
    width = frame.shape[1]
    radius = weights.shape[0] // 2
    if lo.shape[0] != height or hi.shape[0] != height or work_spans.shape[0] < 4 or work_spans.shape[1] != height:
        return INVALID
    if stack.shape[0] < height * width:
        return INVALID
    sob_lo = work_spans[0]
    sob_hi = work_spans[1]
    gau_lo = work_spans[2]
    gau_hi = work_spans[3]
    grow_spans(lo, hi, 1, 1, sob_lo, sob_hi)
    grow_spans(sob_lo, sob_hi, 1, 1, gau_lo, gau_hi)
    for r in range(height):
        gau_hi[r] = min(gau_hi[r], width - 1)
    # Separable smoothing, horizontal pass first: over the union of the smoothing spans of the rows it feeds
    # (rows 0-1 of work_spans are free until the Sobel spans are needed, so they hold that union for a moment).
    # Hot loops run over 0-based slices of row views: Numba then drops its negative-index checks and the loops
    # vectorise (about 10x faster than indexing from a non-zero start).
    hor_lo = work_spans[0]
    hor_hi = work_spans[1]
    grow_spans(gau_lo, gau_hi, radius, 0, hor_lo, hor_hi)
    for r in range(height):
        c0 = np.int64(hor_lo[r])
        c1 = min(np.int64(hor_hi[r]), width - 1)
        if c1 < c0:
            continue
        t_row = out_tmp[r]
        f_row = frame[r]
        inner0 = max(c0, radius)
        inner1 = min(c1, width - 1 - radius)
        if inner1 >= inner0 and radius == 2:
            # The default smoothing (sigma 1 px): one fused loop, no per-tap passes over short spans.
            t_in = t_row[inner0 : inner1 + 1]
            fa = f_row[inner0 - 2 : inner1 - 1]
            fb = f_row[inner0 - 1 : inner1]
            fc = f_row[inner0 : inner1 + 1]
            fd = f_row[inner0 + 1 : inner1 + 2]
            fe = f_row[inner0 + 2 : inner1 + 3]
            w0 = weights[0]
            w1 = weights[1]
            w2 = weights[2]
            for i in range(t_in.shape[0]):
                t_in[i] = w0 * (np.float32(fa[i]) + np.float32(fe[i])) + w1 * (np.float32(fb[i]) + np.float32(fd[i]))
                t_in[i] += w2 * np.float32(fc[i])
        elif inner1 >= inner0:
            t_in = t_row[inner0 : inner1 + 1]
            t_in[:] = ZERO
            for k in range(-radius, radius + 1):
                wk = weights[k + radius]
                f_in = f_row[inner0 + k : inner1 + 1 + k]
                for i in range(t_in.shape[0]):
                    t_in[i] += wk * f_in[i]
        # Columns within `radius` of the image border: replicate the edge pixel.
        for c in range(c0, min(c1 + 1, max(inner0, c0))):
            acc = ZERO
            for k in range(-radius, radius + 1):
                acc += weights[k + radius] * f_row[min(max(c + k, 0), width - 1)]
            t_row[c] = acc
        for c in range(max(inner1 + 1, c0), c1 + 1):
            acc = ZERO
            for k in range(-radius, radius + 1):
                acc += weights[k + radius] * f_row[min(max(c + k, 0), width - 1)]
            t_row[c] = acc
    for r in range(height):
        c0 = np.int64(gau_lo[r])
        c1 = np.int64(gau_hi[r])
        if c1 < c0:
            continue
        s_in = out_smooth[r, c0 : c1 + 1]
        if radius == 2:
            ta = out_tmp[max(r - 2, 0), c0 : c1 + 1]
            tb = out_tmp[max(r - 1, 0), c0 : c1 + 1]
            tc = out_tmp[r, c0 : c1 + 1]
            td = out_tmp[min(r + 1, height - 1), c0 : c1 + 1]
            te = out_tmp[min(r + 2, height - 1), c0 : c1 + 1]
            w0 = weights[0]
            w1 = weights[1]
            w2 = weights[2]
            for i in range(s_in.shape[0]):
                s_in[i] = w0 * (ta[i] + te[i]) + w1 * (tb[i] + td[i]) + w2 * tc[i]
            continue
        s_in[:] = ZERO
        for k in range(-radius, radius + 1):
            wk = weights[k + radius]
            t_in = out_tmp[min(max(r + k, 0), height - 1), c0 : c1 + 1]
            for i in range(s_in.shape[0]):
                s_in[i] += wk * t_in[i]
    grow_spans(lo, hi, 1, 1, sob_lo, sob_hi)
    for r in range(height):
        sob_hi[r] = min(sob_hi[r], width - 1)
    for r in range(height):
        c0 = np.int64(sob_lo[r])
        c1 = np.int64(sob_hi[r])
        if c1 < c0:
            continue
        sm = out_smooth[max(r - 1, 0)]
        s0 = out_smooth[r]
        sp = out_smooth[min(r + 1, height - 1)]
        ox = out_gx[r]
        oy = out_gy[r]
        om = out_mag[r]
        for c in (c0, c1):  # the ends may sit on the image border: replicate it
            cm = max(c - 1, 0)
            cp = min(c + 1, width - 1)
            gx = (sm[cp] + TWO * s0[cp] + sp[cp]) - (sm[cm] + TWO * s0[cm] + sp[cm])
            gy = (sp[cm] + TWO * sp[c] + sp[cp]) - (sm[cm] + TWO * sm[c] + sm[cp])
            ox[c] = gx
            oy[c] = gy
            om[c] = np.sqrt(gx * gx + gy * gy)
        if c1 - c0 < 2:
            continue
        sml = sm[c0 : c1 - 1]
        smc = sm[c0 + 1 : c1]
        smr = sm[c0 + 2 : c1 + 1]
        s0l = s0[c0 : c1 - 1]
        s0r = s0[c0 + 2 : c1 + 1]
        spl = sp[c0 : c1 - 1]
        spc = sp[c0 + 1 : c1]
        spr = sp[c0 + 2 : c1 + 1]
        oxi = ox[c0 + 1 : c1]
        oyi = oy[c0 + 1 : c1]
        omi = om[c0 + 1 : c1]
        for i in range(oxi.shape[0]):
            gx = (smr[i] + TWO * s0r[i] + spr[i]) - (sml[i] + TWO * s0l[i] + spl[i])
            gy = (spl[i] + TWO * spc[i] + spr[i]) - (sml[i] + TWO * smc[i] + smr[i])
            oxi[i] = gx
            oyi[i] = gy
            omi[i] = np.sqrt(gx * gx + gy * gy)
    # Non-maximum suppression with OpenCV's sector rule and tie-breaking; pixels outside the image count as 0.
    top = 0
    for r in range(height):
        c0 = np.int64(lo[r])
        c1 = min(np.int64(hi[r]), width - 1)
        if c1 < c0:
            continue
        e_in = out_edges[r, c0 : c1 + 1]
        m_in = out_mag[r, c0 : c1 + 1]
        e_in[:] = EDGE_NONE
        for i in range(m_in.shape[0]):
            m = m_in[i]
            if m <= low:
                continue
            c = c0 + i
            ax = abs(out_gx[r, c])
            ay = abs(out_gy[r, c])
            if ay < ax * TAN_22_5:
                ml = out_mag[r, c - 1] if c > 0 else ZERO
                mr = out_mag[r, c + 1] if c < width - 1 else ZERO
                keep = m > ml and m >= mr
            elif ay > ax * (TAN_22_5 + TWO):
                mu = out_mag[r - 1, c] if r > 0 else ZERO
                md = out_mag[r + 1, c] if r < height - 1 else ZERO
                keep = m > mu and m >= md
            else:
                s = -1 if out_gx[r, c] * out_gy[r, c] < 0 else 1
                mu = out_mag[r - 1, c - s] if (r > 0 and 0 <= c - s < width) else ZERO
                md = out_mag[r + 1, c + s] if (r < height - 1 and 0 <= c + s < width) else ZERO
                keep = m > mu and m > md
            if keep:
                if m > high:
                    e_in[i] = EDGE_STRONG
                    stack[top] = r * width + c
                    top += 1
                else:
                    e_in[i] = EDGE_WEAK
    # Hysteresis: grow strong edges through weak ones (8-connected), never leaving the spans.
    while top > 0:
        top -= 1
        r = stack[top] // width
        c = stack[top] - r * width
        for k in range(8):
            rr = r + DIR_ROW[k]
            cc = c + DIR_COL[k]
            if 0 <= rr < height and lo[rr] <= cc <= hi[rr] and cc < width and out_edges[rr, cc] == EDGE_WEAK:
                out_edges[rr, cc] = EDGE_STRONG
                stack[top] = rr * width + cc
                top += 1
    count = 0
    for r in range(height):
        c0 = np.int64(lo[r])
        c1 = min(np.int64(hi[r]), width - 1)
        if c1 < c0:
            continue
        e_in = out_edges[r, c0 : c1 + 1]
        for i in range(e_in.shape[0]):
            v = e_in[i] >> 1  # EDGE_STRONG -> 1, weak and none -> 0
            e_in[i] = v
            count += np.int64(v)  # a uint8 sum would wrap at 256 (plain Python promotes to the narrower type)
    return count


# --------------------------------------------------------------------------------------------------------------
# Component selection and contour
# --------------------------------------------------------------------------------------------------------------
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
            top = 0
            stack[top] = r * width + c
            top += 1
            size = 0
            while top > 0:
                top -= 1
                pr = stack[top] // width
                pc = stack[top] - pr * width
                size += 1
                for k in range(8):
                    rr = pr + DIR_ROW[k]
                    cc = pc + DIR_COL[k]
                    if rr < 0 or rr >= height or cc < lo[rr] or cc > hi[rr] or cc >= width:
                        continue
                    if edges[rr, cc] != 0 and out_labels[rr, cc] == 0:
                        out_labels[rr, cc] = label
                        stack[top] = rr * width + cc
                        top += 1
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
    br = start_r
    bc = start_c - 1
    first_r = -1
    first_c = -1
    n = 0
    while True:
        # Direction index of the backtrack pixel seen from the current one.
        dr = br - pr
        dc = bc - pc
        b_idx = 0
        for k in range(8):
            if DIR_ROW[k] == dr and DIR_COL[k] == dc:
                b_idx = k
        found = -1
        for step in range(1, 9):
            k = (b_idx + step) % 8
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
        out_codes[n] = (8 - found) % 8
        n += 1
        prev = (found + 7) % 8
        br = pr + DIR_ROW[prev]
        bc = pc + DIR_COL[prev]
        pr = nr
        pc = nc


# --------------------------------------------------------------------------------------------------------------
# The paper's segmentation operator and scoring (method "paper")
# --------------------------------------------------------------------------------------------------------------
@kernel(int32(i4_2d_ro, int32, i4_1d))
def apply_operator(chain, n, out_tau):
    """Write tau (eq. 2) for each of the first `n` pixels of the closed `chain`: the operator O of eq. (7) summed
    over the previous and the next chain pixel in the 3x3 neighbourhood (0 on smooth points). Returns `n`."""
    for i in range(n):
        ip = (i - 1 + n) % n
        iq = (i + 1) % n
        tau = 0
        dr = chain[ip, 0] - chain[i, 0]
        dc = chain[ip, 1] - chain[i, 1]
        if abs(dr) <= 1 and abs(dc) <= 1 and not (dr == 0 and dc == 0):
            tau += OPERATOR[dr + 1, dc + 1]
        dr = chain[iq, 0] - chain[i, 0]
        dc = chain[iq, 1] - chain[i, 1]
        if abs(dr) <= 1 and abs(dc) <= 1 and not (dr == 0 and dc == 0):
            tau += OPERATOR[dr + 1, dc + 1]
        out_tau[i] = tau
    return n


@kernel(int32(i4_2d_ro, i4_1d_ro, int32, float32, float32, float32, float32, float32, i4_1d, f4_1d))
def score_knots(chain, tau, n, e1_r, e1_c, e2_r, e2_c, radius_px, out_knots, out_score):
    """Score the knots (tau != 0) of the closed `chain` with Features 1-3 and Table 1 of the paper.

    Knot k is chain pixel ``out_knots[k]``; its score goes to ``out_score[k]`` (0 to 2.5). Feature 1 uses tau of
    the neighbouring knots (cyclic, eq. 8), Feature 2 the 90-degree knots (tau in {+-1, +-5}) with the angle
    to the knots two places away and the pairs of (2.2), Feature 3 the distance to the centreline ends e1, e2
    (threshold `radius_px`). Returns the number of knots or FULL.
    """
    m = 0
    for i in range(n):
        if tau[i] != 0:
            if m >= out_knots.shape[0]:
                return FULL
            out_knots[m] = i
            m += 1
    for k in range(m):
        t = tau[out_knots[k]]
        tp = tau[out_knots[(k - 1 + m) % m]]
        tn = tau[out_knots[(k + 1) % m]]
        tpp = tau[out_knots[(k - 2 + 2 * m) % m]]
        tnn = tau[out_knots[(k + 2) % m]]
        score = 0.0
        # Feature 1 (the OCR prints 1.1 and 1.3 alike; 1.3 is read as "exactly one of the sums is zero").
        sn = t + tn
        sp = t + tp
        if sn != 0 and sp != 0:
            score += 1.0
        elif sn == 0 and sp == 0:
            score += 0.0
        elif not (tp + tnn == 0 or tn + tpp == 0):
            score += 0.5
        # Feature 2.
        if t == 1 or t == -1 or t == 5 or t == -5:
            i0 = out_knots[k]
            ia = out_knots[(k - 2 + 2 * m) % m]
            ib = out_knots[(k + 2) % m]
            r1r = float(chain[i0, 0] - chain[ia, 0])
            r1c = float(chain[i0, 1] - chain[ia, 1])
            r2r = float(chain[i0, 0] - chain[ib, 0])
            r2c = float(chain[i0, 1] - chain[ib, 1])
            norm = math.sqrt(r1r * r1r + r1c * r1c) * math.sqrt(r2r * r2r + r2c * r2c)
            if norm > 0.0:
                cos_theta = (r1r * r2r + r1c * r2c) / norm
                if cos_theta > -0.5:  # theta < 120 degrees
                    score += 0.5
        elif (t == 3 and tn == -4) or (t == -3 and tn == 4) or (t == -2 and tn == -9) or (t == 2 and tn == 9):
            score += 0.5
        # Feature 3.
        i0 = out_knots[k]
        d1 = math.hypot(chain[i0, 0] - e1_r, chain[i0, 1] - e1_c)
        d2 = math.hypot(chain[i0, 0] - e2_r, chain[i0, 1] - e2_c)
        if d1 < radius_px or d2 < radius_px:
            score += 1.0
        out_score[k] = score
    return m


# --------------------------------------------------------------------------------------------------------------
# Subpixel refinement and geometry along the closed contour
# --------------------------------------------------------------------------------------------------------------
@kernel(float32(f4_2d_ro, float32, float32))
def sample_bilinear(image, r, c):
    """Return `image` interpolated bilinearly at (r, c), clamped to the image."""
    height = image.shape[0]
    width = image.shape[1]
    r = min(max(r, 0.0), height - 1.0)
    c = min(max(c, 0.0), width - 1.0)
    r0 = min(int(r), height - 2) if height > 1 else 0
    c0 = min(int(c), width - 2) if width > 1 else 0
    fr = r - r0
    fc = c - c0
    r1 = min(r0 + 1, height - 1)
    c1 = min(c0 + 1, width - 1)
    top = image[r0, c0] * (1.0 - fc) + image[r0, c1] * fc
    bottom = image[r1, c0] * (1.0 - fc) + image[r1, c1] * fc
    return top * (1.0 - fr) + bottom * fr


@kernel(int32(f4_2d_ro, f4_2d_ro, f4_2d_ro, i4_2d_ro, int32, f4_2d))
def refine_subpixel(mag, gx, gy, chain, n, out_points):
    """Move each of the first `n` chain pixels to the subpixel maximum of the gradient magnitude (Devernay 1995:
    parabola through the magnitude at -1, 0, +1 px along the image axis nearest the gradient, offset clamped to
    1 px).

    Writes `out_points` (row, col) float32; returns `n`."""
    for i in range(n):
        r = chain[i, 0]
        c = chain[i, 1]
        g_r = gy[r, c]
        g_c = gx[r, c]
        norm = math.sqrt(g_r * g_r + g_c * g_c)
        out_points[i, 0] = r
        out_points[i, 1] = c
        if norm <= 0.0:
            continue
        # Devernay: fit the parabola along the image axis closest to the gradient (exact pixel samples, no
        # interpolation bias), then move along that axis.
        m0 = mag[r, c]
        height = mag.shape[0]
        width = mag.shape[1]
        if abs(g_c) >= abs(g_r):
            if c < 1 or c > width - 2:
                continue
            mm = mag[r, c - 1]
            mp = mag[r, c + 1]
            a_r = 0.0
            a_c = 1.0
        else:
            if r < 1 or r > height - 2:
                continue
            mm = mag[r - 1, c]
            mp = mag[r + 1, c]
            a_r = 1.0
            a_c = 0.0
        denom = mm - 2.0 * m0 + mp
        if denom < 0.0:
            delta = 0.5 * (mm - mp) / denom
            delta = min(max(delta, -1.0), 1.0)
            out_points[i, 0] = r + delta * a_r
            out_points[i, 1] = c + delta * a_c
    return n


@kernel(float64(f4_2d_ro, int32))
def signed_area(points, n):
    """Return the signed area (shoelace, in (row, col) coordinates) of the closed polygon of the first `n`
    points; positive for a clockwise traversal on screen."""
    acc = 0.0
    for i in range(n):
        j = (i + 1) % n
        acc += float(points[i, 1]) * float(points[j, 0]) - float(points[j, 1]) * float(points[i, 0])
    return 0.5 * acc


@kernel(int32(f4_2d_ro, int32, int32, f4_1d))
def turning_angles(points, n, scale, out_turn):
    """Write the unsigned turning angle (radians, 0 to pi) of the closed polyline at each point, measured between
    the chords to the points `scale` places before and after. Returns `n`."""
    for i in range(n):
        a = (i - scale + n * ((scale // n) + 1)) % n
        b = (i + scale) % n
        v1r = points[i, 0] - points[a, 0]
        v1c = points[i, 1] - points[a, 1]
        v2r = points[b, 0] - points[i, 0]
        v2c = points[b, 1] - points[i, 1]
        n1 = math.sqrt(v1r * v1r + v1c * v1c)
        n2 = math.sqrt(v2r * v2r + v2c * v2c)
        if n1 <= 0.0 or n2 <= 0.0:
            out_turn[i] = 0.0
            continue
        cos_t = (v1r * v2r + v1c * v2c) / (n1 * n2)
        cos_t = min(max(cos_t, -1.0), 1.0)
        out_turn[i] = math.acos(cos_t)
    return n


@kernel(int32(f4_2d_ro, f4_1d_ro, int32, float32, float32, float32, int32, i4_1d))
def split_contour(points, turn, n, fixed_r, fixed_c, search_px, min_gap, out_idx):
    """Find the fixed end, the far point and the two segmentation points on the closed subpixel contour.

    The fixed-end index is the contour point nearest to (fixed_r, fixed_c); the far index the point farthest
    from it. Side A runs forward along the chain from the fixed end to the far point, side B backward; on each
    side the segmentation point is the point of largest turning angle among those at least
    ``R_far - search_px`` from the fixed end, the two at least `min_gap` chain steps apart.
    Writes ``out_idx = [fixed, seg_a, far, seg_b]``; returns 4 or NOT_FOUND.
    """
    if n < 8:
        return NOT_FOUND
    i_fix = 0
    best = 1e30
    for i in range(n):
        d = math.hypot(points[i, 0] - fixed_r, points[i, 1] - fixed_c)
        if d < best:
            best = d
            i_fix = i
    i_far = 0
    r_far = -1.0
    for i in range(n):
        d = math.hypot(points[i, 0] - fixed_r, points[i, 1] - fixed_c)
        if d > r_far:
            r_far = d
            i_far = i
    threshold = r_far - search_px
    len_a = (i_far - i_fix + n) % n
    len_b = (i_fix - i_far + n) % n
    if len_a < 1 or len_b < 1:
        return NOT_FOUND
    # Side A: forward from the fixed end to the far point; side B: backward. Each gets the point of largest turning
    # in the tip zone; the pair must be `min_gap` chain steps apart (the far point may itself be a corner), so the
    # best pair is taken over "A first, then B away from it" and "B first, then A away from it".
    best_sum = -1.0
    seg_a = -1
    seg_b = -1
    for first in range(2):
        a = -1
        b = -1
        ta = -1.0
        tb = -1.0
        for rep in range(2):
            pick_a = (rep == 0) == (first == 0)
            length = len_a if pick_a else len_b
            for step in range(1, length + 1):
                i = (i_fix + step) % n if pick_a else (i_fix - step + n) % n
                if math.hypot(points[i, 0] - fixed_r, points[i, 1] - fixed_c) < threshold:
                    continue
                other = b if pick_a else a
                if other >= 0:
                    gap = abs(i - other)
                    if min(gap, n - gap) < min_gap:
                        continue
                if pick_a and turn[i] > ta:
                    ta = turn[i]
                    a = i
                elif not pick_a and turn[i] > tb:
                    tb = turn[i]
                    b = i
        if a >= 0 and b >= 0 and ta + tb > best_sum:
            best_sum = ta + tb
            seg_a = a
            seg_b = b
    if seg_a < 0 or seg_b < 0:
        return NOT_FOUND
    out_idx[0] = i_fix
    out_idx[1] = seg_a
    out_idx[2] = i_far
    out_idx[3] = seg_b
    return 4


@kernel(float64(f4_2d_ro, int64, int64, int64, int64))
def chain_length(points, n, i_start, count, direction):
    """Return the length of the `count` contour points from `i_start`, stepping `direction` (+1/-1), cyclic."""
    total = 0.0
    for k in range(1, count):
        i0 = (i_start + (k - 1) * direction + n * 4) % n
        i1 = (i_start + k * direction + n * 4) % n
        total += math.hypot(points[i1, 0] - points[i0, 0], points[i1, 1] - points[i0, 1])
    return total


@kernel(int32(f4_2d_ro, int32, int32, int32, int32, float32, float32, float32, int32, f4_2d))
def offset_side(points, n, i_start, i_stop, direction, interior_sign, width_px, sweep_tip_px, tangent_span, out_poly):
    """Copy the contour from `i_start` to `i_stop` (stepping `direction` = +1 or -1, cyclic) into `out_poly`,
    each point moved towards the band's interior by ``max(0, (width_px - sweep(s)) / 2)``.

    The edge of a blurred band lies at the centre of the intensity ramp: on the rope axis where the local sweep
    is at least the rope width, `width_px / 2` outside it where the rope did not move. The sweep is modelled as
    growing linearly with arc length from the fixed end to `sweep_tip_px` at the tip (rotation about the fixed
    end). The interior normal is ``interior_sign * (t_col, -t_row)`` for the forward chain tangent t (estimated
    over +-`tangent_span` points). Returns the number of points written or FULL.
    """
    count = (i_stop - i_start) * direction
    count = (count % n + n) % n + 1
    if count > out_poly.shape[0]:
        return FULL
    total = chain_length(points, n, i_start, count, direction)
    s = 0.0
    for k in range(count):
        i = (i_start + k * direction + n * 4) % n
        if k > 0:
            ip = (i_start + (k - 1) * direction + n * 4) % n
            s += math.hypot(points[i, 0] - points[ip, 0], points[i, 1] - points[ip, 1])
        a = (i - tangent_span + n * 4) % n
        b = (i + tangent_span) % n
        t_r = points[b, 0] - points[a, 0]
        t_c = points[b, 1] - points[a, 1]
        norm = math.sqrt(t_r * t_r + t_c * t_c)
        shift = 0.0
        if total > 0.0:
            shift = max(0.0, 0.5 * (width_px - sweep_tip_px * s / total))
        if norm > 0.0:
            out_poly[k, 0] = points[i, 0] + shift * interior_sign * t_c / norm
            out_poly[k, 1] = points[i, 1] - shift * interior_sign * t_r / norm
        else:
            out_poly[k, 0] = points[i, 0]
            out_poly[k, 1] = points[i, 1]
    return count


@kernel(int32(f4_2d_ro, int32, f4_2d_ro, int32, f4_2d, f4_1d))
def midline(side_a, n_a, side_b, n_b, out_poly, out_dist):
    """Write the midline of two polylines running the same way (fixed end first): each point of `side_a` is
    paired with its nearest point on `side_b` (the search advancing monotonically), the midpoint goes to
    `out_poly` and the pair's distance to `out_dist`; returns `n_a` or FULL."""
    if n_a > out_poly.shape[0] or n_a > out_dist.shape[0]:
        return FULL
    if n_a < 1 or n_b < 1:
        return 0
    j = 0
    for i in range(n_a):
        ar = side_a[i, 0]
        ac = side_a[i, 1]
        best = math.hypot(ar - side_b[j, 0], ac - side_b[j, 1])
        while j + 1 < n_b:
            d = math.hypot(ar - side_b[j + 1, 0], ac - side_b[j + 1, 1])
            if d > best:
                break
            best = d
            j += 1
        # Foot of the perpendicular on the neighbouring segments of side B.
        br = side_b[j, 0]
        bc = side_b[j, 1]
        for jj in (j - 1, j):
            if jj < 0 or jj + 1 >= n_b:
                continue
            sr = side_b[jj + 1, 0] - side_b[jj, 0]
            sc = side_b[jj + 1, 1] - side_b[jj, 1]
            ss = sr * sr + sc * sc
            if ss <= 0.0:
                continue
            t = ((ar - side_b[jj, 0]) * sr + (ac - side_b[jj, 1]) * sc) / ss
            t = min(max(t, 0.0), 1.0)
            fr = side_b[jj, 0] + t * sr
            fc = side_b[jj, 1] + t * sc
            d = math.hypot(ar - fr, ac - fc)
            if d <= best:
                best = d
                br = fr
                bc = fc
        out_poly[i, 0] = 0.5 * (ar + br)
        out_poly[i, 1] = 0.5 * (ac + bc)
        out_dist[i] = best
    return n_a


# --------------------------------------------------------------------------------------------------------------
# Polylines and material points
# --------------------------------------------------------------------------------------------------------------
@kernel(float64(f4_2d_ro, int32))
def polyline_length(poly, n):
    """Return the length of the polyline of the first `n` points, eq. (9)."""
    total = 0.0
    for i in range(1, n):
        total += math.hypot(float(poly[i, 0]) - float(poly[i - 1, 0]), float(poly[i, 1]) - float(poly[i - 1, 1]))
    return total


@kernel(int32(f4_2d_ro, int32, float32, f4_2d))
def resample_polyline(poly, n, step_px, out_poly):
    """Resample the polyline at equal arc-length steps of at most `step_px`, keeping both ends; returns the count
    or FULL."""
    if n < 1:
        return 0
    total = polyline_length(poly, n)
    segments = max(1, math.ceil(total / step_px)) if total > 0.0 else 0
    if segments + 1 > out_poly.shape[0]:
        return FULL
    out_poly[0, 0] = poly[0, 0]
    out_poly[0, 1] = poly[0, 1]
    if segments == 0:
        return 1
    step = total / segments
    j = 0
    acc = 0.0
    seg_len = math.hypot(poly[1, 0] - poly[0, 0], poly[1, 1] - poly[0, 1]) if n > 1 else 0.0
    for k in range(1, segments):
        target = k * step
        while acc + seg_len < target and j + 2 < n:
            acc += seg_len
            j += 1
            seg_len = math.hypot(poly[j + 1, 0] - poly[j, 0], poly[j + 1, 1] - poly[j, 1])
        t = (target - acc) / seg_len if seg_len > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        out_poly[k, 0] = poly[j, 0] + t * (poly[j + 1, 0] - poly[j, 0])
        out_poly[k, 1] = poly[j, 1] + t * (poly[j + 1, 1] - poly[j, 1])
    out_poly[segments, 0] = poly[n - 1, 0]
    out_poly[segments, 1] = poly[n - 1, 1]
    return segments + 1


@kernel(int32(f4_2d_ro, int32, f8_1d_ro, float64, f4_2d))
def track_material_points(poly, n, arc_px, length0_px, out_points):
    """Locate material points on the polyline (fixed end first) by arc length with uniform stretch, eqs. (9)-(12).

    ``arc_px[k]`` is the unstretched distance of point k from the fixed end; with the polyline's length Lc and
    the unstretched length `length0_px` (Lc0) it sits at ``l' = arc_px[k] * Lc / Lc0``, interpolated between the
    polyline points bracketing it; beyond the ends it is clamped to them. Writes `out_points` (row, col); returns
    the number of points or INVALID (empty polyline, Lc0 <= 0).
    """
    m = arc_px.shape[0]
    if n < 1 or not length0_px > 0.0 or out_points.shape[0] < m:
        return INVALID
    total = polyline_length(poly, n)
    ratio = total / length0_px
    for k in range(m):
        target = arc_px[k] * ratio
        if n == 1 or target <= 0.0:
            out_points[k, 0] = poly[0, 0]
            out_points[k, 1] = poly[0, 1]
            continue
        acc = 0.0
        done = False
        for j in range(n - 1):
            seg = math.hypot(float(poly[j + 1, 0]) - float(poly[j, 0]), float(poly[j + 1, 1]) - float(poly[j, 1]))
            if acc + seg > target and seg > 0.0:
                t = (target - acc) / seg
                out_points[k, 0] = poly[j, 0] + t * (poly[j + 1, 0] - poly[j, 0])
                out_points[k, 1] = poly[j, 1] + t * (poly[j + 1, 1] - poly[j, 1])
                done = True
                break
            acc += seg
        if not done:
            out_points[k, 0] = poly[n - 1, 0]
            out_points[k, 1] = poly[n - 1, 1]
    return m


@kernel(int32(i4_2d_ro, int32, i4_1d_ro, i4_1d_ro, int32))
def count_roi_contacts(chain, n, lo, hi, width):
    """Return how many of the first `n` chain pixels have an 8-neighbour inside the image but outside the row
    spans `lo`/`hi` (the contour reaches the border of the region of interest)."""
    height = lo.shape[0]
    count = 0
    for i in range(n):
        r = chain[i, 0]
        c = chain[i, 1]
        for k in range(8):
            rr = r + DIR_ROW[k]
            cc = c + DIR_COL[k]
            if 0 <= rr < height and 0 <= cc < width and not in_spans(rr, cc, lo, hi):
                count += 1
                break
    return count


# --------------------------------------------------------------------------------------------------------------
# Polarity, rope width and gradient-based inward offsets
# --------------------------------------------------------------------------------------------------------------
@kernel(types.UniTuple(float32, 2)(f4_2d_ro, f4_2d_ro, f4_2d_ro, int32, int32))
def axis_offset(mag, gx, gy, r, c):
    """Return the (row, col) subpixel offset of the magnitude maximum at pixel (r, c) (as `refine_subpixel`)."""
    height = mag.shape[0]
    width = mag.shape[1]
    if r < 1 or c < 1 or r > height - 2 or c > width - 2:
        return np.float32(0.0), np.float32(0.0)
    m0 = mag[r, c]
    if abs(gx[r, c]) >= abs(gy[r, c]):
        mm = mag[r, c - 1]
        mp = mag[r, c + 1]
        denom = mm - 2.0 * m0 + mp
        if denom < 0.0:
            return np.float32(0.0), np.float32(min(max(0.5 * (mm - mp) / denom, -1.0), 1.0))
    else:
        mm = mag[r - 1, c]
        mp = mag[r + 1, c]
        denom = mm - 2.0 * m0 + mp
        if denom < 0.0:
            return np.float32(min(max(0.5 * (mm - mp) / denom, -1.0), 1.0)), np.float32(0.0)
    return np.float32(0.0), np.float32(0.0)


@kernel(int32(u1_2d_ro, f4_2d_ro, f4_2d_ro, f4_2d_ro, i4_2d_ro, int32, float32, float32, f4_1d))
def measure_widths(edges, mag, gx, gy, chain, n, polarity, max_px, out_width):
    """Write for each contour pixel the distance to the opposite edge of the rope, found by stepping (0.5 px)
    from the pixel into the rope (along ``polarity`` times the gradient) until an edge pixel whose gradient points
    the other way; both ends are refined to subpixel (parabola of `mag` along the image axis nearest the
    gradient) and the distance is taken along the stepping direction. ``nan`` when no opposite edge lies within
    `max_px`. Returns `n`."""
    height = edges.shape[0]
    width = edges.shape[1]
    for i in range(n):
        r = chain[i, 0]
        c = chain[i, 1]
        g_r = gy[r, c] * polarity
        g_c = gx[r, c] * polarity
        norm = math.sqrt(g_r * g_r + g_c * g_c)
        out_width[i] = np.nan
        if norm <= 0.0:
            continue
        u_r = g_r / norm
        u_c = g_c / norm
        steps = int(max_px * 2.0)
        for k in range(2, steps + 1):
            t = 0.5 * k
            rr = math.floor(r + t * u_r + 0.5)
            cc = math.floor(c + t * u_c + 0.5)
            if rr < 0 or rr >= height or cc < 0 or cc >= width:
                break
            if (rr != r or cc != c) and edges[rr, cc] != 0:
                dot = (gy[rr, cc] * u_r + gx[rr, cc] * u_c) * polarity
                if dot < 0.0:
                    d0r, d0c = axis_offset(mag, gx, gy, r, c)
                    d1r, d1c = axis_offset(mag, gx, gy, rr, cc)
                    out_width[i] = (rr + d1r - r - d0r) * u_r + (cc + d1c - c - d0c) * u_c
                    break
    return n


@kernel(int32(f4_1d_ro, int32, int32, i4_1d))
def find_caps(turn, n, min_gap, out_idx):
    """Write into `out_idx` the contour indices of the two rope ends: the largest turning angle, then the largest
    at least `min_gap` chain steps from it. Returns 2 or NOT_FOUND."""
    if n < 3:
        return NOT_FOUND
    e1 = 0
    for i in range(n):
        if turn[i] > turn[e1]:
            e1 = i
    e2 = -1
    best = -1.0
    for i in range(n):
        gap = abs(i - e1)
        if min(gap, n - gap) < min_gap:
            continue
        if turn[i] > best:
            best = turn[i]
            e2 = i
    if e2 < 0:
        return NOT_FOUND
    out_idx[0] = e1
    out_idx[1] = e2
    return 2


@kernel(int32(f4_2d_ro, i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, f4_2d_ro, float32, float32, float32, f4_2d))
def offset_by_gradient(
    points, chain, n, i_start, i_stop, direction, gx, gy, polarity, width_px, sweep_tip_px, out_poly
):
    """Copy the contour from `i_start` to `i_stop` (stepping `direction` = +1 or -1, cyclic) into `out_poly`,
    each point moved into the rope along ``polarity`` times its gradient direction by
    ``max(0, (width_px - sweep(s)) / 2)``, the sweep growing linearly with arc length s from 0 at `i_start` to
    `sweep_tip_px` at `i_stop` (see `offset_side`). The gradient knows where the rope is even where the contour
    doubles back (a rope leaving the image, a crossing). Returns the number of points written or FULL."""
    count = (i_stop - i_start) * direction
    count = (count % n + n) % n + 1
    if count > out_poly.shape[0]:
        return FULL
    total = chain_length(points, n, i_start, count, direction)
    s = 0.0
    for k in range(count):
        i = (i_start + k * direction + n * 4) % n
        if k > 0:
            ip = (i_start + (k - 1) * direction + n * 4) % n
            s += math.hypot(points[i, 0] - points[ip, 0], points[i, 1] - points[ip, 1])
        shift = 0.5 * width_px
        if total > 0.0:
            shift = max(0.0, 0.5 * (width_px - sweep_tip_px * s / total))
        r = chain[i, 0]
        c = chain[i, 1]
        g_r = gy[r, c] * polarity
        g_c = gx[r, c] * polarity
        norm = math.sqrt(g_r * g_r + g_c * g_c)
        out_poly[k, 0] = points[i, 0]
        out_poly[k, 1] = points[i, 1]
        if norm > 0.0:
            out_poly[k, 0] += shift * g_r / norm
            out_poly[k, 1] += shift * g_c / norm
    return count


@kernel(int32(f4_2d, int32, float32))
def trim_polyline_end(poly, n, cut_px):
    """Shorten the polyline of `n` points in place by `cut_px` of arc length at its end (the new last point is
    interpolated); returns the new count, or 0 when the polyline is not longer than `cut_px`."""
    remaining = cut_px
    k = n - 1
    while k > 0:
        seg = math.hypot(poly[k, 0] - poly[k - 1, 0], poly[k, 1] - poly[k - 1, 1])
        if seg >= remaining and seg > 0.0:
            t = remaining / seg
            poly[k, 0] = poly[k, 0] + t * (poly[k - 1, 0] - poly[k, 0])
            poly[k, 1] = poly[k, 1] + t * (poly[k - 1, 1] - poly[k, 1])
            return k + 1
        remaining -= seg
        k -= 1
    return 0


@kernel(int32(f4_2d, int32, f4_2d_ro, int32, float32, float32))
def extend_to_band_end(poly, n, points, n_points, width_px, cap_px):
    """Move the free end of the axis polyline `poly` (n points) to where the band ends along that axis.

    The axis direction is taken over the last 3 widths of arc; the band's end along it is the farthest of the
    contour `points` lying within half a width of the axis line (and within -2 to +4 widths of the current end);
    the tip goes `cap_px` short of it (half a width for a round rope end). The polyline is extended along the
    axis or shortened (`trim_polyline_end`) in place. Returns the new point count (unchanged when nothing is
    found).
    """
    if n < 3:
        return n
    back = 0.0
    k = n - 1
    while k > 0 and back < 3.0 * width_px:
        back += math.hypot(poly[k, 0] - poly[k - 1, 0], poly[k, 1] - poly[k - 1, 1])
        k -= 1
    base_r = poly[n - 1, 0]
    base_c = poly[n - 1, 1]
    dir_r = base_r - poly[k, 0]
    dir_c = base_c - poly[k, 1]
    norm = math.sqrt(dir_r * dir_r + dir_c * dir_c)
    if norm < 1e-6:
        return n
    dir_r /= norm
    dir_c /= norm
    best = -1e30
    for i in range(n_points):
        rel_r = points[i, 0] - base_r
        rel_c = points[i, 1] - base_c
        along = rel_r * dir_r + rel_c * dir_c
        across = abs(rel_r * dir_c - rel_c * dir_r)
        if across < 0.5 * width_px and -2.0 * width_px < along < 4.0 * width_px and along > best:
            best = along
    if best < -1e29:
        return n
    extent = best - cap_px
    if extent >= 0.0:
        poly[n - 1, 0] = base_r + extent * dir_r
        poly[n - 1, 1] = base_c + extent * dir_c
        return n
    count = trim_polyline_end(poly, n, -extent)
    return count if count >= 2 else n


@kernel(int32(i4_2d_ro, int32, int32, int32, int32, f4_2d_ro, float32, float32, f4_1d))
def side_slope_samples(chain, n, i_fix, i_seg, direction, mag, lo_frac, hi_frac, out_values):
    """Write the gradient magnitude at the chain pixels of one side (from `i_fix` stepping `direction` to
    `i_seg`) whose arc fraction lies in [lo_frac, hi_frac) into `out_values`, each followed by its fraction:
    ``out_values[2k] = mag``, ``out_values[2k + 1] = fraction`` (fraction by index, the chain being
    8-connected). Returns the number of pairs written or FULL."""
    count = ((i_seg - i_fix) * direction % n + n) % n + 1
    if count < 2:
        return 0
    m = 0
    for k in range(count):
        frac = k / (count - 1)
        if frac < lo_frac or frac >= hi_frac:
            continue
        if 2 * m + 1 >= out_values.shape[0]:
            return FULL
        i = (i_fix + k * direction + 4 * n) % n
        out_values[2 * m] = mag[chain[i, 0], chain[i, 1]]
        out_values[2 * m + 1] = frac
        m += 1
    return m
