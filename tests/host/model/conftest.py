"""Slow, obvious reference implementations of the ANCF cable element, for checking the kernels."""

from __future__ import annotations

import numpy as np
import pytest


def _hermite_numpy(xi: float, le: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shape functions and their first and second arc-length derivatives, written out plainly."""
    s = np.array(
        [1 - 3 * xi**2 + 2 * xi**3, le * (xi - 2 * xi**2 + xi**3), 3 * xi**2 - 2 * xi**3, le * (xi**3 - xi**2)]
    )
    s1 = np.array([(-6 * xi + 6 * xi**2) / le, 1 - 4 * xi + 3 * xi**2, (6 * xi - 6 * xi**2) / le, -2 * xi + 3 * xi**2])
    s2 = np.array([(-6 + 12 * xi) / le**2, (-4 + 6 * xi) / le, (6 - 12 * xi) / le**2, (-2 + 6 * xi) / le])
    return s, s1, s2


def _element_energy(e: np.ndarray, le: float, ea: float, ei: float) -> float:
    """Strain energy of one element by direct evaluation (numpy's Gauss-Legendre, 5 and 3 points)."""
    energy = 0.0
    for order, part in ((5, "axial"), (3, "bending")):
        x, w = np.polynomial.legendre.leggauss(order)
        for xg, wg in zip(0.5 + 0.5 * x, 0.5 * w, strict=True):
            _, s1, s2 = _hermite_numpy(xg, le)
            rp = np.array([s1 @ e[0::2], s1 @ e[1::2]])
            rpp = np.array([s2 @ e[0::2], s2 @ e[1::2]])
            if part == "axial":
                energy += 0.5 * ea * (np.linalg.norm(rp) - 1.0) ** 2 * wg * le
            else:
                kappa = (rp[0] * rpp[1] - rp[1] * rpp[0]) / (rp @ rp)
                energy += 0.5 * ei * kappa**2 * wg * le
    return energy


@pytest.fixture
def bent_element() -> tuple[np.ndarray, float]:
    """A stretched, curved element: coordinates (x, y, x', y') at both ends and its length."""
    le = 0.0625
    e = np.array([0.01, 0.02, 0.98, 0.15, 0.07, 0.035, 0.93, 0.42])
    return e, le


@pytest.fixture
def hermite_reference():
    """The plain shape-function formulas: (xi, le) -> (S, dS/ds, d2S/ds2)."""
    return _hermite_numpy


@pytest.fixture
def element_energy():
    """Strain energy of one element: (e, le, EA, EI) -> J."""
    return _element_energy
