"""The edge stage's kernel, `detect_edges`: the passes of `canny`, fused into sweeps where the band allows.

Run pass after pass, each pass reads a band (~60 KB per plane on the rig) that the previous one left in L2. Off
the image border (no replicated pixels, every padded span in the image), two sweeps do the work instead:
`smooth_ring` (horizontal smoothing of row r + 2 into a ring of 8 rows, then vertical smoothing of row r) and
`sobel_suppress` (Sobel of row r + 1, then non-maximum suppression of row r), each row read from L1 just after it
is written; elsewhere the pass kernels of `canny` run. Both ways give bit-identical outputs (the same float32
expressions in the same order, in the 8-column steps of `canny_simd`).
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numba import float32, int32, int64

from ropecam.device.pipeline._kernels._common import EDGE_NONE, INVALID, f4_1d_ro, prefetch_read, prefetch_write
from ropecam.device.pipeline._kernels.canny import (
    AHEAD,
    VEC,
    finish_edges,
    grow_edges,
    grow_spans_inplace,
    grow_spans_once,
    padded_end,
    smooth_columns,
    smooth_rows,
    sobel_rows,
    suppress_rows,
)
from ropecam.device.pipeline._kernels.canny_simd import LANES, hsmooth8, nms8, sobel8, vsmooth8
from ropecam.shared.jit import f4_2d, i4_1d, i4_1d_ro, i4_2d, kernel, u1_2d, u1_2d_ro

RING: Final = 8
"""Rows of the horizontal smoothing `smooth_ring` keeps (the first rows of `out_tmp`; 5 are read at a time)."""


@kernel(int64(u1_2d_ro, f4_1d_ro, i4_1d, i4_1d, i4_1d, i4_1d, int64, int64, f4_2d, f4_2d))
def smooth_ring(frame, weights, hor_lo, hor_hi, gau_lo, gau_hi, r_begin, r_end, out_tmp, out_smooth):
    """`smooth_rows` then `smooth_columns` for the 5-tap smoothing in one sweep, when every row is off the image
    border: the horizontal pass of row ``r + 2`` goes into a ring of 8 rows (the first rows of `out_tmp`) just
    before the vertical pass of row ``r`` reads it, so that it stays in L1. Writes `out_smooth` over the spans
    `gau_lo`/`gau_hi` of the rows ``r_begin .. r_end`` (padded to whole vectors; the horizontal spans
    `hor_lo`/`hor_hi` are valid for rows ``r_begin - 2 .. r_end + 2``), bit-identical to the two passes. Returns 1,
    or 0 without writing anything when a row or padded span comes within 2 of the image border or `weights` has
    not 5 taps (then the two passes do it)."""
    height = frame.shape[0]
    width = frame.shape[1]
    if weights.shape[0] != 5 or height < RING or r_begin < 2 or r_end > height - 3:
        return 0
    for r in range(r_begin - 2, r_end + 3):
        if hor_hi[r] >= hor_lo[r]:
            c0 = np.int64(hor_lo[r])
            c0 -= c0 % VEC
            if c0 < 2 or padded_end(c0, np.int64(hor_hi[r]), width) > width - 3:
                return 0
    size = height * width
    f = frame.reshape(size)
    tmp = out_tmp.reshape(size)
    smo = out_smooth.reshape(size)
    w0 = weights[0]
    w1 = weights[1]
    w2 = weights[2]
    mask = np.int64(RING - 1)
    for j in range(r_begin - 2, r_end + 3):
        ahead = j + AHEAD
        if ahead <= r_end + 2 and hor_hi[ahead] >= hor_lo[ahead]:
            first = ahead * width + np.int64(hor_lo[ahead]) - 2
            last = ahead * width + np.int64(hor_hi[ahead]) + 2
            prefetch_read(f, np.uint64(first))  # a fixed number of lines: no loop exit to mispredict per row
            prefetch_read(f, np.uint64(min(first + 64, last)))
            prefetch_read(f, np.uint64(last))
        if hor_hi[j] >= hor_lo[j]:  # horizontal pass of row j into its ring row
            c0 = np.int64(hor_lo[j])
            c0 -= c0 % VEC
            c1 = padded_end(c0, np.int64(hor_hi[j]), width)
            src = np.uint64(j * width + c0)
            dst = np.uint64((j & mask) * width + c0)
            for step in range((c1 - c0 + 1) // LANES):
                us = np.uint64(step * LANES)
                hsmooth8(f, src + us, w0, w1, w2, tmp, dst + us)
        r = j - 2  # vertical pass of row r from the ring rows r - 2 .. r + 2
        if r < r_begin:
            continue
        ahead = r + AHEAD
        if ahead <= r_end and gau_hi[ahead] >= gau_lo[ahead]:
            first = ahead * width + np.int64(gau_lo[ahead])
            last = ahead * width + np.int64(gau_hi[ahead])
            for k in range(4):  # the first 64 columns and the last
                prefetch_write(smo, np.uint64(min(first + 16 * k, last)))
            prefetch_write(smo, np.uint64(last))
        if gau_hi[r] < gau_lo[r]:
            continue
        c0 = np.int64(gau_lo[r])
        c0 -= c0 % VEC
        c1 = padded_end(c0, np.int64(gau_hi[r]), width)
        ka = np.uint64(((r - 2) & mask) * width + c0)
        kb = np.uint64(((r - 1) & mask) * width + c0)
        kc = np.uint64((r & mask) * width + c0)
        kd = np.uint64(((r + 1) & mask) * width + c0)
        ke = np.uint64(((r + 2) & mask) * width + c0)
        out = np.uint64(r * width + c0)
        for step in range((c1 - c0 + 1) // LANES):
            us = np.uint64(step * LANES)
            vsmooth8(tmp, ka + us, kb + us, kc + us, kd + us, ke + us, w0, w1, w2, smo, out + us)
    return 1


@kernel(
    int64(f4_2d, i4_1d_ro, i4_1d_ro, i4_1d, i4_1d, int64, int64, float32, float32, f4_2d, f4_2d, f4_2d, u1_2d, i4_1d)
)
def sobel_suppress(
    smooth, lo, hi, sob_lo, sob_hi, r_begin, r_end, low, high, out_gx, out_gy, out_mag, out_edges, stack
):
    """`sobel_rows` then `suppress_rows` in one sweep, when every Sobel row and padded span is off the image
    border: the Sobel row ``r + 1`` is computed just before the suppression of row ``r`` reads it (from L1).
    Arguments and outputs are those of the two passes (`r_begin .. r_end`: the rows of the spans `lo`/`hi`; the
    Sobel spans `sob_lo`/`sob_hi` valid for ``r_begin - 1 .. r_end + 1``), bit-identical. Returns the number of
    strong pixels pushed onto `stack`, or -1 without writing anything when a row comes to the image border."""
    height = smooth.shape[0]
    width = smooth.shape[1]
    sob_begin = r_begin - 1
    sob_end = r_end + 1
    if sob_begin < 1 or sob_end > height - 2:
        return -1
    for r in range(sob_begin, sob_end + 1):
        if sob_hi[r] >= sob_lo[r]:
            c0 = np.int64(sob_lo[r])
            c0 -= c0 % VEC
            if c0 < 1 or padded_end(c0, np.int64(sob_hi[r]), width) > width - 2:
                return -1
    size = height * width
    smo = smooth.reshape(size)
    ogx = out_gx.reshape(size)
    ogy = out_gy.reshape(size)
    omag = out_mag.reshape(size)
    oedge = out_edges.reshape(size)
    top = 0
    for j in range(sob_begin, sob_end + 2):
        ahead = j + AHEAD
        if ahead <= sob_end and sob_hi[ahead] >= sob_lo[ahead]:
            first = ahead * width + np.int64(sob_lo[ahead])
            last = ahead * width + np.int64(sob_hi[ahead])
            for k in range(4):  # the first 64 columns and the last
                at = np.uint64(min(first + 16 * k, last))
                prefetch_write(ogx, at)
                prefetch_write(ogy, at)
                prefetch_write(omag, at)
            prefetch_write(oedge, np.uint64(first))
            prefetch_write(ogx, np.uint64(last))
            prefetch_write(ogy, np.uint64(last))
            prefetch_write(omag, np.uint64(last))
            prefetch_write(oedge, np.uint64(last))
        if j <= sob_end and sob_hi[j] >= sob_lo[j]:  # Sobel of row j
            c0 = np.int64(sob_lo[j])
            c0 -= c0 % VEC
            c1 = padded_end(c0, np.int64(sob_hi[j]), width)
            k0 = np.uint64(j * width + c0)
            km = k0 - np.uint64(width)
            kp = k0 + np.uint64(width)
            for step in range((c1 - c0 + 1) // LANES):
                us = np.uint64(step * LANES)
                sobel8(smo, km + us, k0 + us, kp + us, ogx, ogy, omag)
        r = j - 1  # suppression of row r
        if r < sob_begin:
            continue
        row = r * width
        s0 = np.int64(sob_lo[r])
        s1 = np.int64(sob_hi[r])
        c0 = np.int64(lo[r])
        c1 = np.int64(hi[r])
        if c1 < c0 or r < r_begin or r > r_end:
            for c in range(s0, s1 + 1):
                oedge[row + c] = EDGE_NONE
            continue
        for c in range(s0, c0):
            oedge[row + c] = EDGE_NONE
        for c in range(c1 + 1, s1 + 1):
            oedge[row + c] = EDGE_NONE
        p0 = c0 - c0 % VEC
        p1 = padded_end(p0, c1, width)
        for step in range((p1 - p0 + 1) // LANES):
            offset = p0 + step * LANES
            k = np.uint64(row + offset)
            bits = nms8(omag, ogx, ogy, k, width, c0 - offset, c1 - offset, low, high, oedge)
            if bits:
                for lane in range(LANES):
                    stack[top] = np.int32(k + np.uint64(lane))
                    top += (bits >> lane) & 1
    return top


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
    replicated border, the magnitude is the L2 norm. Writes `work_spans` (rows 0-1: Sobel spans, the spans
    grown by one row and column; rows 2-3: smoothing spans, grown by two), `out_tmp`, `out_smooth` (valid inside
    the smoothing spans), `out_gx`, `out_gy`, `out_mag` (valid inside the Sobel spans) and `out_edges` (1 on edge
    pixels, 0 elsewhere inside the Sobel spans; valid inside the spans `lo`/`hi`); `stack` needs one slot per
    pixel of the image and holds on return the edge pixels' flat indices ``row * width + col`` (the first
    `count`: the strong pixels in raster order, then the weak ones joined to them). Returns the number of edge
    pixels or INVALID (bad shapes).
    """
    height = frame.shape[0]
    width = frame.shape[1]
    if lo.shape[0] != height or hi.shape[0] != height or work_spans.shape[0] < 4 or work_spans.shape[1] != height:
        return INVALID
    if stack.shape[0] < height * width or weights.shape[0] % 2 != 1:
        return INVALID
    r_first = height
    r_last = -1
    for r in range(height):
        if min(hi[r], width - 1) >= max(lo[r], 0):
            r_first = min(r_first, r)
            r_last = r
    if r_last < 0:
        return 0
    sob_lo = work_spans[0]
    sob_hi = work_spans[1]
    gau_lo = work_spans[2]
    gau_hi = work_spans[3]
    # Spans grown row by row (a window of three rows each time): Sobel spans (one row and column around the
    # spans), smoothing spans (two), and the union of the smoothing spans of the rows each horizontal smoothing
    # row feeds (rows 0-1 of `work_spans` hold it until the Sobel spans are needed).
    radius = weights.shape[0] // 2
    sob_begin = max(r_first - 1, 0)
    sob_end = min(r_last + 1, height - 1)
    gau_begin = max(r_first - 2, 0)
    gau_end = min(r_last + 2, height - 1)
    grow_spans_once(lo, hi, r_first, r_last, width, gau_lo, gau_hi)
    grow_spans_inplace(sob_begin, sob_end, 1, width, gau_lo, gau_hi)
    hor_begin = gau_begin
    hor_end = gau_end
    for r in range(hor_begin, hor_end + 1):
        sob_lo[r] = gau_lo[r]
        sob_hi[r] = gau_hi[r]
    for _ in range(radius):
        grow_spans_inplace(hor_begin, hor_end, 0, width, sob_lo, sob_hi)
        hor_begin = max(hor_begin - 1, 0)
        hor_end = min(hor_end + 1, height - 1)
    if not smooth_ring(frame, weights, sob_lo, sob_hi, gau_lo, gau_hi, gau_begin, gau_end, out_tmp, out_smooth):
        smooth_rows(frame, weights, sob_lo, sob_hi, hor_begin, hor_end, out_tmp)
        smooth_columns(out_tmp, weights, gau_lo, gau_hi, gau_begin, gau_end, out_smooth)
    grow_spans_once(lo, hi, r_first, r_last, width, sob_lo, sob_hi)
    top = sobel_suppress(
        out_smooth, lo, hi, sob_lo, sob_hi, r_first, r_last, low, high, out_gx, out_gy, out_mag, out_edges, stack
    )
    if top < 0:
        sobel_rows(out_smooth, sob_lo, sob_hi, sob_begin, sob_end, out_gx, out_gy, out_mag)
        top = suppress_rows(
            out_mag, out_gx, out_gy, lo, hi, sob_lo, sob_hi, r_first, r_last, low, high, out_edges, stack
        )
    count = grow_edges(lo, hi, top, out_edges, stack)
    finish_edges(lo, hi, r_first, r_last, out_edges)
    return count
