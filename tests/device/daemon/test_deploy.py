"""The shipped unit file and example configuration are usable as they are."""

from __future__ import annotations

import configparser
from pathlib import Path

from ropecam.device.daemon.config import load_device_config

DEPLOY = Path(__file__).resolve().parents[3] / "deploy"


def test_unit_file_is_a_notify_service_with_watchdog_and_numba_cache() -> None:
    unit = configparser.ConfigParser(strict=False, interpolation=None)
    unit.optionxform = str  # systemd keys are case-sensitive
    unit.read(DEPLOY / "ropecam-device.service")
    service = unit["Service"]
    assert service["Type"] == "notify" and service["NotifyAccess"] == "main"
    assert int(service["WatchdogSec"]) > 0 and service["Restart"] == "on-failure"
    assert service["Environment"] == "NUMBA_CACHE_DIR=/var/cache/ropecam/numba"
    assert service["CacheDirectory"] == "ropecam"
    assert "ropecam-device run --config" in service["ExecStart"]


def test_example_device_config_loads(tmp_path: Path) -> None:
    text = (DEPLOY / "device.toml").read_text().replace("/etc/ropecam/control.key", str(tmp_path / "k"))
    (tmp_path / "device.toml").write_text(text)
    config = load_device_config(tmp_path / "device.toml")
    assert config.capture.exposure_us == 4000 and config.sender.sink.startswith("serial://")
    assert config.pipeline.rope_length_m == 0.411
