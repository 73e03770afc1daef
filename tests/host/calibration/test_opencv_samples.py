"""Acceptance 1: OpenCV's own chessboard set gives OpenCV's published calibration, in a file OpenCV reads."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.host.calibration.files import read_camera
from ropecam.host.cli import main

PUBLISHED_RMS_PX = 0.39259098975581364
PUBLISHED_CX_CY = (342.28315473308373, 235.57082909788173)
PUBLISHED_F = 535.915733961632


@pytest.fixture(scope="module")
def left_images(opencv_chessboard_dir: Path) -> list[str]:
    images = sorted(str(p) for p in opencv_chessboard_dir.glob("left*.jpg"))
    assert len(images) == 13
    return images


def test_cli_reproduces_opencv_published_calibration(left_images: list[str], tmp_path: Path, capsys) -> None:
    out = tmp_path / "left.yaml"
    # The settings of OpenCV's calibration sample that wrote left_intrinsics.yml (see SOURCES.md of the set).
    code = main(
        ["calibrate", "intrinsics", *left_images, "--board", "9x6", "--square-mm", "25", "--fix-aspect-ratio",
         "--corner-refine", "subpix", "--subpix-window", "11", "--subpix-eps", "0.1", "--out", str(out)]
    )  # fmt: skip
    assert code == 0
    assert "total RMS reprojection error" in capsys.readouterr().out
    storage = cv2.FileStorage(str(out), cv2.FILE_STORAGE_READ)
    assert storage.isOpened()
    k = storage.getNode("camera_matrix").mat()
    rms = storage.getNode("avg_reprojection_error").real()
    dist = storage.getNode("distortion_coefficients").mat()
    assert int(storage.getNode("image_width").real()) == 640
    assert int(storage.getNode("image_height").real()) == 480
    assert storage.getNode("per_view_reprojection_errors").mat().shape == (13, 1)
    storage.release()
    assert abs(rms / PUBLISHED_RMS_PX - 1) < 0.02
    assert abs(k[0, 2] - PUBLISHED_CX_CY[0]) < 1.0
    assert abs(k[1, 2] - PUBLISHED_CX_CY[1]) < 1.0
    assert k[0, 0] == pytest.approx(k[1, 1])
    assert k[0, 0] == pytest.approx(PUBLISHED_F, rel=2e-3)
    assert dist.shape == (5, 1)
    assert (tmp_path / "left.png").stat().st_size > 10_000


def test_default_refinement_fits_better_than_opencv_sample(left_images: list[str], opencv_chessboard_dir: Path) -> None:
    """Auto window + saddle refinement: the outlier view left02 (window too large for its squares) is fixed."""
    from ropecam.host.calibration.board import parse_board
    from ropecam.host.calibration.intrinsics import calibrate_intrinsics

    result = calibrate_intrinsics(left_images, parse_board("9x6", 25), fix_aspect_ratio=True)
    assert result.rms_px < 0.25
    assert len(result.used) == 13 and not result.failed
    assert np.all(result.per_view_rms_px < 0.45)
    published = read_camera(opencv_chessboard_dir / "left_intrinsics.yml").camera
    # Distortion compared through the points, not coefficient by coefficient (k2/k3 trade off).
    grid = np.stack(np.meshgrid(np.linspace(80, 560, 7), np.linspace(60, 420, 5)), axis=-1).reshape(-1, 2)
    ours = result.camera.undistort(grid) * published.fx
    theirs = published.undistort(grid) * published.fx
    assert np.max(np.linalg.norm(ours - theirs, axis=1)) < 5.0
