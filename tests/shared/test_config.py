"""The configuration loader refuses unknown keys and wrong types and names where they are."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest

from ropecam.shared.config import check_positive, from_mapping, load_toml
from ropecam.shared.errors import ConfigError


@dataclass(frozen=True, slots=True)
class Inner:
    gain: float = 1.0
    mode: Literal["auto", "manual"] = "auto"


@dataclass(frozen=True, slots=True)
class Outer:
    exposure_us: int = 8000
    name: str = "cam"
    roi: tuple[int, int] | None = None
    inner: Inner = field(default_factory=Inner)

    def __post_init__(self) -> None:
        check_positive("exposure_us", self.exposure_us)


def test_builds_nested_and_overrides() -> None:
    config = from_mapping(Outer, {"exposure_us": 100, "inner": {"gain": 2}, "roi": [3, 4]}, name="x")
    assert config == Outer(exposure_us=100, name="x", roi=(3, 4), inner=Inner(gain=2.0))


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"exposure": 1}, "cfg: unknown key 'exposure' (allowed: exposure_us, inner, name, roi)"),
        ({"exposure_us": "8000"}, "cfg.exposure_us: expected an integer, got '8000'"),
        ({"exposure_us": True}, "cfg.exposure_us: expected an integer, got True"),
        ({"exposure_us": -5}, "cfg: exposure_us must be > 0, got -5"),
        ({"inner": {"mode": "x"}}, "cfg.inner.mode: must be one of 'auto', 'manual', got 'x'"),
        ({"inner": {"gian": 1}}, "cfg.inner: unknown key 'gian'"),
        ({"roi": [1, 2, 3]}, "cfg.roi: expected 2 values"),
        ({"inner": 3}, "cfg.inner: expected a table, got int 3"),
    ],
)
def test_errors_name_the_key_and_value(data: dict, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        from_mapping(Outer, data, where="cfg")
    assert message in str(info.value)


def test_load_toml_section_and_file_errors(tmp_path: Path) -> None:
    path = tmp_path / "device.toml"
    path.write_text('[camera]\nexposure_us = 4000\nname = "rig"\n')
    assert load_toml(path, Outer, section="camera") == Outer(exposure_us=4000, name="rig")
    assert load_toml(path, Outer, section="absent") == Outer()
    with pytest.raises(ConfigError, match="config file not found"):
        load_toml(tmp_path / "missing.toml", Outer)
