"""Canny's first half on row spans: Gaussian smoothing and Sobel gradients, and the growing of spans they need.

`smooth_rows` and `smooth_columns` smooth rows then columns, `sobel_rows` writes the gradients and their L2 norm;
`smooth_ring` does the smoothing in one sweep off the image border (the horizontal smoothing of row r + 2 into a
ring of 8 rows, then the vertical smoothing of row r, each row read from L1 just after it is written).
`smooth_box` smooths a rectangle for readers outside the band (the split). Both ways give bit-identical outputs:
the same float32 expressions in the same order, in the 8-column steps of `canny_simd`. The arithmetic passes run
over the row's span padded to whole vectors of `VEC` columns (no scalar remainder loop after the vector loop,
whose trip count would change from row to row and mispredict). Values in the padding are computed from whatever
the planes hold there and are not valid; every output is valid where documented. The non-maximum suppression,
hysteresis and the sequence `detect_edges` are in `canny`.
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numba import float32, int64, void

from ropecam.device.pipeline._kernels._common import (
    TWO,
    ZERO,
    f4_1d_ro,
    prefetch_read,
    prefetch_write,
)
from ropecam.device.pipeline._kernels.canny_simd import LANES, hsmooth8, sobel8, vsmooth8
from ropecam.shared.jit import (
    f4_2d,
    i4_1d,
    i4_1d_ro,
    kernel,
    u1_2d_ro,
)

VEC: Final = 8
"""Columns per vector step of float32 arithmetic (AVX2: 8 lanes); the padded spans are whole multiples of it."""
AHEAD: Final = 4
"""Rows ahead whose cache lines a pass asks for (`prefetch_read`, `prefetch_write`) before working on a row: each
row of a band starts on new cache lines (and pages) of every plane, which the hardware prefetcher, following
contiguous runs, does not fetch; a frame's band then waited ~50 us on memory."""
RING: Final = 8
"""Rows of the horizontal smoothing `smooth_ring` keeps (the first rows of `out_tmp`; 5 are read at a time)."""
_EMPTY_LO: Final = 2147483647


