"""The paper's segmentation operator, eq. (7), and the scoring of its knots (Features 1-3, Table 1): method
``paper``."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import float32, int32

from ropecam.device.pipeline._kernels._common import FULL
from ropecam.shared.jit import (
    f4_1d,
    i4_1d,
    i4_1d_ro,
    i4_2d,
    i4_2d_ro,
    kernel,
)

# The paper's segmentation operator, eq. (7).
OPERATOR: Final = np.array([[-3, 6, 2], [-5, 0, 5], [-2, -6, 3]], dtype=np.int32)


@kernel(int32(int32, int32, int32, int32))
def _touching(r0, c0, r1, c1):
    """Return 1 when pixels (r0, c0) and (r1, c1) are 8-neighbours (not the same pixel), else 0."""
    return 1 if abs(r1 - r0) <= 1 and abs(c1 - c0) <= 1 and (r1 != r0 or c1 != c0) else 0


@kernel(int32(i4_2d_ro, int32, i4_2d, i4_1d))
def thin_chain(chain, n, out_chain, out_index):
    """Write the closed `chain` (first `n` pixels) without its redundant pixels: a pixel whose previous and next
    pixels are distinct 8-neighbours of each other (the corner pixel of a 4-connected step, a 45-degree spike) is
    dropped, repeatedly, also across the closure; repeated pixels are merged.

    What is left is the single-pixel curve the paper assumes: every pixel's two neighbours are opposite (tau = 0),
    135 degrees apart (tau in +-2, +-3, +-4, +-9) or diagonal and 90 degrees apart (tau in +-1, +-5), so tau of
    `apply_operator` names each connection uniquely (eq. 3). The one exception is kept on purpose: where the
    outline is open (a gap in the edge), the trace runs out and back and turns on a pixel whose previous and next
    pixels are the same; removing those would eat the whole open part. Writes `out_chain` (row, col) and
    `out_index` (the index in `chain` of each pixel kept); returns the number kept or FULL.
    """
    if n > out_chain.shape[0] or n > out_index.shape[0]:
        return FULL
    m = 0
    for i in range(n):
        r = chain[i, 0]
        c = chain[i, 1]
        if m > 0 and out_chain[m - 1, 0] == r and out_chain[m - 1, 1] == c:
            continue
        out_chain[m, 0] = r
        out_chain[m, 1] = c
        out_index[m] = i
        m += 1
        while m >= 3 and _touching(out_chain[m - 3, 0], out_chain[m - 3, 1], out_chain[m - 1, 0], out_chain[m - 1, 1]):
            out_chain[m - 2, 0] = out_chain[m - 1, 0]
            out_chain[m - 2, 1] = out_chain[m - 1, 1]
            out_index[m - 2] = out_index[m - 1]
            m -= 1
            if out_chain[m - 1, 0] == out_chain[m - 2, 0] and out_chain[m - 1, 1] == out_chain[m - 2, 1]:
                m -= 1
    start = 0
    changed = True
    while changed and m - start >= 3:
        changed = False
        last = m - 1
        same = out_chain[last, 0] == out_chain[start, 0] and out_chain[last, 1] == out_chain[start, 1]
        if same or _touching(out_chain[last - 1, 0], out_chain[last - 1, 1], out_chain[start, 0], out_chain[start, 1]):
            m -= 1
            changed = True
        elif _touching(out_chain[last, 0], out_chain[last, 1], out_chain[start + 1, 0], out_chain[start + 1, 1]):
            start += 1
            changed = True
    for k in range(start, m):
        out_chain[k - start, 0] = out_chain[k, 0]
        out_chain[k - start, 1] = out_chain[k, 1]
        out_index[k - start] = out_index[k]
    return m - start


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


# Feature 2.2: two adjacent 135-degree knots turning the same way make a 90-degree corner. The paper prints four
# (tau_i, tau_(i+1)) pairs, (3, -4), (-3, 4), (-2, -9), (2, 9); the corner in the other four orientations gives the
# other four below. tau does not depend on the direction of the chain, so the pairs are matched in either order.
CORNER_PAIRS: Final = np.array([[3, -4], [-3, 4], [-2, -9], [2, 9], [-4, 9], [4, -9], [-2, 3], [2, -3]], np.int32)


@kernel(int32(int32, int32))
def _corner_pair(t0, t1):
    """Return 1 when knots with tau `t0`, `t1` next to each other form a 90-degree corner (Feature 2.2), else 0."""
    for k in range(CORNER_PAIRS.shape[0]):
        a = CORNER_PAIRS[k, 0]
        b = CORNER_PAIRS[k, 1]
        if (t0 == a and t1 == b) or (t0 == b and t1 == a):
            return 1
    return 0


@kernel(int32(i4_2d_ro, i4_1d_ro, int32, float32, float32, float32, float32, float32, i4_1d, f4_1d))
def score_knots(chain, tau, n, e1_r, e1_c, e2_r, e2_c, radius_px, out_knots, out_score):
    """Score the knots (tau != 0) of the closed `chain` with Features 1-3 and Table 1 of the paper.

    Knot k is chain pixel ``out_knots[k]``; its score goes to ``out_score[k]`` (0 to 2.5). Feature 1 uses tau of
    the neighbouring knots (cyclic, eq. 8; rule 1.3, printed with 1.1's condition, is read as "exactly one of the
    two sums is zero"), Feature 2 the 90-degree knots (tau in {+-1, +-5}) with the angle to the knots two places
    away (2.1) or a knot forming a 90-degree corner with its previous or next knot (2.2, `CORNER_PAIRS`), Feature 3
    the distance to the centreline ends e1, e2 (threshold `radius_px`). The chain should be thinned first
    (`thin_chain`) so that tau names each connection uniquely. Returns the number of knots or FULL.
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
        elif _corner_pair(t, tn) or _corner_pair(t, tp):
            score += 0.5
        # Feature 3.
        i0 = out_knots[k]
        d1 = math.hypot(chain[i0, 0] - e1_r, chain[i0, 1] - e1_c)
        d2 = math.hypot(chain[i0, 0] - e2_r, chain[i0, 1] - e2_c)
        if d1 < radius_px or d2 < radius_px:
            score += 1.0
        out_score[k] = score
    return m
