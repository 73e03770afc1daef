"""Source URLs: both schemes, overrides, and clear errors for bad ones."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture import open_camera_source
from ropecam.device.capture.fake import fake_factory, uvc_like_camera
from ropecam.device.capture.frameset import FrameSetWriter
from ropecam.device.capture.replay import FrameSetSource
from ropecam.device.capture.url import parse_source_url
from ropecam.device.capture.v4l2 import V4l2Source
from ropecam.shared.errors import ConfigError


def _write(root: Path) -> None:
    with FrameSetWriter(root, (8, 6), 119.0) as writer:
        for i in range(3):
            writer.add(np.full((6, 8), i, np.uint8), t_ns=i * 8_403_361, exposure_us=800)


def test_parse() -> None:
    assert parse_source_url("v4l2:///dev/video0?width=1024&height=544") == (
        "v4l2",
        "/dev/video0",
        {"width": "1024", "height": "544"},
    )
    assert parse_source_url("v4l2:/dev/video2") == ("v4l2", "/dev/video2", {})
    assert parse_source_url("frames:rec/run%201?loop=1") == ("frames", "rec/run 1", {"loop": "1"})
    assert parse_source_url("frames:///data/run") == ("frames", "/data/run", {})


def test_v4l2_url_opens_the_camera_with_its_settings() -> None:
    camera = uvc_like_camera()
    url = "v4l2:///dev/video0?width=1024&height=544&fps=119&format=Y8&buffers=3&exposure_us=2000&gain=4"
    source = open_camera_source(url, driver_factory=fake_factory(camera))
    assert isinstance(source, V4l2Source) and source.buffer_count == 3
    with source:
        assert source.describe() == {
            "source": "v4l2:///dev/video0",
            "width": 1024,
            "height": 544,
            "fps": 119.0,
            "exposure_us": 2000,
            "pixel_format": "GREY",
        }
        assert camera.values["gain"] == 4


def test_keyword_overrides_win_over_the_url() -> None:
    camera = uvc_like_camera()
    url = "v4l2:///dev/video0?width=64&height=32&fps=119&exposure_us=2000"
    with open_camera_source(url, fps=60.0, exposure_us=5000, driver_factory=fake_factory(camera)) as source:
        assert source.fps == 60.0 and source.exposure_us == 5000


def test_frames_url(tmp_path: Path) -> None:
    _write(tmp_path / "set")
    source = open_camera_source(f"frames:{tmp_path / 'set'}?fps=50&loop=1&paced=0")
    assert isinstance(source, FrameSetSource)
    assert (source.fps, source.loop, source.paced) == (50.0, True, False)
    with source:
        assert [source.read(0).sequence for _ in range(4)] == [0, 1, 2, 3]  # type: ignore[union-attr]
    assert open_camera_source(f"frames:{tmp_path / 'set'}", loop=True).loop  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("", "non-empty string"),
        ("/dev/video0", "scheme must be v4l2 or frames"),
        ("rtsp://cam/stream", "scheme must be v4l2 or frames"),
        ("v4l2://", "names no device"),
        ("v4l2:video0", "absolute path"),
        ("v4l2:///dev/video0?widht=640&height=480", "unknown key 'widht'; v4l2 takes width, height"),
        ("v4l2:///dev/video0?width=640", "both width and height"),
        ("v4l2:///dev/video0?width=6.5&height=4", "width must be an integer, got '6.5'"),
        ("v4l2:///dev/video0?fps=-3", "fps must be > 0"),
        ("v4l2:///dev/video0?fps=nan", "fps must be > 0"),
        ("v4l2:///dev/video0?fps=1&fps=2", "given twice"),
        ("v4l2:///dev/video0?format=RGB3", "pixel_format must be one of GREY, Y8, YUYV"),
        ("v4l2:///dev/video0?buffers=99", "buffer_count must be an integer in"),
        ("v4l2:///dev/video0?backend=gstreamer", "backend must be auto, linuxpy or opencv"),
        ("frames:/nonexistent/run", "is not a folder"),
        ("frames:.?exposure_us=3", "unknown key 'exposure_us'; frames takes fps, loop, paced"),
        ("frames:.?loop=maybe", "loop must be 0 or 1"),
    ],
)
def test_bad_urls_are_named(url: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        open_camera_source(url, driver_factory=fake_factory())


def test_exposure_or_loop_on_the_wrong_kind_of_source(tmp_path: Path) -> None:
    _write(tmp_path / "set")
    with pytest.raises(ConfigError, match="replays its own exposure"):
        open_camera_source(f"frames:{tmp_path / 'set'}", exposure_us=1000)
    with pytest.raises(ConfigError, match="loop applies to frame sets only"):
        open_camera_source("v4l2:///dev/video0", loop=True, driver_factory=fake_factory())
