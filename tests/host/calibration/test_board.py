"""Board geometry, corner order and detection."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ropecam.host.calibration.board import (
    Chessboard,
    SubpixSettings,
    detect_corners,
    order_corners,
    parse_board,
    read_gray,
    refine_saddle,
)
from ropecam.shared.errors import DataError

BOARD = Chessboard(4, 3, 0.02)


def _grid(flip_rows: bool, flip_cols: bool) -> np.ndarray:
    u, v = np.meshgrid(100 + 20.0 * np.arange(4), 50 + 20.0 * np.arange(3))
    grid = np.stack([u, v], axis=-1)
    grid = grid[::-1] if flip_rows else grid
    grid = grid[:, ::-1] if flip_cols else grid
    return grid.reshape(-1, 1, 2)


@pytest.mark.parametrize("flip_rows", [False, True])
@pytest.mark.parametrize("flip_cols", [False, True])
def test_order_corners_starts_top_left_rows_to_the_right(flip_rows: bool, flip_cols: bool) -> None:
    ordered = order_corners(_grid(flip_rows, flip_cols), BOARD)
    assert np.array_equal(ordered, _grid(False, False).reshape(-1, 2))


def test_object_points_and_parse() -> None:
    points = BOARD.object_points()
    assert points.shape == (12, 3) and points.dtype == np.float32
    assert np.allclose(points[1], [0.02, 0, 0]) and np.allclose(points[4], [0, 0.02, 0])
    assert parse_board("9x6", 25) == Chessboard(9, 6, 0.025)
    assert parse_board("8X7", 20).describe() == "8x7 inner corners, 20 mm squares"
    with pytest.raises(ValueError, match="at least 2x2"):
        Chessboard(1, 5, 0.02)


def test_saddle_refinement_finds_a_synthetic_corner() -> None:
    # A blurred corner of four squares at (30.3, 20.7): the saddle point is exact by symmetry.
    v, u = np.mgrid[0:48, 0:64].astype(np.float64)
    sign = np.tanh((u - 30.3) / 0.8) * np.tanh((v - 20.7) / 0.8)
    image = np.clip(120 + 90 * sign, 0, 255).astype(np.uint8)
    refined = refine_saddle(image, np.array([[31.0, 20.0]]), spacing_px=20.0)
    assert np.allclose(refined, [[30.3, 20.7]], atol=0.03)


def test_detect_on_real_image_and_settings(opencv_chessboard_dir: Path) -> None:
    image = read_gray(opencv_chessboard_dir / "left01.jpg")
    detection = detect_corners(image, parse_board("9x6", 25), "left01.jpg")
    assert detection.found and detection.corners.shape == (54, 2) and detection.half_window >= 2
    first, last = detection.corners[0], detection.corners[-1]
    assert first[0] < last[0] and first[1] < last[1]
    missing = detect_corners(np.full((100, 100), 128, np.uint8), parse_board("9x6", 25), "grey")
    assert not missing.found and "no 9x6 chessboard found" in missing.reason
    with pytest.raises(ValueError, match="half window"):
        SubpixSettings(half_window=0)
    with pytest.raises(DataError, match="image file not found"):
        read_gray(opencv_chessboard_dir / "left10.jpg")
