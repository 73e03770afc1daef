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


def _rolling_shape(t0_s: float, s_m: np.ndarray, line_s: float) -> tuple[np.ndarray, np.ndarray]:
    """A rope bent to an arc of radius 0.25 m swinging about the plane origin at 8 rad/s as a rolling shutter sees
    it: each point at ``t0_s`` + its image row x `line_s` (the fixed point solved). Returns the (row, col) pixels
    and the (x, y) metres of the points `s_m`."""
    bent = np.column_stack([0.25 * (1.0 - np.cos(s_m / 0.25)), 0.25 * np.sin(s_m / 0.25)])
    t = np.full(s_m.size, t0_s)
    for _ in range(50):
        c, s = np.cos(0.3 + 8.0 * t), np.sin(0.3 + 8.0 * t)
        metres = np.column_stack([c * bent[:, 0] + s * bent[:, 1], 0.05 - s * bent[:, 0] + c * bent[:, 1]])
        uv = PLANE.project(metres)
        t = t0_s + uv[:, 1] * line_s
    return uv[:, ::-1].copy(), metres


def test_rolling_shutter_points_by_the_ropes_arc_length_at_one_instant() -> None:
    # A rolling shutter sees each point at its own row's time: the shape's arc length is not the rope's. The
    # material points are placed by the rope's arc length at one instant (the velocity from the other shape).
    exposure_s, line_s = 0.004, 0.007 / 480
    s_dense = np.linspace(0.0, 0.4, 2001)
    fraction = np.array([0.25, 0.5, 0.75, 1.0])
    shapes, truth = [], []
    for t0 in (0.0, exposure_s):
        rc, _ = _rolling_shape(t0, s_dense, line_s)
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(rc, axis=0).T))])
        spaced = np.linspace(0.0, arc[-1], int(arc[-1] / 2.0))  # 2 px apart, as the pipeline's output
        shapes.append(np.column_stack([np.interp(spaced, arc, rc[:, k]) for k in range(2)]).astype(np.float32))
        truth.append(_rolling_shape(t0, 0.4 * fraction, line_s)[1])
    out = np.zeros((2, 4, 2), np.float32)
    work = np.zeros(K.ROLLING_WORK * (len(shapes[0]) + len(shapes[1])))
    errors = {}
    for rolling in (0.0, line_s / exposure_s):
        params = plane_params(PLANE).copy()
        params[K.PLANE.rolling] = rolling
        assert K.place_on_plane(shapes[0], shapes[1], False, fraction, params, out, work) == 4
        placed = [PLANE.to_plane(out[slot][:, ::-1].astype(np.float64)) for slot in range(2)]
        errors[rolling] = max(float(np.abs(placed[k] - truth[k]).max()) for k in range(2))
    without, with_rolling = errors.values()
    assert without > 2e-4  # by the shapes' own arc lengths: 0.3 mm off along the rope
    assert with_rolling < 0.05 * without
    # A work buffer too short for the rolling placement: the shapes' own arc lengths (as without).
    assert K.place_on_plane(shapes[0], shapes[1], False, fraction, params, out, work[: len(shapes[0]) + 1]) == 4
    placed = PLANE.to_plane(out[0][:, ::-1].astype(np.float64))
    assert float(np.abs(placed - truth[0]).max()) > 0.5 * without
