"""Identification recovers known parameters from model-generated measurements with noise."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ropecam.host.compare.identify import fit_parameters
from ropecam.host.compare.tracks import MaterialPointTracks, model_positions, point_errors
from ropecam.host.model import RopeConfig, SolverConfig, simulate

TRUE_EI = 4e-5
TRUE_T0 = 0.0123


def _measure(rope: RopeConfig, solver: SolverConfig, noise_m: float, seed: int = 0) -> MaterialPointTracks:
    """Material points at the start and end of each 4 ms exposure of a 119 FPS camera, with noise."""
    frames = np.arange(40) / 119.0 + 0.005
    times = np.sort(np.concatenate([frames, frames + 0.004]))
    s = np.array([0.1, 0.2, 0.3, rope.length_m])
    truth = simulate(rope, dataclasses.replace(solver, duration_s=times[-1] - TRUE_T0 + 0.01))
    clean = MaterialPointTracks(times, s, np.zeros((times.size, s.size, 2)))
    positions = model_positions(truth, clean, TRUE_T0)
    positions += np.random.default_rng(seed).normal(0.0, noise_m, positions.shape)
    positions[5, 2] = np.nan  # a point the camera missed
    return MaterialPointTracks(times, s, positions)


@pytest.fixture(scope="module")
def rig() -> tuple[RopeConfig, SolverConfig]:
    return RopeConfig(length_m=0.411, ei_nm2=TRUE_EI), SolverConfig(elements=8, step_s=1e-3, duration_s=0.4)


def test_true_model_has_small_error(rig) -> None:
    rope, solver = rig
    tracks = _measure(rope, solver, noise_m=2e-4)
    trajectory = simulate(rope, dataclasses.replace(solver, duration_s=0.4))
    errors = point_errors(tracks, model_positions(trajectory, tracks, TRUE_T0))
    assert errors.rms_m.shape == (4,)
    assert np.all(errors.rms_m < 3.5e-4) and np.isnan(errors.error_m[5, 2])
    assert errors.overall_rms_m == pytest.approx(2e-4 * np.sqrt(2), rel=0.2)


def test_recovers_ei_from_a_factor_three_and_the_release_time(rig) -> None:
    rope, solver = rig
    tracks = _measure(rope, solver, noise_m=2e-4)
    wrong = dataclasses.replace(rope, ei_nm2=3 * TRUE_EI)
    result = fit_parameters(tracks, wrong, solver, names=("ei", "t0"), release_time_s=0.0)
    assert result.values["ei"] == pytest.approx(TRUE_EI, rel=0.05)
    assert abs(result.release_time_s - TRUE_T0) < 0.5e-3
    assert result.rms_after_m < 0.2 * result.rms_before_m
    # The stated uncertainty is honest: the truth lies within 4 standard errors.
    assert abs(result.values["ei"] - TRUE_EI) < 4 * result.std_errors["ei"] + 1e-12
    assert result.rope.ei_nm2 == result.values["ei"]


def test_rejects_unknown_parameters(rig) -> None:
    rope, solver = rig
    tracks = MaterialPointTracks(np.array([0.0]), np.array([0.1]), np.zeros((1, 1, 2)))
    with pytest.raises(ValueError, match="among ei, damping, drag, t0"):
        fit_parameters(tracks, rope, solver, names=("stiffness",))
