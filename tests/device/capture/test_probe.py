"""`ropecam-device probe` against fake cameras: text, JSON, no camera, a camera that cannot be opened."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ropecam.device.capture import probe
from ropecam.device.capture.driver import FormatInfo
from ropecam.device.capture.fake import FakeCamera, FakeV4l2Driver, fake_factory, uvc_like_camera
from ropecam.device.cli import main


@pytest.fixture
def two_cameras(monkeypatch: pytest.MonkeyPatch) -> None:
    busy = uvc_like_camera("/dev/video2")
    busy.busy = True
    factory = fake_factory(uvc_like_camera("/dev/video0"), busy)
    monkeypatch.setattr(probe, "default_driver_factory", lambda backend="auto": factory)


def test_text_report(two_cameras: None, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["probe", "/dev/video0", "/dev/video2"]) == 0
    out = capsys.readouterr().out
    assert "/dev/video0: Fake global-shutter camera (driver fake)" in out
    assert "* GREY  8-bit Greyscale" in out and "  MJPG  Motion-JPEG" in out
    assert "1024x544: 119, 60, 30 fps" in out
    assert "exposure_time_absolute" in out and "(= 15700 us; 100 us units)" in out
    assert "(1: Manual Mode, 3: Aperture Priority Mode)" in out
    assert "/dev/video2: cannot probe: camera /dev/video2: Device or resource busy" in out


def test_json_report(two_cameras: None, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["probe", "/dev/video0", "--json"]) == 0
    (camera,) = json.loads(capsys.readouterr().out)["cameras"]
    assert camera["error"] is None and camera["current"] == {"width": 1280, "height": 800, "fourcc": "MJPG"}
    grey = next(f for f in camera["formats"] if f["fourcc"] == "GREY")
    assert (
        grey["usable"] and {"width": 64, "height": 32, "fps": [119.0, 60.0, 30.0], "fps_range": None} in grey["sizes"]
    )
    controls = {c["name"]: c for c in camera["controls"]}
    assert controls["exposure_time_absolute"]["maximum"] == 5000


def test_no_camera(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["probe", "--dev-dir", str(tmp_path)]) == probe.EXIT_NO_CAMERA
    assert "no camera found" in capsys.readouterr().err
    assert main(["probe", "--dev-dir", str(tmp_path), "--json"]) == probe.EXIT_NO_CAMERA
    assert json.loads(capsys.readouterr().out)["cameras"] == []


def test_only_unopenable_cameras_exit_non_zero(two_cameras: None, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["probe", "/dev/video2", "/dev/video7"]) == probe.EXIT_NO_CAMERA
    captured = capsys.readouterr()
    assert "/dev/video7: cannot probe: camera /dev/video7: No such file or directory" in captured.out
    assert "no camera could be opened" in captured.err


def test_a_metadata_node_is_listed_without_formats(monkeypatch: pytest.MonkeyPatch, capsys) -> None:  # type: ignore[no-untyped-def]
    """uvcvideo adds a metadata node per camera: no capture formats, G_FMT fails with EINVAL."""
    camera = FakeCamera("/dev/video1", [FormatInfo("GREY", "grey")], {})
    camera.format_list = []  # what the node lists
    monkeypatch.setattr(FakeV4l2Driver, "get_format", lambda self: (_ for _ in ()).throw(OSError(22, "Invalid")))
    monkeypatch.setattr(probe, "default_driver_factory", lambda backend="auto": fake_factory(camera))
    assert main(["probe", "/dev/video1"]) == 0
    out = capsys.readouterr().out
    assert "/dev/video1: Fake global-shutter camera" in out and "no capture formats (a metadata node?)" in out


def test_lists_nodes_in_numeric_order(tmp_path: Path) -> None:
    for name in ("video10", "video2", "video0", "vbi0"):
        (tmp_path / name).touch()
    assert probe.list_video_nodes(tmp_path) == [str(tmp_path / n) for n in ("video0", "video2", "video10")]


def test_help_teaches_the_source_url(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["probe", "--help"])
    assert "v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY" in capsys.readouterr().out
