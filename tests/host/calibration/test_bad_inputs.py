"""Acceptance 3: bad inputs end with a clear error naming the files, and exit code 2 from the command line."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.host.calibration.board import parse_board
from ropecam.host.calibration.files import write_camera
from ropecam.host.calibration.intrinsics import calibrate_intrinsics
from ropecam.host.cli import main
from ropecam.host.sim.boards import paper_camera
from ropecam.shared.errors import CalibrationError, DataError

BOARD = ["--board", "9x6", "--square-mm", "25"]


@pytest.fixture
def good(opencv_chessboard_dir: Path, tmp_path: Path) -> list[Path]:
    """Five views of the OpenCV set, copied so tests can add bad files beside them."""
    copies = []
    for name in ("left01.jpg", "left03.jpg", "left04.jpg", "left05.jpg", "left06.jpg"):
        copies.append(tmp_path / name)
        shutil.copy(opencv_chessboard_dir / name, copies[-1])
    return copies


def _blank(path: Path, size: tuple[int, int] = (640, 480)) -> Path:
    cv2.imwrite(str(path), np.full((size[1], size[0]), 128, np.uint8))
    return path


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_view_without_board_is_listed_with_reason(good: list[Path], tmp_path: Path, capsys) -> None:
    blank = _blank(tmp_path / "wall.png")
    code, out, err = _run(
        ["calibrate", "intrinsics", *map(str, [*good, blank]), *BOARD, "--out", str(tmp_path / "c.yaml")], capsys
    )
    assert code == 0
    assert f"{blank}: left out: no 9x6 chessboard found" in out
    assert f"{blank}: NO BOARD" in err
    assert "views used: 5 of 6" in out


def test_folder_argument_and_empty_folder(good: list[Path], tmp_path: Path, capsys) -> None:
    code, out, _ = _run(["calibrate", "intrinsics", str(tmp_path), *BOARD, "--out", str(tmp_path / "c.yaml")], capsys)
    assert code == 0 and "views used: 5 of 5" in out
    empty = tmp_path / "empty"
    empty.mkdir()
    code, _, err = _run(["calibrate", "intrinsics", str(empty), *BOARD, "--out", str(tmp_path / "d.yaml")], capsys)
    assert code == 1 and f"{empty}: folder holds no images" in err


def test_wrong_board_size(good: list[Path], tmp_path: Path, capsys) -> None:
    # Two views: OpenCV's search for a board that is not there is slow (it tries every quad grouping).
    code, _, err = _run(["calibrate", "intrinsics", *map(str, good[:2]), "--board", "10x7", "--square-mm", "25",
                         "--out", str(tmp_path / "c.yaml")], capsys)  # fmt: skip
    assert code == 1
    assert "only 0 of 2 images show a 10x7 board" in err
    assert "check --board (inner corners, not squares)" in err
    assert str(good[0]) in err
    assert not (tmp_path / "c.yaml").exists()


def test_too_few_views(good: list[Path], tmp_path: Path, capsys) -> None:
    blank = _blank(tmp_path / "blank.png")
    code, _, err = _run(
        ["calibrate", "intrinsics", *map(str, good[:3]), str(blank), *BOARD, "--out", str(tmp_path / "c.yaml")], capsys
    )
    assert code == 1
    assert "only 3 of 4 images" in err and "at least 4 are needed" in err
    assert f"{blank}: no 9x6 chessboard found" in err


def test_mixed_image_sizes_name_both_files(good: list[Path], tmp_path: Path) -> None:
    small = _blank(tmp_path / "small.png", (320, 240))
    with pytest.raises(DataError) as info:
        calibrate_intrinsics([*good, small], parse_board("9x6", 25))
    message = str(info.value)
    assert str(small) in message and str(good[0]) in message and "320x240" in message and "640x480" in message


def test_unreadable_and_missing_files_are_all_named(good: list[Path], tmp_path: Path, capsys) -> None:
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"this is not a PNG file")
    empty = tmp_path / "empty.jpg"
    empty.write_bytes(b"")
    missing = tmp_path / "missing.jpg"
    code, _, err = _run(["calibrate", "intrinsics", *map(str, good), str(garbage), str(empty), str(missing), *BOARD,
                         "--out", str(tmp_path / "c.yaml")], capsys)  # fmt: skip
    assert code == 1
    assert "3 of 8 images cannot be read" in err
    assert f"{garbage}: not a readable image" in err
    assert f"{empty}: not a readable image" in err
    assert f"{missing}: image file not found" in err


def test_plane_image_size_does_not_match_camera_file(good: list[Path], tmp_path: Path, capsys) -> None:
    camera_yaml = write_camera(tmp_path / "paper_camera.yaml", paper_camera(), 0.05)
    code, _, err = _run(["calibrate", "plane", str(good[0]), "--camera", str(camera_yaml), *BOARD,
                         "--out", str(tmp_path / "p.yaml")], capsys)  # fmt: skip
    assert code == 1
    assert f"{good[0]} is 640x480 px but {camera_yaml} was calibrated at 1024x544 px" in err
    assert not (tmp_path / "p.yaml").exists()


def test_plane_image_without_board(tmp_path: Path, capsys) -> None:
    camera_yaml = write_camera(tmp_path / "camera.yaml", paper_camera(), 0.05)
    blank = _blank(tmp_path / "plane.png", (1024, 544))
    code, _, err = _run(["calibrate", "plane", str(blank), "--camera", str(camera_yaml), "--board", "8x7",
                         "--square-mm", "20", "--out", str(tmp_path / "p.yaml")], capsys)  # fmt: skip
    assert code == 1
    assert f"{blank}: no 8x7 chessboard found" in err


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (None, "camera file not found"),
        ("just text\n", "not an OpenCV FileStorage camera file"),
        ("%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n", "key 'camera_matrix' is missing"),
    ],
)
def test_bad_camera_file(tmp_path: Path, capsys, content: str | None, expected: str) -> None:
    camera_yaml = tmp_path / "camera.yaml"
    if content is not None:
        camera_yaml.write_text(content)
    blank = _blank(tmp_path / "plane.png")
    code, _, err = _run(["calibrate", "plane", str(blank), "--camera", str(camera_yaml), *BOARD,
                         "--out", str(tmp_path / "p.yaml")], capsys)  # fmt: skip
    assert code == 1
    assert str(camera_yaml) in err and expected in err


def test_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="COLSxROWS"):
        parse_board("9by6", 25)
    with pytest.raises(ValueError, match="square size"):
        parse_board("9x6", 0)
    with pytest.raises(CalibrationError, match="no images"):
        calibrate_intrinsics([], parse_board("9x6", 25))
    with pytest.raises(SystemExit):
        main(["calibrate", "plane", "x.png", "--camera", "c.yaml", *BOARD, "--origin-px", "1;2", "--out", "p.yaml"])


@pytest.mark.parametrize("bad", ["nan_k", "zero_fx", "nan_dist"])
def test_diverged_calibration_is_a_calibration_error(
    good: list[Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys, bad: str
) -> None:
    real = cv2.calibrateCamera

    def diverging(*args, **kwargs):  # type: ignore[no-untyped-def]
        rms, k, dist, rvecs, tvecs = real(*args, **kwargs)
        k, dist = k.copy(), dist.copy()
        if bad == "nan_k":
            k[0, 0] = np.nan
        elif bad == "zero_fx":
            k[0, 0] = 0.0
        else:
            dist[0] = np.inf
        return rms, k, dist, rvecs, tvecs

    monkeypatch.setattr(cv2, "calibrateCamera", diverging)
    with pytest.raises(CalibrationError, match=r"calibration (diverged|on 4 views gave an unusable camera)"):
        calibrate_intrinsics(good[:4], parse_board("9x6", 25))
    code, _, err = _run(["calibrate", "intrinsics", *map(str, good[:4]), *BOARD, "--out", str(tmp_path / "c.yaml")],
                        capsys)  # fmt: skip
    assert code == 1 and "calibration" in err and "Traceback" not in err
    assert not (tmp_path / "c.yaml").exists()


def test_no_images_is_the_documented_calibration_error() -> None:
    from ropecam.host.calibration.intrinsics import detect_views

    with pytest.raises(CalibrationError, match="no images given"):
        detect_views([], parse_board("9x6", 25))
    raises = detect_views.__doc__.split("Raises")[1]
    assert "CalibrationError" in raises and "empty" in raises
