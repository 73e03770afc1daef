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
    i4_2d_ro,
    kernel,
)

# The paper's segmentation operator, eq. (7).
OPERATOR: Final = np.array([[-3, 6, 2], [-5, 0, 5], [-2, -6, 3]], dtype=np.int32)


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
