"""Camera and plane files: round trips, OpenCV's own files, and OpenCV reading ours."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.host.calibration.files import read_camera, read_plane, write_camera, write_plane
from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.shared.errors import DataError

CAMERA = CameraModel(
    np.array([[1495.2, 0, 508.1], [0, 1483.3, 275.6], [0, 0, 1]]),
    np.array([-0.18, 0.39, 1e-4, -2e-4, 0.01]),
    (1024, 544),
)
PLANE = PlanePose.from_rvec([0.02, -0.03, 0.01], [0.01, -0.12, 1.5])


def test_camera_round_trip_and_opencv_reads_it(tmp_path: Path) -> None:
    path = write_camera(tmp_path / "sub" / "camera.yaml", CAMERA, 0.123, {"nframes": 7, "per_view": np.ones((7, 1))})
    loaded = read_camera(path)
    assert np.array_equal(loaded.camera.camera_matrix, CAMERA.camera_matrix)
    assert np.array_equal(loaded.camera.distortion, CAMERA.distortion)
    assert loaded.camera.image_size == (1024, 544)
    assert loaded.avg_reprojection_error_px == 0.123
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert storage.getNode("nframes").real() == 7
    assert storage.getNode("distortion_coefficients").mat().shape == (5, 1)
    storage.release()


def test_reads_opencv_published_file(opencv_chessboard_dir: Path) -> None:
    loaded = read_camera(opencv_chessboard_dir / "left_intrinsics.yml")
    assert loaded.camera.fx == pytest.approx(535.915733961632)
    assert loaded.camera.image_size == (640, 480)
    assert loaded.avg_reprojection_error_px == pytest.approx(0.39259098975581364)


def test_plane_round_trip(tmp_path: Path) -> None:
    path = write_plane(tmp_path / "plane.yaml", CAMERA, PLANE, {"origin_board_mm": np.array([[-30.0], [-60.0]])})
    loaded = read_plane(path)
    assert np.allclose(loaded.plane.rotation, PLANE.rotation, atol=1e-15)
    assert np.array_equal(loaded.plane.translation_m, PLANE.translation_m)
    assert np.array_equal(loaded.camera.camera_matrix, CAMERA.camera_matrix)
    assert np.array_equal(loaded.metadata["origin_board_mm"], [-30.0, -60.0])
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    rvec = storage.getNode("plane_rvec").mat().ravel()
    storage.release()
    assert np.allclose(rvec, PLANE.rvec)


def test_plane_file_is_not_a_camera_file_and_vice_versa(tmp_path: Path) -> None:
    camera_path = write_camera(tmp_path / "camera.yaml", CAMERA, 0.1)
    with pytest.raises(DataError, match=r"camera.yaml: key 'plane_rotation' is missing"):
        read_plane(camera_path)
    bad = tmp_path / "bad.yaml"
    bad.write_text(camera_path.read_text().replace("rows: 3\n   cols: 3", "rows: 1\n   cols: 3", 1).replace(
        "data: [ 1495.2", "data: [ 1495.2, 0., 508.1 ]\n   ignored: [ 1495.2", 1))  # fmt: skip
    with pytest.raises(DataError, match=r"bad.yaml"):
        read_camera(bad)


def test_unwritable_output_names_the_file(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    with pytest.raises(DataError, match=r"a_file/camera.yaml: cannot open for writing"):
        write_camera(blocker / "camera.yaml", CAMERA, 0.1)
