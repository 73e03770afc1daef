"""Each model kernel against a slow, obvious reference."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.host.model import CableModel, RopeConfig, SolverConfig
from ropecam.host.model import _kernels as k

EA, EI = 97389.37, 6.086836e-3


def _params(le: float, damping: float = 0.0) -> np.ndarray:
    p = np.zeros(k.N_PARAMS)
    p[k.P_EA], p[k.P_EI], p[k.P_LE], p[k.P_MATERIAL_DAMPING] = EA, EI, le, damping
    return p


@pytest.mark.parametrize("xi", [0.0, 0.2113, 0.5, 1.0])
def test_hermite_matches_formulas(xi: float, hermite_reference) -> None:
    out = np.zeros((3, 4))
    k.hermite(xi, 0.25, out[0], out[1], out[2])
    for got, expected in zip(out, hermite_reference(xi, 0.25), strict=True):
        np.testing.assert_allclose(got, expected, rtol=1e-14, atol=1e-14)


def test_element_force_is_energy_gradient(bent_element, element_energy) -> None:
    e, le = bent_element
    scratch = np.zeros((k.N_SCRATCH, 8))
    mats = np.zeros((3, 8, 8))
    scratch[k.S_ELEM_Q] = e
    k.element_internal(_params(le), 1, scratch, mats)
    step = 1e-7
    gradient = np.array(
        [
            (element_energy(e + step * np.eye(8)[a], le, EA, EI) - element_energy(e - step * np.eye(8)[a], le, EA, EI))
            / (2 * step)
            for a in range(8)
        ]
    )
    np.testing.assert_allclose(scratch[k.S_FORCE], gradient, rtol=2e-6, atol=1e-6 * np.abs(gradient).max())


@pytest.mark.parametrize("damping", [0.0, 1e-3])
def test_element_tangent_is_force_jacobian(bent_element, damping: float) -> None:
    e, le = bent_element
    scratch = np.zeros((k.N_SCRATCH, 8))
    mats = np.zeros((3, 8, 8))

    def force(coords: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        scratch[k.S_ELEM_Q] = coords
        scratch[k.S_ELEM_V] = velocity
        k.element_internal(_params(le, damping), 0, scratch, mats)
        return scratch[k.S_FORCE].copy()

    scratch[k.S_ELEM_Q] = e
    scratch[k.S_ELEM_V] = 0.0
    k.element_internal(_params(le, damping), 1, scratch, mats)
    tangent, material = mats[0].copy(), mats[1].copy()
    step = 1e-7
    zero = np.zeros(8)
    numeric = np.column_stack(
        [(force(e + step * np.eye(8)[b], zero) - force(e - step * np.eye(8)[b], zero)) / (2 * step) for b in range(8)]
    )
    np.testing.assert_allclose(tangent, numeric, rtol=1e-5, atol=1e-5 * np.abs(numeric).max())
    np.testing.assert_allclose(tangent, tangent.T, rtol=1e-12, atol=1e-9)
    if damping:
        velocity_jacobian = np.column_stack([(force(e, np.eye(8)[b]) - force(e, zero)) for b in range(8)])
        np.testing.assert_allclose(damping * material, velocity_jacobian, rtol=1e-6, atol=1e-6)


def test_drag_opposes_normal_velocity_and_its_jacobian() -> None:
    le = 0.1
    p = _params(le)
    p[k.P_EA] = p[k.P_EI] = 0.0
    p[k.P_DRAG] = 0.7
    scratch = np.zeros((k.N_SCRATCH, 8))
    mats = np.zeros((3, 8, 8))
    straight = np.array([0, 0, 1, 0, le, 0, 1, 0], dtype=float)

    def drag(velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        scratch[k.S_ELEM_Q] = straight
        scratch[k.S_ELEM_V] = velocity
        scratch[k.S_FORCE] = 0.0
        mats[2] = 0.0
        k.element_drag(p, 1, scratch, mats)
        return scratch[k.S_FORCE].copy(), mats[2].copy()

    # Uniform sideways velocity 2 m/s: force per length -0.7 * 2 * 2 = -2.8 N/m, total -0.28 N along y.
    force, _ = drag(np.array([0, 2.0, 0, 0, 0, 2.0, 0, 0]))
    assert force[1::2][[0, 2]].sum() == pytest.approx(-0.28, rel=1e-12)
    assert np.allclose(force[0::2], 0.0)
    # Motion along the rope feels no drag.
    force, _ = drag(np.array([1.0, 0, 0, 0, 1.0, 0, 0, 0]))
    assert np.allclose(force, 0.0)
    velocity = np.array([0.3, 1.1, 0.0, 0.2, -0.2, 1.4, 0.1, 0.0])
    base, jacobian = drag(velocity)
    step = 1e-7
    numeric = np.column_stack([(drag(velocity + step * np.eye(8)[b])[0] - base) / step for b in range(8)])
    np.testing.assert_allclose(jacobian, -numeric, rtol=1e-4, atol=1e-7)


def test_mass_matrix_matches_direct_integration(hermite_reference) -> None:
    rho_a, le, n_el = 1.13e-3, 0.25, 3
    scratch = np.zeros((k.N_SCRATCH, 8))
    band = np.zeros((4 * (n_el + 1), k.BAND_WIDTH))
    k.assemble_mass(rho_a, le, scratch, band)
    x, w = np.polynomial.legendre.leggauss(8)
    local = np.zeros((8, 8))
    for xg, wg in zip(0.5 + 0.5 * x, 0.5 * w, strict=True):
        s, _, _ = hermite_reference(xg, le)
        shape = np.zeros((2, 8))
        shape[0, 0::2] = s
        shape[1, 1::2] = s
        local += rho_a * le * wg * shape.T @ shape
    dense = np.zeros((band.shape[0],) * 2)
    for el in range(n_el):
        dense[4 * el : 4 * el + 8, 4 * el : 4 * el + 8] += local
    got = np.zeros_like(dense)
    for i in range(dense.shape[0]):
        for j in range(max(0, i - k.KL), min(dense.shape[0], i + k.KU + 1)):
            got[i, j] = band[i, j - i + k.KL]
    np.testing.assert_allclose(got, dense, rtol=1e-13, atol=1e-18)
    translation = np.zeros(dense.shape[0])
    translation[0::4] = 1.0  # every node moved by 1 m along x, slopes unchanged
    assert translation @ dense @ translation == pytest.approx(rho_a * le * n_el, rel=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_band_lu_solves_like_numpy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 24
    dense = np.zeros((n, n))
    for i in range(n):
        for j in range(max(0, i - k.KL), min(n, i + k.KU + 1)):
            dense[i, j] = rng.normal()
    dense[0, 0] = 0.0  # forces a row exchange
    band = np.zeros((n, k.BAND_WIDTH))
    for i in range(n):
        for j in range(max(0, i - k.KL), min(n, i + k.KU + 1)):
            band[i, j - i + k.KL] = dense[i, j]
    rhs = rng.normal(size=n)
    y = np.zeros(n)
    k.band_matvec(band, rhs, y)
    np.testing.assert_allclose(y, dense @ rhs, rtol=1e-12, atol=1e-12)
    pivots = np.zeros(n, dtype=np.int32)
    assert k.band_factor(band, pivots) == 0
    solution = rhs.copy()
    k.band_solve(band, pivots, solution)
    np.testing.assert_allclose(solution, np.linalg.solve(dense, rhs), rtol=1e-9, atol=1e-10)


def test_singular_band_is_reported() -> None:
    band = np.zeros((8, k.BAND_WIDTH))
    pivots = np.zeros(8, dtype=np.int32)
    assert k.band_factor(band, pivots) == k.KernelStatus.SINGULAR


def test_energies_of_a_straight_rope_at_rest() -> None:
    model = CableModel(RopeConfig(length_m=2.0, angle_deg=90.0), SolverConfig(elements=4, step_s=1e-3, duration_s=1))
    q, v = model.initial_state()
    energies = model.energies(q[None, :], v[None, :])
    # Hanging straight down from the origin: potential -rho A g L^2 / 2, no strain, no motion.
    rope = model.rope
    assert energies["gravity"][0] == pytest.approx(-rope.mass_per_length_kg_m * 9.81 * 2.0**2 / 2, rel=1e-12)
    assert energies["kinetic"][0] == 0.0
    assert abs(energies["axial"][0]) < 1e-25 and abs(energies["bending"][0]) < 1e-25
