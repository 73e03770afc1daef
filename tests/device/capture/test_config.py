"""`CaptureConfig` from TOML: defaults, overrides of the URL, refusals naming the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from ropecam.device.capture.config import CaptureConfig
from ropecam.device.capture.fake import fake_factory, uvc_like_camera
from ropecam.shared.config import from_mapping, load_toml
from ropecam.shared.errors import ConfigError


def test_loads_from_toml_and_opens_the_camera(tmp_path: Path) -> None:
    path = tmp_path / "device.toml"
    path.write_text(
        '[capture]\nsource = "v4l2:///dev/video0?width=64&height=32&fps=60"\nfps = 119\nexposure_us = 2500\n'
    )
    config = load_toml(path, CaptureConfig, section="capture")
    assert config == CaptureConfig("v4l2:///dev/video0?width=64&height=32&fps=60", 119.0, 2500)
    camera = uvc_like_camera()
    with config.open(driver_factory=fake_factory(camera)) as source:
        assert source.fps == 119.0 and source.exposure_us == 2500


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"sourse": "v4l2:///dev/video0"}, "unknown key 'sourse'"),
        ({"source": "usb://0"}, "scheme must be v4l2 or frames"),
        ({"fps": 0}, r"capture.fps must be in \[0.1, 10000.0\], got 0.0"),
        ({"exposure_us": 2.5}, "expected an integer"),
        ({"read_timeout_s": 0}, "capture.read_timeout_s must be in"),
    ],
)
def test_refusals_name_the_key(table: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        from_mapping(CaptureConfig, table, where="device.toml [capture]")
