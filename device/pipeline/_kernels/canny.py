"""Canny edge detection on row spans: non-maximum suppression, hysteresis, and `detect_edges`, the whole sequence.

One kernel per pass, each a loop over the rows of the region of interest; `detect_edges` runs them in order where
a band reaches the image border. Off the border (the usual band), two sweeps do the work instead: `smooth_ring`
(horizontal smoothing of row r + 2 into a ring of 8 rows, then vertical smoothing of row r) and `sobel_suppress`
(Sobel of row r + 1, then non-maximum suppression of row r), each row read from L1 just after it is written
(pass after pass, each read a band of ~60 KB per plane that the previous one had left in L2). Both ways give
bit-identical outputs: the same float32 expressions in the same order, in the 8-column steps of `canny_simd`.
The smoothing and Sobel passes are in `canny_gradient` (the package drops its caches when either file changes).
A band around a rope is a few hundred short rows (~40 px each on the rig), so what a pass costs per row matters
as much as what it costs per pixel: the loops index flat views with unsigned offsets (no wraparound test, no
slice objects), run branch-free over contiguous columns so that LLVM vectorises them, and the arithmetic passes
(smoothing, Sobel) run over the row's span padded to whole vectors of `VEC` columns (no scalar remainder loop
after the vector loop, whose trip count would change from row to row and mispredict). Values in the padding are
computed from whatever the planes hold there and are not valid; every output is valid where documented.
"""

from __future__ import annotations

import numpy as np
from numba import float32, int32, int64, uint8, void

from ropecam.device.pipeline._kernels._common import (
    DIR_COL,
    DIR_ROW,
    EDGE_NONE,
    EDGE_STRONG,
    EDGE_WEAK,
    INVALID,
    TAN_22_5,
    TWO,
    ZERO,
    f4_1d_ro,
    prefetch_write,
)
from ropecam.device.pipeline._kernels.canny_gradient import (
    AHEAD,
    VEC,
    grow_spans,
    padded_end,
    smooth_columns,
    smooth_ring,
    smooth_rows,
    sobel_rows,
)
from ropecam.device.pipeline._kernels.canny_simd import LANES, nms8, push_lanes8, sobel8
from ropecam.shared.jit import (
    f4_2d,
    i4_1d,
    i4_1d_ro,
    i4_2d,
    kernel,
    u1_2d,
    u1_2d_ro,
)


