"""The ANCF rope against Exudyn's reference solutions, energy conservation, damping, drag and a moving support."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ropecam.host.model import CableModel, FixedEndMotion, RopeConfig, SolverConfig, simulate
from ropecam.shared.errors import ModelError


def _reference(directory: Path, name: str) -> np.ndarray:
    data = np.loadtxt(directory / name, delimiter=",", skiprows=1)
    data[:, 2] *= -1.0  # the reference files use y up; ropecam's plane frame has y down
    return data


def _max_tip_error(trajectory, reference: np.ndarray) -> float:
    tip = trajectory.tip()
    assert np.allclose(trajectory.times_s, reference[:, 0], atol=1e-9)
    return float(np.max(np.hypot(*(tip - reference[:, 1:]).T)))


def test_paper_rope_matches_exudyn_at_its_step(ancf_reference_dir: Path) -> None:
    """N = 16, h = 1e-3, generalized-alpha rho = 0.9: the same time discretisation as Exudyn's file."""
    model = CableModel(RopeConfig(), SolverConfig(elements=16, step_s=1e-3, duration_s=2.0, spectral_radius=0.9))
    trajectory, stats = model.run()
    error = _max_tip_error(trajectory, _reference(ancf_reference_dir, "exudyn_paper_rope_n16.csv"))
    assert error <= 20e-6
    # Undamped energy drift over 2 s at h = 1e-3 (acceptance: <= 1e-4 of m g L / 2).
    total = trajectory.energies["total"]
    assert np.max(np.abs(total - total[0])) <= 1e-4 * RopeConfig().potential_scale_j
    assert stats.steps == 2000 and stats.refined_steps == 0


@pytest.mark.slow
def test_paper_rope_converged_matches_best_reference(ancf_reference_dir: Path) -> None:
    """N = 32, h = 1e-4 within 5 um of Exudyn's N = 64, h = 1e-4 over the whole 2 s."""
    trajectory = simulate(RopeConfig(), SolverConfig(elements=32, step_s=1e-4, duration_s=2.0))
    error = _max_tip_error(trajectory, _reference(ancf_reference_dir, "exudyn_paper_rope_n64_h1e-4.csv"))
    assert error <= 5e-6


def test_error_shrinks_with_element_count(ancf_reference_dir: Path) -> None:
    """Spatial convergence over the first 0.5 s at h = 1e-4 against the N = 64 reference."""
    reference = _reference(ancf_reference_dir, "exudyn_paper_rope_n64_h1e-4.csv")[:501]
    errors = []
    for elements in (2, 4, 8):
        trajectory = simulate(RopeConfig(), SolverConfig(elements=elements, step_s=1e-4, duration_s=0.5))
        errors.append(_max_tip_error(trajectory, reference))
    assert errors[0] > 2 * errors[1] > 4 * errors[2]


def test_energy_is_conserved_without_numerical_damping() -> None:
    rope = RopeConfig(length_m=0.5, ei_nm2=1e-4)
    trajectory = simulate(rope, SolverConfig(elements=8, step_s=5e-4, duration_s=0.5, spectral_radius=1.0))
    total = trajectory.energies["total"]
    assert np.max(np.abs(total - total[0])) <= 1e-5 * rope.potential_scale_j
    assert trajectory.energies["kinetic"].max() > 0.5 * rope.potential_scale_j  # it really swung


@pytest.mark.parametrize(
    "losses", [{"material_damping_s": 1e-3}, {"mass_damping_per_s": 2.0}, {"drag_coefficient": 1.122}]
)
def test_damping_and_drag_only_remove_energy(losses: dict[str, float]) -> None:
    rope = RopeConfig(length_m=0.5, ei_nm2=1e-4, **losses)
    trajectory = simulate(rope, SolverConfig(elements=8, step_s=5e-4, duration_s=0.6))
    total = trajectory.energies["total"]
    assert np.all(np.diff(total) <= 1e-9 * rope.potential_scale_j)
    assert total[-1] < total[0] - 1e-3 * rope.potential_scale_j


def test_moving_support_follows_its_prescription() -> None:
    motion = FixedEndMotion(amplitude_x_m=0.02, amplitude_y_m=-0.01, frequency_hz=3.0, phase_rad=0.3)
    rope = RopeConfig(length_m=0.3, angle_deg=90.0, ei_nm2=1e-4, fixed_end_motion=motion)
    trajectory = simulate(rope, SolverConfig(elements=6, step_s=5e-4, duration_s=0.3))
    phase = 2 * np.pi * 3.0 * trajectory.times_s + 0.3
    expected = np.column_stack([0.02 * np.sin(phase), -0.01 * np.sin(phase)])
    np.testing.assert_allclose(trajectory.sample_positions([0.0])[:, 0, :], expected, atol=1e-12)
    # The rope hanging below is dragged along: its tip moves sideways.
    assert np.ptp(trajectory.tip()[:, 0]) > 1e-3


def test_clamped_end_keeps_its_slope() -> None:
    trajectory = simulate(
        RopeConfig(length_m=0.3, fixed_end="clamped", angle_deg=30.0), SolverConfig(elements=4, duration_s=0.05)
    )
    slopes = trajectory.q[:, 2:4]
    np.testing.assert_allclose(slopes, np.tile([np.cos(np.pi / 6), np.sin(np.pi / 6)], (slopes.shape[0], 1)))


def test_rigid_rotation_initial_velocity() -> None:
    model = CableModel(
        RopeConfig(angle_deg=90.0, initial_angular_velocity_rad_s=2.0), SolverConfig(elements=4, duration_s=0.01)
    )
    _, v = model.initial_state()
    # Hanging down (along +y) and turning from +x towards +y means moving towards -x.
    np.testing.assert_allclose(v.reshape(-1, 4)[:, 0], -2.0 * np.linspace(0, 1, 5))
    np.testing.assert_allclose(v.reshape(-1, 4)[:, 1], 0.0, atol=1e-15)


def test_failed_steps_are_refined_or_reported() -> None:
    """Three Newton iterations are too few for h = 2e-3: adaptive runs refine those steps, strict runs say when."""
    rope = RopeConfig(length_m=0.411, ei_nm2=4e-5)
    fine = simulate(rope, SolverConfig(elements=6, step_s=2.5e-4, duration_s=0.2, output_every_s=2e-3))
    assert fine.times_s.size == 101
    model = CableModel(
        rope, SolverConfig(elements=6, step_s=2e-3, duration_s=0.199, output_every_s=4e-3, max_iterations=3)
    )
    trajectory, stats = model.run()
    assert stats.refined_steps > 0
    # Refined steps do not shift the output grid, and the run reaches the requested duration.
    np.testing.assert_allclose(np.diff(trajectory.times_s), 4e-3, rtol=1e-9)
    assert trajectory.times_s[-1] == pytest.approx(0.2)
    assert np.max(np.abs(trajectory.tip() - fine.tip()[::2])) < 2e-3
    strict = CableModel(rope, SolverConfig(elements=6, step_s=2e-3, duration_s=0.2, max_iterations=3, adaptive=False))
    with pytest.raises(ModelError, match=r"Newton did not converge at t = [0-9.]+ s"):
        strict.run()