@kernel(int64(int64, int64, int64))
def padded_end(c0, c1, width):
    """Return the last column of the span starting at `c0` that covers `c1` in whole `VEC`-column steps, or
    ``width - 1`` when that would leave the image (then the last step is partial)."""
    return min(c0 + ((c1 - c0) // VEC + 1) * VEC - 1, width - 1)


@kernel(void(i4_1d_ro, i4_1d_ro, int64, int64, int64, int64, i4_1d, i4_1d))
def grow_spans(lo, hi, r_begin, r_end, cols_apart, width, out_lo, out_hi):
    """Write into `out_lo`/`out_hi`, for the rows ``r_begin - 1 .. r_end + 1`` (clipped to the image), the union
    of the spans `lo`/`hi` of the row and its two neighbours (only rows ``r_begin .. r_end`` are read, the others
    count as empty), widened by `cols_apart` columns and clipped to ``[0, width)``; an empty result is ``(1, 0)``.

    `out_lo`/`out_hi` may be `lo`/`hi` themselves (grown in place): each row is read before it is written."""
    height = lo.shape[0]
    prev_lo = _EMPTY_LO
    prev_hi = -1
    b = max(r_begin - 1, 0)
    e = min(r_end + 1, height - 1)
    cur_lo = np.int64(lo[b]) if b >= r_begin and hi[b] >= lo[b] else _EMPTY_LO
    cur_hi = np.int64(hi[b]) if b >= r_begin and hi[b] >= lo[b] else -1
    for r in range(b, e + 1):
        nxt_lo = _EMPTY_LO
        nxt_hi = -1
        if r + 1 <= r_end and hi[r + 1] >= lo[r + 1]:
            nxt_lo = np.int64(lo[r + 1])
            nxt_hi = np.int64(hi[r + 1])
        a = min(min(prev_lo, cur_lo), nxt_lo)
        z = max(max(prev_hi, cur_hi), nxt_hi)
        out_lo[r] = max(0, a - cols_apart) if z >= 0 else 1
        out_hi[r] = min(width - 1, z + cols_apart) if z >= 0 else 0
        prev_lo = cur_lo
        prev_hi = cur_hi
        cur_lo = nxt_lo
        cur_hi = nxt_hi


@kernel(float32(u1_2d_ro, f4_1d_ro, int64, int64))
def smooth_replicated(frame, weights, r, c):
    """Return the horizontal smoothing of `frame` at (r, c) with the image border replicated."""
    width = frame.shape[1]
    radius = weights.shape[0] // 2
    acc = ZERO
    for k in range(-radius, radius + 1):
        acc += weights[k + radius] * frame[r, min(max(c + k, 0), width - 1)]
    return acc


@kernel(void(u1_2d_ro, f4_1d_ro, i4_1d, i4_1d, int64, int64, f4_2d))
def smooth_rows(frame, weights, hor_lo, hor_hi, r_begin, r_end, out_tmp):
    """Write the horizontal pass of the separable smoothing of `frame` into `out_tmp` (border replicated) over
    the spans `hor_lo`/`hor_hi` of the rows ``r_begin .. r_end``, padded to whole vectors."""
    height = frame.shape[0]
    width = frame.shape[1]
    radius = weights.shape[0] // 2
    size = height * width
    f = frame.reshape(size)
    tmp = out_tmp.reshape(size)
    u1 = np.uint64(1)
    u2 = np.uint64(2)
    w0 = weights[0]
    w1 = weights[min(1, 2 * radius)]
    w2 = weights[min(2, 2 * radius)]
    # Each pass's row loop starts as the others' do (here, `smooth_columns`, `sobel_rows`, `suppress_rows`): the
    # span of row r + AHEAD asked for, then the row's span padded to whole vectors. Written out in each on purpose:
    # the planes asked for and the strides differ per pass, and a step kernel the loops share costs its call where
    # Numba does not inline it (docs/speed.md, house10: +3-37 % on the split's and the band's loops; not measured
    # on these passes). `smooth_box`, inside the steady frame's `split_frame`, runs this pass and `smooth_columns`.
    for r in range(r_begin, r_end + 1):
        ahead = r + AHEAD
        if ahead <= r_end and hor_hi[ahead] >= hor_lo[ahead]:
            first = ahead * width + max(np.int64(hor_lo[ahead]) - radius, 0)
            last = ahead * width + min(np.int64(hor_hi[ahead]) + radius, width - 1)
            for k in range(first, last + 1, 64):
                prefetch_read(f, np.uint64(k))
            prefetch_read(f, np.uint64(last))
            for k in range(first, last + 1, 16):
                prefetch_write(tmp, np.uint64(k))
            prefetch_write(tmp, np.uint64(last))
        c0 = np.int64(hor_lo[r])
        c1 = np.int64(hor_hi[r])
        if c1 < c0:
            continue
        c0 -= c0 % VEC
        c1 = padded_end(c0, c1, width)
        row = r * width
        inner0 = max(c0, radius)
        inner1 = min(c1, width - 1 - radius)
        if radius == 2 and inner0 == c0 and inner1 == c1:
            # The default smoothing (sigma 1 px) in whole 8-column steps, all inside the image.
            base = np.uint64(row + c0)
            for step in range((c1 - c0 + 1) // LANES):
                k = base + np.uint64(step * LANES)
                hsmooth8(f, k, w0, w1, w2, tmp, k)
            continue
        if inner1 >= inner0:
            base = np.uint64(row + inner0)
            if radius == 2:
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
        else:  # every column is within `radius` of the image border
            inner0 = c1 + 1
            inner1 = c1
        for c in range(c0, inner0):
            out_tmp[r, c] = smooth_replicated(frame, weights, r, c)
        for c in range(inner1 + 1, c1 + 1):
            out_tmp[r, c] = smooth_replicated(frame, weights, r, c)


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


@kernel(void(f4_2d, f4_1d_ro, i4_1d, i4_1d, int64, int64, f4_2d))
def smooth_columns(tmp, weights, gau_lo, gau_hi, r_begin, r_end, out_smooth):
    """Write the vertical pass of the separable smoothing of `tmp` into `out_smooth` (border replicated) over the
    spans `gau_lo`/`gau_hi` of the rows ``r_begin .. r_end``, padded to whole vectors."""
    height = tmp.shape[0]
    width = tmp.shape[1]
    radius = weights.shape[0] // 2
    size = height * width
    t = tmp.reshape(size)
    smo = out_smooth.reshape(size)
    w0 = weights[0]
    w1 = weights[min(1, 2 * radius)]
    w2 = weights[min(2, 2 * radius)]
    for r in range(r_begin, r_end + 1):
        ahead = r + AHEAD
        if ahead <= r_end and gau_hi[ahead] >= gau_lo[ahead]:
            first = ahead * width + np.int64(gau_lo[ahead])
            last = ahead * width + np.int64(gau_hi[ahead])
            for k in range(first, last + 1, 16):
                prefetch_write(smo, np.uint64(k))
            prefetch_write(smo, np.uint64(last))
        c0 = np.int64(gau_lo[r])
        c1 = np.int64(gau_hi[r])
        if c1 < c0:
            continue
        c0 -= c0 % VEC
        c1 = padded_end(c0, c1, width)
        n = c1 - c0 + 1
        out = np.uint64(r * width + c0)
        if radius == 2:
            ka = np.uint64(max(r - 2, 0) * width + c0)
            kb = np.uint64(max(r - 1, 0) * width + c0)
            kd = np.uint64(min(r + 1, height - 1) * width + c0)
            ke = np.uint64(min(r + 2, height - 1) * width + c0)
            if n % LANES == 0:  # whole 8-column steps
                for step in range(n // LANES):
                    us = np.uint64(step * LANES)
                    vsmooth8(t, ka + us, kb + us, out + us, kd + us, ke + us, w0, w1, w2, smo, out + us)
                continue
            for i in range(n):
                ui = np.uint64(i)
                smo[out + ui] = w0 * (t[ka + ui] + t[ke + ui]) + w1 * (t[kb + ui] + t[kd + ui]) + w2 * t[out + ui]
            continue
        for i in range(n):
            smo[out + np.uint64(i)] = ZERO
        for k in range(-radius, radius + 1):
            wk = weights[k + radius]
            src = np.uint64(min(max(r + k, 0), height - 1) * width + c0)
            for i in range(n):
                ui = np.uint64(i)
                smo[out + ui] += wk * t[src + ui]


@kernel(int64(u1_2d_ro, f4_1d_ro, i4_1d_ro, i4_1d_ro, int64, int64, int64, int64, i4_1d, i4_1d, f4_2d, f4_2d))
def smooth_box(frame, weights, lo, hi, r0, r1, c0, c1, work_lo, work_hi, out_tmp, out_smooth):
    """Make `out_smooth` hold the smoothing of `frame` over rows `r0`..`r1`, columns `c0`..`c1` (inclusive, inside
    the image): rows whose box part lies inside the spans `lo`/`hi` of the last `detect_edges` already do (it
    smooths at least its spans); the rows from the first to the last that they do not cover are smoothed again
    over the box's columns with `smooth_rows` and `smooth_columns` (the values `detect_edges` gives; `out_tmp` is
    scratch). Returns the number of pixels smoothed (0 when the spans covered the box). `work_lo`/`work_hi`
    (image height) are scratch spans."""
    first = -1
    last = -1
    for r in range(r0, r1 + 1):
        if lo[r] > c0 or hi[r] < c1:
            if first < 0:
                first = r
            last = r
    if first < 0:
        return 0
    radius = weights.shape[0] // 2
    t0 = max(0, first - radius)
    t1 = min(frame.shape[0] - 1, last + radius)
    for r in range(t0, t1 + 1):
        work_lo[r] = c0
        work_hi[r] = c1
    smooth_rows(frame, weights, work_lo, work_hi, t0, t1, out_tmp)
    smooth_columns(out_tmp, weights, work_lo, work_hi, first, last, out_smooth)
    return (last - first + 1) * (c1 - c0 + 1)


@kernel(void(f4_2d, i4_1d, i4_1d, int64, int64, f4_2d, f4_2d, f4_2d))
def sobel_rows(smooth, sob_lo, sob_hi, r_begin, r_end, out_gx, out_gy, out_mag):
    """Write the 3x3 Sobel gradients of `smooth` and their L2 norm over the spans `sob_lo`/`sob_hi` (within the
    image) of the rows ``r_begin .. r_end``, padded to whole vectors, replicating the image border."""
    height = smooth.shape[0]
    width = smooth.shape[1]
    size = height * width
    smo = smooth.reshape(size)
    ogx = out_gx.reshape(size)
    ogy = out_gy.reshape(size)
    omag = out_mag.reshape(size)
    u1 = np.uint64(1)
    for r in range(r_begin, r_end + 1):  # the row loop's start as `smooth_rows`' (see the comment there)
        ahead = r + AHEAD
        if ahead <= r_end and sob_hi[ahead] >= sob_lo[ahead]:
            first = ahead * width + np.int64(sob_lo[ahead])
            last = ahead * width + np.int64(sob_hi[ahead])
            for k in range(first, last + 1, 16):
                prefetch_write(ogx, np.uint64(k))
                prefetch_write(ogy, np.uint64(k))
                prefetch_write(omag, np.uint64(k))
            prefetch_write(ogx, np.uint64(last))
            prefetch_write(ogy, np.uint64(last))
            prefetch_write(omag, np.uint64(last))
        c0 = np.int64(sob_lo[r])
        c1 = np.int64(sob_hi[r])
        if c1 < c0:
            continue
        c0 -= c0 % VEC
        c1 = padded_end(c0, c1, width)
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
        if i0 == c0 and i1 == c1:  # whole 8-column steps, all inside the image
            for step in range((i1 - i0 + 1) // LANES):
                us = np.uint64(step * LANES)
                sobel8(smo, km + us, k0 + us, kp + us, ogx, ogy, omag)
            continue
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