@kernel(uint8(f4_2d, f4_2d, f4_2d, int64, int64, float32, float32))
def nms_pixel(mag, gx, gy, r, c, low, high):
    """Return the non-maximum suppression label of pixel (r, c) (EDGE_NONE, EDGE_WEAK, EDGE_STRONG) with
    OpenCV's sector rule and tie-breaking; neighbours outside the image count as 0."""
    height = mag.shape[0]
    width = mag.shape[1]
    m = mag[r, c]
    if not m > low:
        return EDGE_NONE
    ax = abs(gx[r, c])
    ay = abs(gy[r, c])
    if ay < ax * TAN_22_5:
        ml = mag[r, c - 1] if c > 0 else ZERO
        mr = mag[r, c + 1] if c < width - 1 else ZERO
        keep = m > ml and m >= mr
    elif ay > ax * (TAN_22_5 + TWO):
        mu = mag[r - 1, c] if r > 0 else ZERO
        md = mag[r + 1, c] if r < height - 1 else ZERO
        keep = m > mu and m >= md
    else:
        s = -1 if gx[r, c] * gy[r, c] < 0 else 1
        mu = mag[r - 1, c - s] if (r > 0 and 0 <= c - s < width) else ZERO
        md = mag[r + 1, c + s] if (r < height - 1 and 0 <= c + s < width) else ZERO
        keep = m > mu and m > md
    if not keep:
        return EDGE_NONE
    return EDGE_STRONG if m > high else EDGE_WEAK


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
            c1 = np.int64(sob_hi[r])
            if c0 < 1 or padded_end(c0, c1, width) > width - 2:
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
            c0 = s1 + 1  # no pixel to label: only the ring around the spans is cleared
            c1 = s1
        # Steps over the Sobel span (all inside the image): the spans' pixels labelled, the ring around them set
        # to EDGE_NONE in the same store (no scalar loops of 1-3 columns whose exits mispredict). The first step
        # starts at the span's first column, as the Sobel steps do, not at the multiple of 8 before it (0.4 steps
        # fewer per row on the rig; docs/speed.md, ledger rows edges7). Nothing reads the gradients outside the
        # Sobel spans (`measure_widths` stops at the spans since edges7).
        p0 = s0
        p1 = padded_end(p0, s1, width)
        for step in range((p1 - p0 + 1) // LANES):
            offset = p0 + step * LANES
            k = np.uint64(row + offset)
            bits = nms8(omag, ogx, ogy, k, width, c0 - offset, c1 - offset, s0 - offset, s1 - offset, low, high, oedge)
            top = push_lanes8(stack, top, k, bits)
    return top


@kernel(int64(f4_2d, f4_2d, f4_2d, i4_1d_ro, i4_1d_ro, i4_1d, i4_1d, int64, int64, float32, float32, u1_2d, i4_1d))
def suppress_rows(mag, gx, gy, lo, hi, sob_lo, sob_hi, r_begin, r_end, low, high, out_edges, stack):
    """Non-maximum suppression over the spans `lo`/`hi` of the rows ``r_begin .. r_end``: write the labels
    (EDGE_NONE, EDGE_WEAK, EDGE_STRONG) into `out_edges`, EDGE_NONE on the rest of the Sobel spans
    `sob_lo`/`sob_hi` (the ring around the spans, so that the hysteresis never leaves them), and push the strong
    pixels' flat indices onto `stack`, in raster order. Returns the number pushed."""
    height = mag.shape[0]
    width = mag.shape[1]
    size = height * width
    omag = mag.reshape(size)
    ogx = gx.reshape(size)
    ogy = gy.reshape(size)
    oedge = out_edges.reshape(size)
    uw = np.uint64(width)
    u1 = np.uint64(1)
    top = 0
    for r in range(max(r_begin - 1, 0), min(r_end + 1, height - 1) + 1):
        ahead = min(r + AHEAD, height - 1)
        if sob_hi[ahead] >= sob_lo[ahead]:
            first = ahead * width + np.int64(sob_lo[ahead])
            last = ahead * width + np.int64(sob_hi[ahead])
            for k in range(first, last + 1, 64):
                prefetch_write(oedge, np.uint64(k))
            prefetch_write(oedge, np.uint64(last))
        c0 = max(np.int64(lo[r]), 0)
        c1 = min(np.int64(hi[r]), width - 1)
        row = r * width
        s0 = np.int64(sob_lo[r])
        s1 = np.int64(sob_hi[r])
        if c1 < c0:
            for c in range(s0, s1 + 1):
                oedge[row + c] = EDGE_NONE
            continue
        for c in range(s0, c0):
            oedge[row + c] = EDGE_NONE
        for c in range(c1 + 1, s1 + 1):
            oedge[row + c] = EDGE_NONE
        i0 = c0
        i1 = c1
        if 0 < r < height - 1:
            i0 = max(c0, 1)
            i1 = min(c1, width - 2)
            if i1 >= i0:
                p0 = i0 - i0 % VEC
                p1 = padded_end(p0, i1, width)
                if p0 >= 1 and p1 <= width - 2 and i0 == c0 and i1 == c1:
                    # Whole 8-column steps, off the image border: labels and strong seeds at once.
                    for step in range((p1 - p0 + 1) // LANES):
                        k = np.uint64(row + p0 + step * LANES)
                        offset = p0 + step * LANES
                        bits = nms8(omag, ogx, ogy, k, width, i0 - offset, i1 - offset, 1, 0, low, high, oedge)
                        top = push_lanes8(stack, top, k, bits)
                    continue
                p0 = i0  # near the image border: no padding
                p1 = i1
                # Branch-free (all eight neighbours loaded, the pair of the gradient's sector selected): the
                # labels of `nms_pixel`, written only in ``i0 .. i1`` (the loop runs over whole vectors).
                base = np.uint64(row + p0)
                k_first = np.uint64(row + i0)
                k_last = np.uint64(row + i1)
                for i in range(p1 - p0 + 1):
                    k = base + np.uint64(i)
                    m = omag[k]
                    gxv = ogx[k]
                    gyv = ogy[k]
                    ax = abs(gxv)
                    ay = abs(gyv)
                    horizontal = ay < ax * TAN_22_5
                    vertical = ay > ax * (TAN_22_5 + TWO)
                    falling = gxv * gyv < 0  # the diagonal pair is up-right/down-left, else up-left/down-right
                    up_left = omag[k - uw - u1]
                    up = omag[k - uw]
                    up_right = omag[k - uw + u1]
                    left = omag[k - u1]
                    right = omag[k + u1]
                    down_left = omag[k + uw - u1]
                    down = omag[k + uw]
                    down_right = omag[k + uw + u1]
                    diag_a = up_right if falling else up_left
                    diag_b = down_left if falling else down_right
                    a = left if horizontal else (up if vertical else diag_a)
                    b = right if horizontal else (down if vertical else diag_b)
                    diagonal = not (horizontal or vertical)
                    keep = (m > low) & (m > a) & ((m > b) | ((m == b) & (not diagonal)))
                    label = np.uint8(keep) * (np.uint8(1) + np.uint8(m > high))
                    oedge[k] = label if (k >= k_first) & (k <= k_last) else oedge[k]
            for c in range(c0, i0):  # column 0
                oedge[row + c] = nms_pixel(mag, gx, gy, r, c, low, high)
            for c in range(i1 + 1, c1 + 1):  # column width - 1
                oedge[row + c] = nms_pixel(mag, gx, gy, r, c, low, high)
        else:
            for c in range(c0, c1 + 1):  # rows 0 and height - 1
                oedge[row + c] = nms_pixel(mag, gx, gy, r, c, low, high)
        # The strong pixels seed the hysteresis: looked for 8 at a time (few chunks hold one), then one by one.
        base = np.uint64(row + c0)
        n = c1 - c0 + 1
        j = 0
        while j + 8 <= n:
            chunk = base + np.uint64(j)
            labels = np.uint8(0)
            for i in range(8):
                labels |= oedge[chunk + np.uint64(i)]
            if labels & EDGE_STRONG:
                for i in range(8):
                    k = chunk + np.uint64(i)
                    stack[top] = np.int32(k)
                    top += np.int64(oedge[k] >> 1)
            j += 8
        for i in range(j, n):
            k = base + np.uint64(i)
            stack[top] = np.int32(k)
            top += np.int64(oedge[k] >> 1)
    return top


@kernel(int64(i4_1d_ro, i4_1d_ro, int64, u1_2d, i4_1d))
def grow_edges(lo, hi, top, out_edges, stack):
    """Hysteresis: mark EDGE_STRONG every EDGE_WEAK pixel of `out_edges` 8-connected to the strong pixels whose
    flat indices are ``stack[:top]``, never leaving the spans `lo`/`hi`; the pixels marked are appended to
    `stack` (breadth first), which then lists every edge pixel. Returns their number."""
    height = out_edges.shape[0]
    width = out_edges.shape[1]
    oedge = out_edges.reshape(height * width)
    head = 0
    # Inside the spans and off the image border every neighbour is in the image, and the ring around the spans
    # holds EDGE_NONE (`suppress_rows`): then a weak neighbour is always inside the spans, no test needed.
    inner = True
    for r in range(height):
        if hi[r] >= lo[r] and (r == 0 or r == height - 1 or lo[r] < 1 or hi[r] > width - 2):
            inner = False
    if inner:
        offsets = (-width - 1, -width, -width + 1, -1, 1, width - 1, width, width + 1)
        while head < top:
            k = np.int64(stack[head])
            head += 1
            for o in offsets:
                kk = np.uint64(k + o)
                if oedge[kk] == EDGE_WEAK:
                    oedge[kk] = EDGE_STRONG
                    stack[top] = np.int32(kk)
                    top += 1
        return top
    while head < top:
        r = stack[head] // width
        c = stack[head] - r * width
        head += 1
        for k in range(8):
            rr = r + DIR_ROW[k]
            cc = c + DIR_COL[k]
            if 0 <= rr < height and lo[rr] <= cc <= hi[rr] and cc < width and out_edges[rr, cc] == EDGE_WEAK:
                out_edges[rr, cc] = EDGE_STRONG
                stack[top] = rr * width + cc
                top += 1
    return top


@kernel(void(i4_1d_ro, i4_1d_ro, int64, int64, u1_2d))
def finish_edges(lo, hi, r_begin, r_end, out_edges):
    """Turn the labels in the spans `lo`/`hi` of rows ``r_begin .. r_end`` into 1 (EDGE_STRONG) and 0 (the
    rest)."""
    height = out_edges.shape[0]
    width = out_edges.shape[1]
    oedge = out_edges.reshape(height * width)
    for r in range(r_begin, r_end + 1):
        c0 = max(np.int64(lo[r]), 0)
        c1 = min(np.int64(hi[r]), width - 1)
        if c1 < c0:
            continue
        base = np.uint64(r * width + c0)
        for i in range(c1 - c0 + 1):
            k = base + np.uint64(i)
            oedge[k] = oedge[k] >> 1  # EDGE_STRONG -> 1, weak and none -> 0


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
    grow_spans(lo, hi, r_first, r_last, 1, width, gau_lo, gau_hi)
    grow_spans(gau_lo, gau_hi, sob_begin, sob_end, 1, width, gau_lo, gau_hi)
    hor_begin = gau_begin
    hor_end = gau_end
    for r in range(hor_begin, hor_end + 1):
        sob_lo[r] = gau_lo[r]
        sob_hi[r] = gau_hi[r]
    for _ in range(radius):
        grow_spans(sob_lo, sob_hi, hor_begin, hor_end, 0, width, sob_lo, sob_hi)
        hor_begin = max(hor_begin - 1, 0)
        hor_end = min(hor_end + 1, height - 1)
    if not smooth_ring(frame, weights, sob_lo, sob_hi, gau_lo, gau_hi, gau_begin, gau_end, out_tmp, out_smooth):
        smooth_rows(frame, weights, sob_lo, sob_hi, hor_begin, hor_end, out_tmp)
        smooth_columns(out_tmp, weights, gau_lo, gau_hi, gau_begin, gau_end, out_smooth)
    grow_spans(lo, hi, r_first, r_last, 1, width, sob_lo, sob_hi)
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
