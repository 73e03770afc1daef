"""Canny edge detection on row spans: smoothing, Sobel, non-maximum suppression, hysteresis."""

from __future__ import annotations

import numpy as np
from numba import float32, int32

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
