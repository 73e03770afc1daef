"""Cantilever statics against the small-deflection formulas and the large-deflection elastica."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from ropecam.host.model import RopeConfig
from ropecam.host.model.statics import solve_static
from ropecam.shared.errors import ModelError


def elastica_tip(length_m: float, ei_nm2: float, weight_n_m: float, tip_load_n: float) -> np.ndarray:
    """Tip (x, y-down) of an inextensible horizontal cantilever: EI theta'' = -(P + w (L - s)) cos theta.

    Shooting on theta'(0) until the free end carries no moment (theta'(L) = 0).
    """

    def shoot(curvature0: float):
        def rhs(s, y):
            theta, dtheta, _, _ = y
            return [dtheta, -(tip_load_n + weight_n_m * (length_m - s)) * np.cos(theta) / ei_nm2,
                    np.cos(theta), np.sin(theta)]  # fmt: skip

        return solve_ivp(rhs, (0, length_m), [0, curvature0, 0, 0], rtol=1e-12, atol=1e-14)

    upper = (tip_load_n * length_m + weight_n_m * length_m**2 / 2) / ei_nm2
    curvature0 = brentq(lambda c: shoot(c).y[1, -1], 0.0, upper, xtol=1e-14)
    return shoot(curvature0).y[2:, -1]


def test_small_deflection_under_own_weight() -> None:
    rope = RopeConfig(length_m=0.2, fixed_end="clamped")
    w = rope.mass_per_length_kg_m * rope.gravity_m_s2
    expected = w * 0.2**4 / (8 * rope.bending_stiffness_nm2)
    tip = solve_static(rope, elements=4, load_steps=1).tip()[0]
    assert tip[1] == pytest.approx(expected, rel=2e-3)  # small-deflection theory is itself this far off here


def test_small_deflection_under_tip_load() -> None:
    rope = RopeConfig(length_m=0.2, fixed_end="clamped", gravity_m_s2=0.0)
    load = 1e-4
    expected = load * 0.2**3 / (3 * rope.bending_stiffness_nm2)
    tip = solve_static(rope, elements=2, tip_load_n=(0.0, load), load_steps=1).tip()[0]
    assert tip[1] == pytest.approx(expected, rel=1e-3)


@pytest.mark.parametrize(("weight", "load"), [(True, 0.0), (False, 5e-3), (True, 2e-3)])
def test_large_deflection_matches_elastica(weight: bool, load: float) -> None:
    """The paper's rope as a 1 m cantilever sags far beyond small-deflection theory."""
    rope = RopeConfig(
        fixed_end="clamped", gravity_m_s2=9.81 if weight else 0.0
    )  # EA = 97 kN: stretch ~1e-7, far below the tolerance
    w = rope.mass_per_length_kg_m * rope.gravity_m_s2
    expected = elastica_tip(rope.length_m, rope.bending_stiffness_nm2, w, load)
    tip = solve_static(rope, elements=32, tip_load_n=(0.0, load), load_steps=20).tip()[0]
    assert expected[1] > 0.15  # really large: tens of centimetres
    np.testing.assert_allclose(tip, expected, atol=2e-5)


def test_static_solution_converges_with_element_count() -> None:
    rope = RopeConfig(fixed_end="clamped")
    expected = elastica_tip(rope.length_m, rope.bending_stiffness_nm2, rope.mass_per_length_kg_m * 9.81, 0.0)
    errors = [np.linalg.norm(solve_static(rope, elements=n).tip()[0] - expected) for n in (2, 4, 8, 16, 32)]
    assert all(a > 3 * b for a, b in itertools.pairwise(errors))
    assert errors[-1] < 1e-5


def test_statics_refuses_a_pinned_rope() -> None:
    with pytest.raises(ModelError, match="clamped"):
        solve_static(RopeConfig(), elements=4)
