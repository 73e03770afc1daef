"""Numba kernels of the 2D ANCF cable model: element forces and tangents, banded LU, generalized-alpha stepping.

Element (Gerstmayr & Shabana 2006, gradient-deficient cable): nodal coordinates (x, y, x', y') at both ends, cubic
Hermite shape functions in the unstretched arc length, axial strain eps = |r'| - 1 (5-point Gauss), curvature
kappa = (r' x r'')_z / |r'|^2 (3-point Gauss), consistent mass. Global vectors are node-major
(q[4 k + 0..3] = x, y, x', y' of node k), so an element couples 8 consecutive entries and every matrix is banded
with half bandwidth 7. Matrices are stored row-wise as ``band[i, j - i + KL]`` with room for the fill-in of
partial pivoting (columns up to i + KU + KL).
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import float64, int64, void

from ropecam.shared.jit import KernelStatus, f8_1d, f8_2d, f8_3d, i4_1d, kernel

KL: Final = 7
KU: Final = 7
BAND_WIDTH: Final = 2 * KL + KU + 1

# Gauss-Legendre points and weights on [0, 1].
GAUSS3_X: Final = np.array([0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6)])
GAUSS3_W: Final = np.array([5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0])
_G5 = (0.9061798459386640, 0.5384693101056831, 0.0, -0.5384693101056831, -0.9061798459386640)
_W5 = (0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665, 0.2369268850561891)
GAUSS5_X: Final = np.array([0.5 + 0.5 * g for g in _G5])
GAUSS5_W: Final = np.array([0.5 * w for w in _W5])

# Layout of the float64 parameter vector.
P_EA: Final = 0
P_EI: Final = 1
P_RHOA: Final = 2
P_GRAVITY: Final = 3
P_LE: Final = 4
P_DRAG: Final = 5  # 0.5 * rho_air * Cd * d  (N s^2 / m^3 per unit length)
P_MASS_DAMPING: Final = 6
P_MATERIAL_DAMPING: Final = 7
P_ALPHA_M: Final = 8
P_ALPHA_F: Final = 9
P_GAMMA: Final = 10
P_BETA: Final = 11
P_STEP: Final = 12
P_TOLERANCE: Final = 13
P_MAX_ITERATIONS: Final = 14
P_CLAMPED: Final = 15
P_AMPLITUDE_X: Final = 16
P_AMPLITUDE_Y: Final = 17
P_OMEGA: Final = 18
P_PHASE: Final = 19
P_SLOPE_X: Final = 20
P_SLOPE_Y: Final = 21
N_PARAMS: Final = 22

# Rows of the scratch array (8 columns each).
S_ELEM_Q: Final = 0
S_ELEM_V: Final = 1
S_FORCE: Final = 2
S_D_EPS: Final = 3
S_D_KAPPA: Final = 4
S_D_C: Final = 5
S_D_G: Final = 6
S_SHAPE: Final = 7
S_SHAPE_1: Final = 8
S_SHAPE_2: Final = 9
S_CV: Final = 10
N_SCRATCH: Final = 11

# Progress counters written by `advance`.
C_STEPS: Final = 0
C_SAMPLES: Final = 1
C_ITERATIONS: Final = 2
N_COUNTERS: Final = 3


@kernel(void(float64, float64, f8_1d, f8_1d, f8_1d))
def hermite(xi, le, out_s, out_s1, out_s2):
    """Write the cubic Hermite shape functions at `xi` and their first and second arc-length derivatives.

    Writes `out_s` (values), `out_s1` (d/ds), `out_s2` (d^2/ds^2), 4 entries each.
    """
    xi2 = xi * xi
    xi3 = xi2 * xi
    out_s[0] = 1.0 - 3.0 * xi2 + 2.0 * xi3
    out_s[1] = le * (xi - 2.0 * xi2 + xi3)
    out_s[2] = 3.0 * xi2 - 2.0 * xi3
    out_s[3] = le * (xi3 - xi2)
    out_s1[0] = (-6.0 * xi + 6.0 * xi2) / le
    out_s1[1] = 1.0 - 4.0 * xi + 3.0 * xi2
    out_s1[2] = (6.0 * xi - 6.0 * xi2) / le
    out_s1[3] = -2.0 * xi + 3.0 * xi2
    out_s2[0] = (-6.0 + 12.0 * xi) / (le * le)
    out_s2[1] = (-4.0 + 6.0 * xi) / le
    out_s2[2] = (6.0 - 12.0 * xi) / (le * le)
    out_s2[3] = (-2.0 + 6.0 * xi) / le


@kernel(void(f8_1d, int64, f8_2d, f8_3d))
def element_internal(params, with_tangent, scratch, out_mats):
    """Write the internal force of one element (elastic + Kelvin-Voigt damping) and optionally its tangents.

    Reads the element's coordinates and velocities from ``scratch[S_ELEM_Q]`` and ``scratch[S_ELEM_V]``. Writes
    ``scratch[S_FORCE]``; when `with_tangent`, also ``out_mats[0]`` (tangent stiffness, symmetric) and, with material
    damping, ``out_mats[1]`` (material stiffness EA de de + EI dk dk, the damping force's velocity Jacobian divided
    by the damping time). All overwritten.

    The bending tangent uses d2k = Hc / g - (dk dg + dg dk) / g - k Hg / g with k = c / g, which with
    p = k dg / g becomes (dk - p)(dk - p)^T - p p^T plus the sparse Hessians Hc and Hg.
    """
    ea = params[P_EA]
    ei = params[P_EI]
    le = params[P_LE]
    damping = params[P_MATERIAL_DAMPING]
    with_material = with_tangent and damping > 0.0
    e = scratch[S_ELEM_Q]
    ev = scratch[S_ELEM_V]
    f = scratch[S_FORCE]
    s = scratch[S_SHAPE]
    s1 = scratch[S_SHAPE_1]
    s2 = scratch[S_SHAPE_2]
    z = scratch[S_D_EPS]
    d_kap = scratch[S_D_KAPPA]
    p_vec = scratch[S_D_C]
    d_g = scratch[S_D_G]
    kt = out_mats[0]
    km = out_mats[1]
    for a in range(8):
        f[a] = 0.0
        if with_tangent:
            for b in range(a, 8):
                kt[a, b] = 0.0
                if with_material:
                    km[a, b] = 0.0
    # Axial strain, 5-point Gauss: blocks s1_k s1_m [EA t t^T + EA eps (I - t t^T) / |r'|].
    for g in range(5):
        hermite(GAUSS5_X[g], le, s, s1, s2)
        w = GAUSS5_W[g] * le * ea
        xp = s1[0] * e[0] + s1[1] * e[2] + s1[2] * e[4] + s1[3] * e[6]
        yp = s1[0] * e[1] + s1[1] * e[3] + s1[2] * e[5] + s1[3] * e[7]
        norm = math.sqrt(xp * xp + yp * yp)
        tx = xp / norm
        ty = yp / norm
        eps = norm - 1.0
        if damping > 0.0:
            xpv = s1[0] * ev[0] + s1[1] * ev[2] + s1[2] * ev[4] + s1[3] * ev[6]
            ypv = s1[0] * ev[1] + s1[1] * ev[3] + s1[2] * ev[5] + s1[3] * ev[7]
            eps += damping * (tx * xpv + ty * ypv)  # Kelvin-Voigt: stress from eps + damping * d eps / dt
        for kk in range(4):
            f[2 * kk] += w * eps * s1[kk] * tx
            f[2 * kk + 1] += w * eps * s1[kk] * ty
        if not with_tangent:
            continue
        eps = norm - 1.0
        geo = eps / norm
        b00 = w * (tx * tx + geo * (1.0 - tx * tx))
        b01 = w * (tx * ty - geo * tx * ty)
        b11 = w * (ty * ty + geo * (1.0 - ty * ty))
        for kk in range(4):
            for m in range(4):
                ss = s1[kk] * s1[m]
                kt[2 * kk, 2 * m] += ss * b00
                kt[2 * kk, 2 * m + 1] += ss * b01
                kt[2 * kk + 1, 2 * m] += ss * b01
                kt[2 * kk + 1, 2 * m + 1] += ss * b11
                if with_material:
                    km[2 * kk, 2 * m] += ss * w * tx * tx
                    km[2 * kk, 2 * m + 1] += ss * w * tx * ty
                    km[2 * kk + 1, 2 * m] += ss * w * tx * ty
                    km[2 * kk + 1, 2 * m + 1] += ss * w * ty * ty
    # Bending, 3-point Gauss.
    for g in range(3):
        hermite(GAUSS3_X[g], le, s, s1, s2)
        w = GAUSS3_W[g] * le * ei
        xp = s1[0] * e[0] + s1[1] * e[2] + s1[2] * e[4] + s1[3] * e[6]
        yp = s1[0] * e[1] + s1[1] * e[3] + s1[2] * e[5] + s1[3] * e[7]
        xpp = s2[0] * e[0] + s2[1] * e[2] + s2[2] * e[4] + s2[3] * e[6]
        ypp = s2[0] * e[1] + s2[1] * e[3] + s2[2] * e[5] + s2[3] * e[7]
        inv_g = 1.0 / (xp * xp + yp * yp)
        kappa = (xp * ypp - yp * xpp) * inv_g
        for kk in range(4):
            d_g[2 * kk] = 2.0 * xp * s1[kk]
            d_g[2 * kk + 1] = 2.0 * yp * s1[kk]
            d_kap[2 * kk] = ((ypp * s1[kk] - yp * s2[kk]) - kappa * d_g[2 * kk]) * inv_g
            d_kap[2 * kk + 1] = ((-xpp * s1[kk] + xp * s2[kk]) - kappa * d_g[2 * kk + 1]) * inv_g
        stress = kappa
        if damping > 0.0:
            rate = 0.0
            for a in range(8):
                rate += d_kap[a] * ev[a]
            stress += damping * rate
        for a in range(8):
            f[a] += w * stress * d_kap[a]
        if not with_tangent:
            continue
        for a in range(8):
            p_vec[a] = kappa * inv_g * d_g[a]
            z[a] = d_kap[a] - p_vec[a]
        for a in range(8):
            for b in range(a, 8):
                kt[a, b] += w * (z[a] * z[b] - p_vec[a] * p_vec[b])
                if with_material:
                    km[a, b] += w * d_kap[a] * d_kap[b]
        wk = w * kappa * inv_g
        for kk in range(4):
            for m in range(4):
                hc = wk * (s1[kk] * s2[m] - s2[kk] * s1[m])
                kt[2 * kk, 2 * m + 1] += hc
                kt[2 * m + 1, 2 * kk] += hc
                hg = -wk * kappa * 2.0 * s1[kk] * s1[m]
                kt[2 * kk, 2 * m] += hg
                kt[2 * kk + 1, 2 * m + 1] += hg
    # The bending loops filled the upper triangle (the axial and Hessian terms are symmetric and filled both):
    # mirror the upper part of the outer products into the lower triangle.
    if not with_tangent:
        return
    for a in range(8):
        for b in range(a + 1, 8):
            kt[b, a] = kt[a, b]
            if with_material:
                km[b, a] = km[a, b]


@kernel(void(f8_1d, int64, f8_2d, f8_3d))
def element_drag(params, with_tangent, scratch, out_mats):
    """Add the aerodynamic drag force of one element to ``scratch[S_FORCE]`` (as a force on the rope).

    Reads ``scratch[S_ELEM_Q]`` and ``scratch[S_ELEM_V]``. When `with_tangent`, adds d(-force)/dv to ``out_mats[2]``.
    """
    cd = params[P_DRAG]
    le = params[P_LE]
    e = scratch[S_ELEM_Q]
    ev = scratch[S_ELEM_V]
    f = scratch[S_FORCE]
    s = scratch[S_SHAPE]
    s1 = scratch[S_SHAPE_1]
    s2 = scratch[S_SHAPE_2]
    cmat = out_mats[2]
    for g in range(5):
        hermite(GAUSS5_X[g], le, s, s1, s2)
        w = GAUSS5_W[g] * le
        xp = s1[0] * e[0] + s1[1] * e[2] + s1[2] * e[4] + s1[3] * e[6]
        yp = s1[0] * e[1] + s1[1] * e[3] + s1[2] * e[5] + s1[3] * e[7]
        norm = math.sqrt(xp * xp + yp * yp)
        tx = xp / norm
        ty = yp / norm
        vx = s[0] * ev[0] + s[1] * ev[2] + s[2] * ev[4] + s[3] * ev[6]
        vy = s[0] * ev[1] + s[1] * ev[3] + s[2] * ev[5] + s[3] * ev[7]
        vt = vx * tx + vy * ty
        nx = vx - vt * tx
        ny = vy - vt * ty
        vn = math.sqrt(nx * nx + ny * ny)
        fx = -cd * vn * nx
        fy = -cd * vn * ny
        for k in range(4):
            f[2 * k] += w * s[k] * fx
            f[2 * k + 1] += w * s[k] * fy
        if with_tangent and vn > 0.0:
            # d(|vn| vn)/dv = (|vn| I + vn vn^T / |vn|) P, with P = I - t t^T.
            a00 = vn + nx * nx / vn
            a01 = nx * ny / vn
            a11 = vn + ny * ny / vn
            p00 = 1.0 - tx * tx
            p01 = -tx * ty
            p11 = 1.0 - ty * ty
            j00 = cd * (a00 * p00 + a01 * p01)
            j01 = cd * (a00 * p01 + a01 * p11)
            j10 = cd * (a01 * p00 + a11 * p01)
            j11 = cd * (a01 * p01 + a11 * p11)
            for k in range(4):
                for m in range(4):
                    ss = w * s[k] * s[m]
                    cmat[2 * k, 2 * m] += ss * j00
                    cmat[2 * k, 2 * m + 1] += ss * j01
                    cmat[2 * k + 1, 2 * m] += ss * j10
                    cmat[2 * k + 1, 2 * m + 1] += ss * j11


@kernel(void(float64, float64, f8_2d, f8_2d))
def assemble_mass(rho_a, le, scratch, out_band):
    """Write the consistent mass matrix of a uniform rope into `out_band` (overwritten; n = out_band.shape[0])."""
    n = out_band.shape[0]
    s = scratch[S_SHAPE]
    s1 = scratch[S_SHAPE_1]
    s2 = scratch[S_SHAPE_2]
    out_band[:, :] = 0.0
    for el in range(n // 4 - 1):
        base = 4 * el
        for g in range(5):
            hermite(GAUSS5_X[g], le, s, s1, s2)
            w = GAUSS5_W[g] * le * rho_a
            for k in range(4):
                for m in range(4):
                    for c in range(2):
                        i = base + 2 * k + c
                        j = base + 2 * m + c
                        out_band[i, j - i + KL] += w * s[k] * s[m]


@kernel(void(float64, float64, f8_2d, f8_1d))
def assemble_gravity(rho_a_g, le, scratch, out_force):
    """Write the consistent gravity load (along +y) into `out_force` (overwritten)."""
    n = out_force.shape[0]
    s = scratch[S_SHAPE]
    s1 = scratch[S_SHAPE_1]
    s2 = scratch[S_SHAPE_2]
    out_force[:] = 0.0
    for el in range(n // 4 - 1):
        base = 4 * el
        for g in range(5):
            hermite(GAUSS5_X[g], le, s, s1, s2)
            for k in range(4):
                out_force[base + 2 * k + 1] += GAUSS5_W[g] * le * rho_a_g * s[k]


@kernel(void(f8_2d, f8_1d, f8_1d))
def band_matvec(band, x, out_y):
    """Write ``out_y = A x`` for the banded matrix A (half bandwidths KL, KU)."""
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for d in range(-KL, KU + 1):
            j = i + d
            if 0 <= j < n:
                acc += band[i, d + KL] * x[j]
        out_y[i] = acc


@kernel(int64(f8_2d, i4_1d))
def band_factor(band, out_pivots):
    """Factor the banded matrix in place (LU with partial pivoting); write the row pivots into `out_pivots`.

    Returns 0, or KernelStatus.SINGULAR when a pivot is zero.
    """
    n = band.shape[0]
    width = KU + KL
    for k in range(n):
        last = min(k + KL, n - 1)
        p = k
        best = abs(band[k, KL])
        for i in range(k + 1, last + 1):
            value = abs(band[i, k - i + KL])
            if value > best:
                best = value
                p = i
        out_pivots[k] = p
        if best == 0.0:
            return KernelStatus.SINGULAR
        if p != k:
            for j in range(k, min(k + width, n - 1) + 1):
                tmp = band[k, j - k + KL]
                band[k, j - k + KL] = band[p, j - p + KL]
                band[p, j - p + KL] = tmp
        pivot = band[k, KL]
        for i in range(k + 1, last + 1):
            factor = band[i, k - i + KL] / pivot
            band[i, k - i + KL] = factor
            if factor != 0.0:
                for j in range(k + 1, min(k + width, n - 1) + 1):
                    band[i, j - i + KL] -= factor * band[k, j - k + KL]
    return 0


@kernel(void(f8_2d, i4_1d, f8_1d))
def band_solve(band, pivots, rhs):
    """Solve in place with the factors from `band_factor`: `rhs` becomes the solution."""
    n = band.shape[0]
    width = KU + KL
    for k in range(n):
        p = pivots[k]
        if p != k:
            tmp = rhs[k]
            rhs[k] = rhs[p]
            rhs[p] = tmp
        for i in range(k + 1, min(k + KL, n - 1) + 1):
            rhs[i] -= band[i, k - i + KL] * rhs[k]
    for k in range(n - 1, -1, -1):
        acc = rhs[k]
        for j in range(k + 1, min(k + width, n - 1) + 1):
            acc -= band[k, j - k + KL] * rhs[j]
        rhs[k] = acc / band[k, KL]


@kernel(void(f8_1d, float64, f8_1d, f8_1d, f8_1d))
def prescribe_fixed_end(params, t, q, v, qdd):
    """Overwrite the fixed end's constrained coordinates, velocities and accelerations at time `t`."""
    omega = params[P_OMEGA]
    phase = omega * t + params[P_PHASE]
    sin_p = math.sin(phase)
    cos_p = math.cos(phase)
    q[0] = params[P_AMPLITUDE_X] * sin_p
    q[1] = params[P_AMPLITUDE_Y] * sin_p
    v[0] = params[P_AMPLITUDE_X] * omega * cos_p
    v[1] = params[P_AMPLITUDE_Y] * omega * cos_p
    qdd[0] = -params[P_AMPLITUDE_X] * omega * omega * sin_p
    qdd[1] = -params[P_AMPLITUDE_Y] * omega * omega * sin_p
    if params[P_CLAMPED] != 0.0:
        q[2] = params[P_SLOPE_X]
        q[3] = params[P_SLOPE_Y]
        v[2] = 0.0
        v[3] = 0.0
        qdd[2] = 0.0
        qdd[3] = 0.0


