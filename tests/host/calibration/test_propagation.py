"""Error propagation: closed form for a fronto-parallel plane seen by a pinhole camera."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.host.calibration.propagation import error_table, mm_per_px, propagate_pixel_error
from ropecam.shared.errors import CalibrationError

PINHOLE = CameraModel(np.array([[1500.0, 0, 512], [0, 1400.0, 272], [0, 0, 1]]), np.zeros(5), (1024, 544))
FRONTO = PlanePose(np.eye(3), np.array([0.0, 0.0, 1.5]))


def test_fronto_parallel_jacobian_is_distance_over_focal_length() -> None:
    j = mm_per_px([[100.0, 50.0], [512.0, 272.0]], PINHOLE, FRONTO)
    assert j.shape == (2, 2, 2)
    assert np.allclose(j[:, 0, 0], 1500.0 / 1500.0, rtol=1e-9)
    assert np.allclose(j[:, 1, 1], 1500.0 / 1400.0, rtol=1e-9)
    assert np.allclose(j[:, 0, 1], 0.0, atol=1e-9) and np.allclose(j[:, 1, 0], 0.0, atol=1e-9)


def test_error_map_and_table() -> None:
    error_map = propagate_pixel_error(PINHOLE, FRONTO, 0.5, 2.0, step_px=64)
    assert error_map.sigma_x_mm.shape == (len(error_map.v_px), len(error_map.u_px))
    assert np.allclose(error_map.sigma_x_mm, 0.5, rtol=1e-6)
    assert np.allclose(error_map.sigma_y_mm, 2.0 * 1500 / 1400, rtol=1e-6)
    assert np.allclose(error_map.sigma_max_mm, error_map.sigma_y_mm)
    table = error_table(PINHOLE, FRONTO, (0.06, 0.46), (0.17, 1.0))
    assert table["average_x_mm"] == pytest.approx(0.06)
    assert table["maximum_y_mm"] == pytest.approx(1500 / 1400)


def test_tilted_plane_grows_errors_with_distance() -> None:
    rotation = np.array([[1, 0, 0], [0, np.cos(0.5), -np.sin(0.5)], [0, np.sin(0.5), np.cos(0.5)]])
    error_map = propagate_pixel_error(PINHOLE, PlanePose(rotation, np.array([0, 0, 1.5])), 1.0, step_px=64)
    column = error_map.sigma_y_mm[:, 0]
    assert np.all(np.diff(column) > 0)  # plane y tilts away from the camera: lower rows see farther points
    edge_on = PlanePose(np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]), np.array([0, 0.0, 1.5]))
    with pytest.raises(CalibrationError, match="cannot propagate"):
        propagate_pixel_error(PINHOLE, edge_on, 1.0)
