"""Material points by arc length on the plane (`_kernels/plane.py`) against a slow reference: the shape mapped to
the plane by `PlaneCalibration.to_plane` (NumPy), its points placed by `np.interp` of the cumulative length."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.tracking import plane_params
from ropecam.shared.plane import PlaneCalibration

pytestmark = pytest.mark.kernel

PLANE = PlaneCalibration(
    np.array([[900.0, 0.0, 330.0], [0.0, 905.0, 250.0], [0.0, 0.0, 1.0]]),
    np.array([-0.2, 0.09, 0.002, -0.003, 0.02]),
    (640, 480),
    np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.4), -np.sin(0.4)], [0.0, np.sin(0.4), np.cos(0.4)]]),
    np.array([0.02, -0.3, 1.2]),
)


def _reference(shape_rc: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    metres = PLANE.to_plane(shape_rc[:, ::-1].astype(np.float64))
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(metres, axis=0).T))])
    targets = fraction * arc[-1]
    return np.column_stack([np.interp(targets, arc, shape_rc[:, 0]), np.interp(targets, arc, shape_rc[:, 1])])


def test_pixel_to_plane_is_the_calibrations_mapping() -> None:
    params = plane_params(PLANE)
    rng = np.random.default_rng(3)
    for row, col in rng.uniform((0, 0), (480, 640), (20, 2)):
        np.testing.assert_allclose(K.pixel_to_plane(row, col, params), PLANE.to_plane([[col, row]])[0], atol=1e-9)


def test_points_by_plane_arc_length_match_the_reference() -> None:
    s = np.linspace(0.0, 1.0, 60)
    begin = np.column_stack([40.0 + 400.0 * s, 320.0 + 150.0 * np.sin(2.5 * s)]).astype(np.float32)
    end = np.column_stack([40.0 + 380.0 * s, 320.0 - 200.0 * s**2]).astype(np.float32)
    fraction = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    out = np.zeros((2, 5, 2), np.float32)
    work = np.zeros(64)
    assert K.place_on_plane(begin, end, False, fraction, plane_params(PLANE), out, work) == 5
    np.testing.assert_allclose(out[0], _reference(begin, fraction), atol=2e-3)
    np.testing.assert_allclose(out[1], _reference(end, fraction), atol=2e-3)
    # By pixels the middle points would be elsewhere: the tilt makes the plane arc length differ.
    arc_px = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(begin.astype(np.float64), axis=0).T))])
    by_pixels = [np.interp(0.5 * arc_px[-1], arc_px, begin[:, k]) for k in range(2)]
    assert np.hypot(*(out[0, 2] - by_pixels)) > 2.0
    # One shape given twice: the end's points are the begin's.
    assert K.place_on_plane(begin, begin, True, fraction, plane_params(PLANE), out, work) == 5
    np.testing.assert_array_equal(out[0], out[1])