@kernel(void(f8_1d, f8_2d, f8_1d, f8_1d, f8_1d, f8_1d, float64, float64, int64, f8_2d, f8_3d, f8_1d, f8_2d))
def assemble_system(
    params, mass_band, gravity, q, v, qdd, scale_m, scale_c, with_tangent, scratch, mats, out_res, out_band
):
    """Write the residual ``M qdd + f_int + f_damp - f_grav - f_drag`` and, when `with_tangent`, the matrix
    ``scale_m M + K + scale_c C`` (K: stiffness, C: damping Jacobian).

    Constrained rows (fixed end) get a zero residual and an identity row; their columns are cleared elsewhere.
    `out_band` must have BAND_WIDTH columns; `out_res` (and with the tangent `out_band`) are overwritten.
    """
    n = q.shape[0]
    n_constrained = 4 if params[P_CLAMPED] != 0.0 else 2
    alpha = params[P_MASS_DAMPING]
    beta_mat = params[P_MATERIAL_DAMPING]
    has_drag = params[P_DRAG] > 0.0
    with_material = with_tangent and beta_mat > 0.0
    band_matvec(mass_band, qdd, out_res)
    for i in range(n):
        out_res[i] -= gravity[i]
        if with_tangent:
            for w in range(BAND_WIDTH):
                out_band[i, w] = 0.0
        for d in range(-KL, KU + 1):
            j = i + d
            if 0 <= j < n:
                m = mass_band[i, d + KL]
                if with_tangent:
                    out_band[i, d + KL] = (scale_m + scale_c * alpha) * m
                out_res[i] += alpha * m * v[j]
    e = scratch[S_ELEM_Q]
    ev = scratch[S_ELEM_V]
    f = scratch[S_FORCE]
    cv = scratch[S_CV]
    kt = mats[0]
    km = mats[1]
    cmat = mats[2]
    for el in range(n // 4 - 1):
        base = 4 * el
        for a in range(8):
            e[a] = q[base + a]
            ev[a] = v[base + a]
        element_internal(params, with_tangent, scratch, mats)
        if with_tangent:
            for a in range(8):
                for b in range(8):
                    cmat[a, b] = beta_mat * km[a, b] if with_material else 0.0
        if has_drag:
            # The drag force goes to the residual with a minus sign: accumulate it negated.
            for a in range(8):
                cv[a] = f[a]
                f[a] = 0.0
            element_drag(params, with_tangent, scratch, mats)
            for a in range(8):
                f[a] = cv[a] - f[a]
        for a in range(8):
            out_res[base + a] += f[a]
            if with_tangent:
                i = base + a
                for b in range(8):
                    j = base + b
                    out_band[i, j - i + KL] += kt[a, b] + scale_c * cmat[a, b]
    for i in range(n_constrained):
        out_res[i] = 0.0
        if not with_tangent:
            continue
        for w in range(BAND_WIDTH):
            out_band[i, w] = 0.0
        out_band[i, KL] = 1.0
        for r in range(n_constrained, min(i + KL, n - 1) + 1):
            out_band[r, i - r + KL] = 0.0


@kernel(
    int64(
        f8_1d, f8_1d, f8_1d, f8_1d, float64, int64, int64, int64, f8_1d, f8_2d, f8_1d,
        f8_2d, f8_1d, f8_1d, i4_1d, f8_2d, f8_3d, f8_2d, f8_1d, f8_2d, f8_2d, i4_1d,
    )
)  # fmt: skip
def advance(
    q, v, qdd, acc, t0, step0, n_steps, sample_every, params, mass_band, gravity,
    band, res, delta, pivots, scratch, mats, backup, out_t, out_q, out_v, out_counters,
):  # fmt: skip
    """Advance the rope `n_steps` generalized-alpha steps (Arnold & Bruls 2007) from time `t0` (step number `step0`).

    Updates the state in place: `q`, `v` (nodal coordinates and velocities), `qdd` (accelerations) and `acc` (the
    algorithmic acceleration). After each step whose absolute number (step0 + 1, step0 + 2, ...) is a multiple of
    `sample_every` writes the time and state into `out_t`, `out_q`,
    `out_v`. `backup` (2, n) is work space holding q and v at the start of the current step. Writes `out_counters`
    (steps done, samples written, Newton iterations). Returns the number of samples
    written, KernelStatus.FULL when the output is too short, or KernelStatus.NO_CONVERGENCE /
    KernelStatus.SINGULAR, with the state left at the last converged step.
    """
    n = q.shape[0]
    h = params[P_STEP]
    am = params[P_ALPHA_M]
    af = params[P_ALPHA_F]
    gamma = params[P_GAMMA]
    beta = params[P_BETA]
    tol = params[P_TOLERANCE]
    max_iter = int(params[P_MAX_ITERATIONS])
    max_update = 0.05 * params[P_LE]
    beta_p = h * h * beta * (1.0 - af) / (1.0 - am)
    gamma_p = h * gamma * (1.0 - af) / (1.0 - am)
    out_counters[C_STEPS] = 0
    out_counters[C_SAMPLES] = 0
    out_counters[C_ITERATIONS] = 0
    samples = 0
    refactor = 1
    factored_age = 0
    for step in range(n_steps):
        t = t0 + (step + 1) * h
        for i in range(n):
            backup[0, i] = q[i]
            backup[1, i] = v[i]
        # Newton on x = q''_{n+1} (dq/dx = beta_p, dv/dx = gamma_p). First attempt: modified Newton, keeping the
        # factored tangent across iterations and steps and rebuilding it when an update shrinks by less than 10x.
        # If that fails, the step is redone with a fresh tangent at every iteration (full Newton).
        converged = False
        for attempt in range(2):
            if attempt == 1:
                refactor = 1
                for i in range(n):
                    q[i] = backup[0, i]
                    v[i] = backup[1, i]
            # Predictor: x starts at q''_n; q and v follow from the Newmark relations.
            for i in range(n):
                a_new = (qdd[i] - am * acc[i]) / (1.0 - am)
                q[i] += h * v[i] + h * h * ((0.5 - beta) * acc[i] + beta * a_new)
                v[i] += h * ((1.0 - gamma) * acc[i] + gamma * a_new)
                delta[i] = qdd[i]
            prescribe_fixed_end(params, t, q, v, scratch[S_CV])
            for i in range(4 if params[P_CLAMPED] != 0.0 else 2):
                delta[i] = scratch[S_CV, i]
            previous = 0.0
            iteration = 0
            for iteration in range(max_iter):
                assemble_system(params, mass_band, gravity, q, v, delta, 1.0 / beta_p, gamma_p / beta_p, refactor,
                                scratch, mats, res, band)  # fmt: skip
                if refactor:
                    if band_factor(band, pivots) < 0:
                        break
                    factored_age = 0
                for i in range(n):
                    res[i] = -res[i]
                band_solve(band, pivots, res)
                largest = 0.0
                for i in range(n):
                    if abs(res[i]) > largest:
                        largest = abs(res[i])
                # Damped Newton: a soft rope under slight compression makes the matrix nearly singular (its slope
                # modes have almost no stiffness and tiny inertia); limit any update to a fraction of an element.
                limit = max_update
                shrink = 1.0 if largest <= limit else limit / largest
                largest = 0.0
                for i in range(n):
                    dq = shrink * res[i]
                    q[i] += dq
                    v[i] += gamma_p / beta_p * dq
                    delta[i] += dq / beta_p
                    if abs(dq) > largest:
                        largest = abs(dq)
                out_counters[C_ITERATIONS] += 1
                if not largest < 1e30:  # diverged (or NaN)
                    break
                if largest <= tol and shrink == 1.0:
                    converged = True
                    break
                refactor = 1 if (attempt == 1 or (iteration > 0 and largest > 0.1 * previous)) else 0
                previous = largest
            if converged:
                break
        if not converged:
            for i in range(n):
                q[i] = backup[0, i]
                v[i] = backup[1, i]
            return KernelStatus.NO_CONVERGENCE
        refactor = 1 if iteration >= 3 or factored_age >= 50 else 0
        factored_age += 1
        for i in range(n):
            acc[i] = ((1.0 - af) * delta[i] + af * qdd[i] - am * acc[i]) / (1.0 - am)
            qdd[i] = delta[i]
        out_counters[C_STEPS] = step + 1
        if (step0 + step + 1) % sample_every == 0:
            if samples >= out_t.shape[0]:
                return KernelStatus.FULL
            out_t[samples] = t
            for i in range(n):
                out_q[samples, i] = q[i]
                out_v[samples, i] = v[i]
            samples += 1
            out_counters[C_SAMPLES] = samples
    return samples


@kernel(void(f8_1d, f8_2d, f8_2d, f8_2d, f8_2d))
def energies(params, q, v, scratch, out_energy):
    """Write kinetic, gravity, axial and bending energy (J) of each state row into ``out_energy[:, 0..3]``."""
    ea = params[P_EA]
    ei = params[P_EI]
    rho_a = params[P_RHOA]
    grav = params[P_GRAVITY]
    le = params[P_LE]
    s = scratch[S_SHAPE]
    s1 = scratch[S_SHAPE_1]
    s2 = scratch[S_SHAPE_2]
    n = q.shape[1]
    for r in range(q.shape[0]):
        kinetic = 0.0
        gravity = 0.0
        axial = 0.0
        bending = 0.0
        for el in range(n // 4 - 1):
            b = 4 * el
            for g in range(5):
                hermite(GAUSS5_X[g], le, s, s1, s2)
                w = GAUSS5_W[g] * le
                y = s[0] * q[r, b + 1] + s[1] * q[r, b + 3] + s[2] * q[r, b + 5] + s[3] * q[r, b + 7]
                vx = s[0] * v[r, b] + s[1] * v[r, b + 2] + s[2] * v[r, b + 4] + s[3] * v[r, b + 6]
                vy = s[0] * v[r, b + 1] + s[1] * v[r, b + 3] + s[2] * v[r, b + 5] + s[3] * v[r, b + 7]
                xp = s1[0] * q[r, b] + s1[1] * q[r, b + 2] + s1[2] * q[r, b + 4] + s1[3] * q[r, b + 6]
                yp = s1[0] * q[r, b + 1] + s1[1] * q[r, b + 3] + s1[2] * q[r, b + 5] + s1[3] * q[r, b + 7]
                eps = math.sqrt(xp * xp + yp * yp) - 1.0
                kinetic += 0.5 * w * rho_a * (vx * vx + vy * vy)
                gravity -= w * rho_a * grav * y
                axial += 0.5 * w * ea * eps * eps
            for g in range(3):
                hermite(GAUSS3_X[g], le, s, s1, s2)
                w = GAUSS3_W[g] * le
                xp = s1[0] * q[r, b] + s1[1] * q[r, b + 2] + s1[2] * q[r, b + 4] + s1[3] * q[r, b + 6]
                yp = s1[0] * q[r, b + 1] + s1[1] * q[r, b + 3] + s1[2] * q[r, b + 5] + s1[3] * q[r, b + 7]
                xpp = s2[0] * q[r, b] + s2[1] * q[r, b + 2] + s2[2] * q[r, b + 4] + s2[3] * q[r, b + 6]
                ypp = s2[0] * q[r, b + 1] + s2[1] * q[r, b + 3] + s2[2] * q[r, b + 5] + s2[3] * q[r, b + 7]
                kappa = (xp * ypp - yp * xpp) / (xp * xp + yp * yp)
                bending += 0.5 * w * ei * kappa * kappa
        out_energy[r, 0] = kinetic
        out_energy[r, 1] = gravity
        out_energy[r, 2] = axial
        out_energy[r, 3] = bending
