"""The plane pose: frame conventions, origin choices and the joint fit of several board placements."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ropecam.host.calibration.board import Chessboard
from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane, plane_to_pixels
from ropecam.host.calibration.plane import calibrate_plane
from ropecam.host.sim.boards import BoardArt, make_calibration_set
from ropecam.shared.errors import CalibrationError

CAMERA = CameraModel(
    np.array([[700.0, 0, 321.0], [0, 690.0, 238.0], [0, 0, 1]]), np.array([-0.15, 0.1, 0, 0, 0]), (640, 480)
)
ART = BoardArt(Chessboard(6, 5, 0.02), margin_m=0.01)


@pytest.fixture(scope="module")
def calib_set():
    return make_calibration_set(CAMERA, ART, n_views=4, plane_distance_m=0.9, seed=11)


def test_axes_follow_the_image_and_origin_is_the_fixed_end(calib_set) -> None:
    result = calibrate_plane(calib_set.plane_view.image, CAMERA, ART.board, origin_px=calib_set.origin_px)
    x_axis, y_axis = result.plane.rotation[:, 0], result.plane.rotation[:, 1]
    assert x_axis[0] > 0.99 and y_axis[1] > 0.99  # x right, y down (gravity) for a level board and upright camera
    assert np.allclose(plane_to_pixels(np.zeros(2), CAMERA, result.plane), calib_set.origin_px, atol=1e-6)
    by_mm = calibrate_plane(calib_set.plane_view.image, CAMERA, ART.board, origin_mm=calib_set.origin_mm)
    assert np.allclose(by_mm.plane.translation_m, calib_set.plane_pose.translation_m, atol=5e-4)
    assert np.allclose(result.plane.translation_m, by_mm.plane.translation_m, atol=5e-4)
    default = calibrate_plane(calib_set.plane_view.image, CAMERA, ART.board)
    assert np.allclose(default.origin_board_m, 0.0)
    assert len(result.corners_px) == ART.board.n_corners and result.report.max_v_px < 0.1


def test_board_seen_upside_down_keeps_the_axes(calib_set) -> None:
    # Rotate the board 180 degrees within the plane: OpenCV may number its corners from the other end,
    # the corner ordering keeps x to the right and y down.
    pose = calib_set.plane_view.pose
    flip = np.diag([-1.0, -1.0, 1.0])
    span = np.array([(ART.board.cols - 1) * ART.board.square_m, (ART.board.rows - 1) * ART.board.square_m, 0])
    flipped = PlanePose(pose.rotation @ flip, pose.translation_m + pose.rotation @ span)
    from ropecam.host.sim.boards import render_board_view

    image = render_board_view(CAMERA, flipped, ART, np.random.default_rng(1))
    result = calibrate_plane(image, CAMERA, ART.board)
    assert result.plane.rotation[0, 0] > 0.99 and result.plane.rotation[1, 1] > 0.99
    assert np.allclose(result.board_pose.rotation, pose.rotation, atol=2e-3)


def test_extra_placements_are_fitted_in_one_plane(calib_set) -> None:
    extra = [(view.name, view.image) for view in calib_set.extra_plane_views]
    single = calibrate_plane(calib_set.plane_view.image, CAMERA, ART.board, origin_mm=calib_set.origin_mm)
    joint = calibrate_plane(
        calib_set.plane_view.image, CAMERA, ART.board, origin_mm=calib_set.origin_mm, extra_images=extra
    )
    assert len(joint.detections) == 3 and len(joint.corners_px) == 3 * ART.board.n_corners
    normal = calib_set.plane_pose.rotation[:, 2]
    tilt = lambda r: np.degrees(np.arccos(np.clip(r.plane.rotation[:, 2] @ normal, -1, 1)))  # noqa: E731
    assert tilt(joint) < 0.05
    assert joint.report.rotation_sigma_deg < single.report.rotation_sigma_deg
    # Every extra board's corners land on their true plane positions.
    for view in calib_set.extra_plane_views:
        truth_m = ART.board.object_points()[:, :2].astype(np.float64)
        pixels = plane_to_pixels(truth_m, CAMERA, view.pose)
        board_in_plane = pixels_to_plane(pixels, CAMERA, joint.plane)
        expected = pixels_to_plane(pixels, CAMERA, calib_set.plane_pose)
        assert np.max(np.abs(board_in_plane - expected)) < 3e-4


def test_wrong_camera_and_bad_origin(calib_set) -> None:
    image = calib_set.plane_view.image
    # A board near the image edge seen through a grossly wrong distortion model cannot be fitted.
    wrong = CameraModel(CAMERA.camera_matrix, np.array([2.0, 0.0, 0.0, 0.0, 0.0]), CAMERA.image_size)
    edge_image = calib_set.extra_plane_views[0].image
    with pytest.raises(
        CalibrationError, match=r"edge\.png: the board reprojects with .* px RMS .*wrong\.yaml does not"
    ):
        calibrate_plane(edge_image, wrong, ART.board, source="edge.png", max_rms_px=0.3, camera_source="wrong.yaml")
    with pytest.raises(ValueError, match="either as origin_px or as origin_mm"):
        calibrate_plane(image, CAMERA, ART.board, origin_px=(1, 2), origin_mm=(1, 2))
    small = cv2.resize(image, (320, 240))
    with pytest.raises(CalibrationError, match=r"extra\.png is 320x240 px"):
        calibrate_plane(image, CAMERA, ART.board, extra_images=[("extra.png", small)])
