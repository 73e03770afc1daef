"""Trajectory evaluation: exact at nodes, Hermite inside elements and in time, round trip to disk."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ropecam.host.model.trajectory import Trajectory
from ropecam.shared.errors import DataError


def _rotating_rod(omega: float = 2.0, length: float = 1.0, elements: int = 4) -> Trajectory:
    """A rigid rod turning at constant rate: exactly representable in space, smooth in time."""
    t = np.linspace(0.0, 0.5, 51)
    s = np.linspace(0.0, length, elements + 1)
    phi = omega * t
    direction = np.stack([np.cos(phi), np.sin(phi)], axis=-1)  # (T, 2)
    rate = omega * np.stack([-np.sin(phi), np.cos(phi)], axis=-1)
    q = np.concatenate([s[None, :, None] * direction[:, None, :], np.repeat(direction[:, None, :], s.size, 1)], 2)
    v = np.concatenate([s[None, :, None] * rate[:, None, :], np.repeat(rate[:, None, :], s.size, 1)], 2)
    return Trajectory(length, t, q.reshape(t.size, -1), v.reshape(t.size, -1))


def test_positions_inside_elements_and_between_samples() -> None:
    trajectory = _rotating_rod()
    t = np.array([0.0, 0.123, 0.3333, 0.5])
    s = np.array([0.0, 0.1, 0.37, 1.0])
    expected = s[None, :, None] * np.stack([np.cos(2 * t), np.sin(2 * t)], -1)[:, None, :]
    np.testing.assert_allclose(trajectory.positions(t, s), expected, atol=1e-9)
    velocity = s[None, :, None] * 2.0 * np.stack([-np.sin(2 * t), np.cos(2 * t)], -1)[:, None, :]
    np.testing.assert_allclose(trajectory.velocities(t, s), velocity, atol=1e-6)
    np.testing.assert_allclose(trajectory.tip(), trajectory.sample_positions([1.0])[:, 0])


def test_out_of_range_requests_are_refused() -> None:
    trajectory = _rotating_rod()
    with pytest.raises(ValueError, match="arc lengths"):
        trajectory.positions([0.1], [1.5])
    with pytest.raises(ValueError, match="times must lie in"):
        trajectory.positions([0.6], [0.5])


def test_save_and_load(tmp_path: Path) -> None:
    trajectory = _rotating_rod()
    trajectory.energies["kinetic"] = np.arange(51.0)
    trajectory.save(tmp_path / "t.npz")
    loaded = Trajectory.load(tmp_path / "t.npz")
    np.testing.assert_array_equal(loaded.q, trajectory.q)
    np.testing.assert_array_equal(loaded.energies["kinetic"], np.arange(51.0))
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(DataError, match=r"bad\.npz"):
        Trajectory.load(tmp_path / "bad.npz")
