"""Fixtures of the calibration tests: OpenCV's real chessboard set and one simulated calibration set per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from ropecam.host.sim.boards import make_calibration_set, write_calibration_set


@pytest.fixture(scope="session")
def opencv_chessboard_dir(shared_dir: Path) -> Path:
    """OpenCV's sample chessboard images (left01..14, 9x6 inner corners, 25 mm) and its published calibration."""
    return shared_dir / "realdata" / "opencv_samples_chessboard"


@pytest.fixture(scope="session")
def sim_set_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated calibration set (paper camera, 30 views + plane view, 8x7 board, 20 mm) written as PNG + JSON."""
    folder = tmp_path_factory.mktemp("simset")
    write_calibration_set(make_calibration_set(seed=3), folder)
    return folder
