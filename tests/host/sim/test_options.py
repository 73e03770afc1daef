"""The realism option table is true: every key is a configuration field, in --help and in docs/simulator.md."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from ropecam.host.cli import main
from ropecam.host.sim.config import SimConfig
from ropecam.host.sim.options import REALISM_OPTIONS

DOCS = Path(__file__).resolve().parents[3] / "docs" / "simulator.md"


def test_every_option_is_a_field_documented_and_in_help(capsys: pytest.CaptureFixture[str]) -> None:
    tables = {f.name: f.type for f in dataclasses.fields(SimConfig)}
    docs = DOCS.read_text()
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    help_text = capsys.readouterr().out
    for key, _, _, _ in REALISM_OPTIONS:
        table, name = key.split(".")
        spec = {"scene": "SceneSpec", "camera": "CameraSpec", "sensor": "SensorSpec"}[table]
        assert table in tables
        from ropecam.host.sim import config

        assert name in {f.name for f in dataclasses.fields(getattr(config, spec))}, key
        assert f"`{key}`" in docs, f"{key} is not in docs/simulator.md"
        assert key in help_text, f"{key} is not in ropecam simulate --help"
    for preset in ("lab", "lab-dark", "lab-mjpeg", "lab-rolling", "lab-hard", "--paper-exposures"):
        assert preset in help_text
