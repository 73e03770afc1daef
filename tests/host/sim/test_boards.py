"""The chessboard renderer and calibration-set generator: geometry against projection, determinism, files."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.host.calibration.board import Chessboard, detect_corners
from ropecam.host.calibration.geometry import CameraModel, PlanePose, plane_to_pixels
from ropecam.host.sim.boards import (
    BoardArt,
    RenderSettings,
    make_calibration_set,
    paper_camera,
    pixel_rays,
    read_calibration_set,
    render_board_view,
    write_calibration_set,
)
from ropecam.shared.errors import DataError

SMALL_CAMERA = CameraModel(
    np.array([[420.0, 0, 161.0], [0, 415.0, 118.5], [0, 0, 1]]), np.array([-0.2, 0.1, 0, 0, 0]), (320, 240)
)
SMALL_ART = BoardArt(Chessboard(6, 5, 0.02), margin_m=0.01)


def _pose(tilt_deg: float = 20.0, distance_m: float = 0.55) -> PlanePose:
    rotation, _ = cv2.Rodrigues(np.array([np.radians(tilt_deg), np.radians(10.0), 0.05]))
    centre = np.array([0.05, 0.04, 0.0])
    return PlanePose(rotation, np.array([0.0, 0.0, distance_m]) - rotation @ centre)


def test_rendered_corners_are_where_the_camera_projects_them() -> None:
    pose = _pose()
    image = render_board_view(SMALL_CAMERA, pose, SMALL_ART, np.random.default_rng(0))
    assert image.shape == (240, 320) and image.dtype == np.uint8
    detection = detect_corners(image, SMALL_ART.board, "render")
    truth = plane_to_pixels(SMALL_ART.board.object_points()[:, :2].astype(np.float64), SMALL_CAMERA, pose)
    error = np.linalg.norm(detection.corners - truth, axis=1)
    assert error.max() < 0.1
    assert np.sqrt(np.mean(error**2)) < 0.05


def test_top_left_square_is_dark_and_margin_white() -> None:
    pose = PlanePose(np.eye(3), np.array([-0.05, -0.04, 0.5]))  # fronto-parallel, board centred
    image = render_board_view(SMALL_CAMERA, pose, SMALL_ART, np.random.default_rng(0), RenderSettings(noise_std=0))
    centre_dark = plane_to_pixels(np.array([-0.01, -0.01]), SMALL_CAMERA, pose)
    centre_light = plane_to_pixels(np.array([0.01, -0.01]), SMALL_CAMERA, pose)
    margin = plane_to_pixels(np.array([-0.025, 0.04]), SMALL_CAMERA, pose)
    background = plane_to_pixels(np.array([-0.06, 0.04]), SMALL_CAMERA, pose)
    level = lambda uv: int(image[round(uv[1]), round(uv[0])])  # noqa: E731
    assert level(centre_dark) == pytest.approx(SMALL_ART.dark, abs=3)
    assert level(centre_light) == pytest.approx(SMALL_ART.light, abs=3)
    assert level(margin) == pytest.approx(SMALL_ART.light, abs=3)
    assert level(background) == pytest.approx(SMALL_ART.background, abs=3)


def test_same_seed_same_image_and_supersampling_agrees() -> None:
    pose = _pose()
    first = render_board_view(SMALL_CAMERA, pose, SMALL_ART, np.random.default_rng(7))
    again = render_board_view(SMALL_CAMERA, pose, SMALL_ART, np.random.default_rng(7))
    other = render_board_view(SMALL_CAMERA, pose, SMALL_ART, np.random.default_rng(8))
    assert np.array_equal(first, again) and not np.array_equal(first, other)
    quiet = RenderSettings(noise_std=0)
    fine = RenderSettings(supersample=4, noise_std=0)
    one = render_board_view(SMALL_CAMERA, pose, SMALL_ART, np.random.default_rng(0), quiet).astype(float)
    four = render_board_view(SMALL_CAMERA, pose, SMALL_ART, np.random.default_rng(0), fine, pixel_rays(SMALL_CAMERA, 4))
    assert np.mean(np.abs(one - four)) < 1.0


def test_calibration_set_covers_the_image_with_tilted_views(tmp_path: Path) -> None:
    calib_set = make_calibration_set(SMALL_CAMERA, SMALL_ART, n_views=8, plane_distance_m=0.9, seed=4)
    assert len(calib_set.views) == 8
    tilts = [np.degrees(np.arccos(view.pose.rotation[2, 2])) for view in calib_set.views]
    assert min(tilts) > 12 and max(tilts) < 50
    centres = [plane_to_pixels(np.array([0.05, 0.04]), SMALL_CAMERA, view.pose) for view in calib_set.views]
    assert np.ptp([c[0] for c in centres]) > 0.3 * 320
    # The rope's fixed end is the plane frame's origin, and the plane board sits where origin_mm says.
    origin = plane_to_pixels(np.zeros(2), SMALL_CAMERA, calib_set.plane_pose)
    assert np.allclose(origin, calib_set.origin_px)
    board_origin = calib_set.plane_view.pose.translation_m
    fixed_end = board_origin + calib_set.plane_view.pose.rotation @ np.array([*np.array(calib_set.origin_mm) / 1000, 0])
    assert np.allclose(fixed_end, calib_set.plane_pose.translation_m)

    for extra in calib_set.extra_plane_views:  # lying in the same plane: same normal, zero height above it
        assert np.allclose(extra.pose.rotation[:, 2], calib_set.plane_pose.rotation[:, 2])
        offset = calib_set.plane_pose.rotation.T @ (extra.pose.translation_m - calib_set.plane_pose.translation_m)
        assert abs(offset[2]) < 1e-12 and abs(offset[0]) > 0.05
    truth_path = write_calibration_set(calib_set, tmp_path / "set")
    names = sorted(p.name for p in (tmp_path / "set").glob("*.png"))
    assert names[:4] == ["plane.png", "plane_01.png", "plane_02.png", "view_00.png"] and len(names) == 11
    camera, plane, _truth = read_calibration_set(tmp_path / "set")
    assert np.allclose(camera.camera_matrix, SMALL_CAMERA.camera_matrix)
    assert np.allclose(plane.rotation, calib_set.plane_pose.rotation)
    assert json.loads(truth_path.read_text())["board"] == {"cols": 6, "rows": 5, "square_mm": 20.0}
    assert np.array_equal(
        cv2.imread(str(tmp_path / "set" / "view_03.png"), cv2.IMREAD_GRAYSCALE), calib_set.views[3].image
    )


def test_paper_camera_and_bad_truth(tmp_path: Path) -> None:
    camera = paper_camera()
    assert camera.image_size == (1024, 544)
    with pytest.raises(DataError, match="truth file not found"):
        read_calibration_set(tmp_path)
    (tmp_path / "truth.json").write_text("{}")
    with pytest.raises(DataError, match="malformed truth file"):
        read_calibration_set(tmp_path)
    with pytest.raises(ValueError, match="n_views"):
        make_calibration_set(SMALL_CAMERA, SMALL_ART, n_views=2)
