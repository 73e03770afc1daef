"""Canny edge detection on row spans: smoothing, Sobel, non-maximum suppression, hysteresis."""

from __future__ import annotations

import numpy as np
from numba import float32, int32, void

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
)
from ropecam.device.pipeline._kernels.spans import grow_spans
from ropecam.shared.jit import (
    f4_2d,
    i4_1d,
    i4_1d_ro,
    i4_2d,
    kernel,
    u1_2d,
    u1_2d_ro,
)


@kernel(void(f4_2d, i4_1d, i4_1d, f4_2d, f4_2d, f4_2d))
def sobel_rows(smooth, sob_lo, sob_hi, out_gx, out_gy, out_mag):
    """Write the 3x3 Sobel gradients of `smooth` and their L2 norm inside the row spans `sob_lo`/`sob_hi` (clipped
    to the image), replicating the image border."""
    height = smooth.shape[0]
    width = smooth.shape[1]
    size = height * width
    smo = smooth.reshape(size)
    ogx = out_gx.reshape(size)
    ogy = out_gy.reshape(size)
    omag = out_mag.reshape(size)
    u1 = np.uint64(1)
    for r in range(height):
        c0 = np.int64(sob_lo[r])
        c1 = min(np.int64(sob_hi[r]), width - 1)
        if c1 < c0:
            continue
        rm = max(r - 1, 0) * width
        r0 = r * width
        rp = min(r + 1, height - 1) * width
        for c in (0, width - 1):  # on the image border: replicate it
            if c < c0 or c > c1:
                continue
            cm = max(c - 1, 0)
            cp = min(c + 1, width - 1)
            gx = (smo[rm + cp] + TWO * smo[r0 + cp] + smo[rp + cp]) - (smo[rm + cm] + TWO * smo[r0 + cm] + smo[rp + cm])
            gy = (smo[rp + cm] + TWO * smo[rp + c] + smo[rp + cp]) - (smo[rm + cm] + TWO * smo[rm + c] + smo[rm + cp])
            ogx[r0 + c] = gx
            ogy[r0 + c] = gy
            omag[r0 + c] = np.sqrt(gx * gx + gy * gy)
        i0 = max(c0, 1)
        i1 = min(c1, width - 2)
        km = np.uint64(rm + i0)
        k0 = np.uint64(r0 + i0)
        kp = np.uint64(rp + i0)
        for i in range(i1 - i0 + 1):
            ui = np.uint64(i)
            a = km + ui
            b = k0 + ui
            d = kp + ui
            gx = (smo[a + u1] + TWO * smo[b + u1] + smo[d + u1]) - (smo[a - u1] + TWO * smo[b - u1] + smo[d - u1])
            gy = (smo[d - u1] + TWO * smo[d] + smo[d + u1]) - (smo[a - u1] + TWO * smo[a] + smo[a + u1])
            ogx[b] = gx
            ogy[b] = gy
            omag[b] = np.sqrt(gx * gx + gy * gy)


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
    pixel of the image and holds on return the edge pixels' flat indices ``row * width + col`` in raster order
    (the first `count`). Returns the number of edge pixels or INVALID (bad shapes).
    """
    height = frame.shape[0]
    width = frame.shape[1]
    radius = weights.shape[0] // 2
    if lo.shape[0] != height or hi.shape[0] != height or work_spans.shape[0] < 4 or work_spans.shape[1] != height:
        return INVALID
    if stack.shape[0] < height * width:
        return INVALID
    # Hot loops index flat views with unsigned offsets: Numba then emits no negative-index wraparound and no
    # per-row slice objects (each slice costs reference counting), so short row spans stay cheap and the loops
    # vectorise. The arithmetic (and its order) is the same as the obvious per-pixel formulas.
    size = height * width
    f = frame.reshape(size)
    tmp = out_tmp.reshape(size)
    smo = out_smooth.reshape(size)
    ogx = out_gx.reshape(size)
    ogy = out_gy.reshape(size)
    omag = out_mag.reshape(size)
    oedge = out_edges.reshape(size)
    u1 = np.uint64(1)
    u2 = np.uint64(2)
    uw = np.uint64(width)
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
    hor_lo = work_spans[0]
    hor_hi = work_spans[1]
    grow_spans(gau_lo, gau_hi, radius, 0, hor_lo, hor_hi)
    w0 = weights[0]
    w1 = weights[min(1, 2 * radius)]
    w2 = weights[min(2, 2 * radius)]
    for r in range(height):
        c0 = np.int64(hor_lo[r])
        c1 = min(np.int64(hor_hi[r]), width - 1)
        if c1 < c0:
            continue
        row = r * width
        inner0 = max(c0, radius)
        inner1 = min(c1, width - 1 - radius)
        if inner1 >= inner0:
            base = np.uint64(row + inner0)
            if radius == 2:
                # The default smoothing (sigma 1 px): one fused loop.
                for i in range(inner1 - inner0 + 1):
                    k = base + np.uint64(i)
                    t = w0 * (np.float32(f[k - u2]) + np.float32(f[k + u2])) + w1 * (
                        np.float32(f[k - u1]) + np.float32(f[k + u1])
                    )
                    t += w2 * np.float32(f[k])
                    tmp[k] = t
            else:
                for i in range(inner1 - inner0 + 1):
                    k = base + np.uint64(i)
                    t = ZERO
                    for j in range(2 * radius + 1):
                        t += weights[j] * np.float32(f[k + np.uint64(j) - np.uint64(radius)])
                    tmp[k] = t
        # Columns within `radius` of the image border: replicate the edge pixel.
        for c in range(c0, min(c1 + 1, max(inner0, c0))):
            acc = ZERO
            for k in range(-radius, radius + 1):
                acc += weights[k + radius] * frame[r, min(max(c + k, 0), width - 1)]
            out_tmp[r, c] = acc
        for c in range(max(inner1 + 1, c0), c1 + 1):
            acc = ZERO
            for k in range(-radius, radius + 1):
                acc += weights[k + radius] * frame[r, min(max(c + k, 0), width - 1)]
            out_tmp[r, c] = acc
    for r in range(height):
        c0 = np.int64(gau_lo[r])
        c1 = np.int64(gau_hi[r])
        if c1 < c0:
            continue
        n = c1 - c0 + 1
        out = np.uint64(r * width + c0)
        if radius == 2:
            ka = np.uint64(max(r - 2, 0) * width + c0)
            kb = np.uint64(max(r - 1, 0) * width + c0)
            kd = np.uint64(min(r + 1, height - 1) * width + c0)
            ke = np.uint64(min(r + 2, height - 1) * width + c0)
            for i in range(n):
                ui = np.uint64(i)
                smo[out + ui] = (
                    w0 * (tmp[ka + ui] + tmp[ke + ui]) + w1 * (tmp[kb + ui] + tmp[kd + ui]) + w2 * tmp[out + ui]
                )
            continue
        for i in range(n):
            smo[out + np.uint64(i)] = ZERO
        for k in range(-radius, radius + 1):
            wk = weights[k + radius]
            src = np.uint64(min(max(r + k, 0), height - 1) * width + c0)
            for i in range(n):
                ui = np.uint64(i)
                smo[out + ui] += wk * tmp[src + ui]
    grow_spans(lo, hi, 1, 1, sob_lo, sob_hi)
    for r in range(height):
        sob_hi[r] = min(sob_hi[r], width - 1)
    sobel_rows(out_smooth, sob_lo, sob_hi, out_gx, out_gy, out_mag)
    # Non-maximum suppression with OpenCV's sector rule and tie-breaking; pixels outside the image count as 0.
    top = 0
    for r in range(height):
        c0 = np.int64(lo[r])
        c1 = min(np.int64(hi[r]), width - 1)
        if c1 < c0:
            continue
        base = np.uint64(r * width + c0)
        n = c1 - c0 + 1
        # Most pixels are below `low`: find those 16 at a time with a loop that vectorises, and run the
        # branchy sector test only on chunks that hold a candidate.
        chunk = np.int64(0)
        while chunk < n:
            stop = min(chunk + 16, n)
            kc = base + np.uint64(chunk)
            above = 0
            for j in range(stop - chunk):
                above += 1 if omag[kc + np.uint64(j)] > low else 0
            if above == 0:
                for j in range(stop - chunk):
                    oedge[kc + np.uint64(j)] = EDGE_NONE
                chunk = stop
                continue
            for i in range(chunk, stop):
                k = base + np.uint64(i)
                m = omag[k]
                if not m > low:
                    oedge[k] = EDGE_NONE
                    continue
                c = c0 + i
                ax = abs(ogx[k])
                ay = abs(ogy[k])
                if ay < ax * TAN_22_5:
                    ml = omag[k - u1] if c > 0 else ZERO
                    mr = omag[k + u1] if c < width - 1 else ZERO
                    keep = m > ml and m >= mr
                elif ay > ax * (TAN_22_5 + TWO):
                    mu = omag[k - uw] if r > 0 else ZERO
                    md = omag[k + uw] if r < height - 1 else ZERO
                    keep = m > mu and m >= md
                else:
                    s = -1 if ogx[k] * ogy[k] < 0 else 1
                    mu = out_mag[r - 1, c - s] if (r > 0 and 0 <= c - s < width) else ZERO
                    md = out_mag[r + 1, c + s] if (r < height - 1 and 0 <= c + s < width) else ZERO
                    keep = m > mu and m > md
                if not keep:
                    oedge[k] = EDGE_NONE
                elif m > high:
                    oedge[k] = EDGE_STRONG
                    stack[top] = r * width + c
                    top += 1
                else:
                    oedge[k] = EDGE_WEAK
            chunk = stop
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
        base = np.uint64(r * width + c0)
        for i in range(c1 - c0 + 1):
            k = base + np.uint64(i)
            v = oedge[k] >> 1  # EDGE_STRONG -> 1, weak and none -> 0
            oedge[k] = v
            stack[count] = np.int32(k)  # the edge list: kept only where v == 1 (count advances)
            count += np.int64(v)  # a uint8 sum would wrap at 256 (plain Python promotes to the narrower type)
    return count
