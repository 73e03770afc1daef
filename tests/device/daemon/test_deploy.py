"""The shipped unit file and example configuration are usable as they are."""

from __future__ import annotations

import configparser
from pathlib import Path

from ropecam.device.daemon.config import DaemonConfig, load_device_config

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
    assert service["RestartPreventExitStatus"] == "2"  # a configuration error: a restart cannot fix it
    assert service["ProtectSystem"] == "strict" and service["NoNewPrivileges"] == "yes"
    assert "MemoryDenyWriteExecute" not in service  # Numba's JIT executes the code it writes
    assert "/var/cache/" in service["Environment"] and "ProtectSystem" in service  # the cache stays writable
    assert "://" not in unit["Unit"]["Documentation"]  # no web address that does not exist


def test_example_device_config_loads(tmp_path: Path) -> None:
    text = (DEPLOY / "device.toml").read_text().replace("/etc/ropecam/control.key", str(tmp_path / "k"))
    (tmp_path / "device.toml").write_text(text)
    config = load_device_config(tmp_path / "device.toml")
    assert config.capture.exposure_us == 4000 and config.sender.sink.startswith("serial://")
    assert config.pipeline.rope_length_m == 0.411
    # Stable names: the camera by id, the Pi's UART by its alias (docs/daemon.md: the serial console).
    assert "/dev/v4l/by-id/" in config.capture.source and config.sender.sink.startswith("serial:///dev/serial0")


def test_watchdog_outlasts_every_step_that_does_not_ping(tmp_path: Path) -> None:
    """The daemon pings every WatchdogSec/2 and inside its retry waits; a single step (one read, one backoff slice,
    one open attempt) must stay well inside the watchdog period, whatever the shipped configuration says."""
    unit = configparser.ConfigParser(strict=False, interpolation=None)
    unit.optionxform = str
    unit.read(DEPLOY / "ropecam-device.service")
    watchdog_s = int(unit["Service"]["WatchdogSec"])
    text = (DEPLOY / "device.toml").read_text().replace("/etc/ropecam/control.key", str(tmp_path / "k"))
    (tmp_path / "device.toml").write_text(text)
    config = load_device_config(tmp_path / "device.toml")
    assert watchdog_s >= 2 * max(config.daemon.retry_max_s, config.capture.read_timeout_s)
    assert watchdog_s >= 2 * DaemonConfig().retry_max_s
    assert int(unit["Service"]["TimeoutStartSec"]) > config.daemon.camera_give_up_s  # first compile + camera retries
