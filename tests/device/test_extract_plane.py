"""`ropecam-device extract` with a plane calibration and a rolling shutter; bad plane files and readout times."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSetWriter
from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.cli import main

PlaneYaml = Callable[[Path, tuple[float, float], tuple[int, int]], Path]
"""The `plane_yaml` fixture (tests/device/conftest.py)."""

ROPE = SyntheticRope(exposure_us=12000, amplitude_rad=0.7, period_s=0.9, diameter_px=3.0, phase_rad=1.2)


@pytest.fixture(scope="module")
def frameset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("plane") / "set"
    with FrameSetWriter(root, (ROPE.width, ROPE.height), ROPE.fps) as writer:
        for f in ROPE.frames(3):
            writer.add(f.image, f.t_ns, f.exposure_us)
    return root


def _read(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_the_fixed_end_is_the_plane_origin_and_rows_have_their_times(
    tmp_path: Path, frameset: Path, plane_yaml: PlaneYaml
) -> None:
    origin = (ROPE.fixed_uv[0] + 0.4, ROPE.fixed_uv[1] - 0.3)
    plane = plane_yaml(tmp_path / "plane.yaml", origin, (ROPE.width, ROPE.height))
    config = tmp_path / "device.toml"
    config.write_text("[pipeline]\nrope_length_m = 1.0\nmaterial_points_m = [0.0, 0.5, 1.0]\n")
    out = tmp_path / "out.jsonl"
    argv = ["extract", str(frameset), "--out", str(out), "--plane", str(plane), "--config", str(config)]
    assert main([*argv, "--readout-us", "5000", "--quiet"]) == 0
    records = _read(out)
    assert all(r["status"] == "OK" for r in records[1:])  # frame 0: its time order undecided (the rope swings)
    for record in records:
        assert record["readout_ns"] == 5_000_000
        np.testing.assert_allclose(record["fixed_end"], origin, atol=1e-3)
        # Material point 0 is the fixed end (the polyline starts at the foot of the fixed end on the rope's axis).
        for shape in ("begin", "end"):
            assert np.hypot(*np.subtract(record["material_points"][shape][0], origin)) < 1.0
            assert np.hypot(*np.subtract(record[shape][0], origin)) < 1.0
    # On a camera square to the plane, points by plane arc length are points by pixel arc length.
    tips = np.array([records[1]["material_points"]["end"][2], records[1]["tips"]["end"]])
    assert np.hypot(*(tips[0] - tips[1])) < 0.05


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--readout-us", "-1"], "--readout-us must be >= 0"),
        (["--readout-us", "9000"], "--readout-us is 9000 us, longer than the frame period"),
        (["--plane", "{far}"], "far.yaml: the plane origin (the rope's fixed end) projects to"),
        (["--plane", "{small}"], "small.yaml: calibrated for 160x120 images, the frames are 320x240"),
        (["--plane", "{missing}"], "missing.yaml: cannot read the plane calibration"),
    ],
)
def test_bad_plane_or_readout_is_an_error_and_writes_nothing(
    tmp_path: Path,
    frameset: Path,
    capsys: pytest.CaptureFixture[str],
    plane_yaml: PlaneYaml,
    extra: list[str],
    message: str,
) -> None:
    files = {
        "far": str(plane_yaml(tmp_path / "far.yaml", (ROPE.width + 40.0, 20.0), (ROPE.width, ROPE.height))),
        "small": str(plane_yaml(tmp_path / "small.yaml", (80.0, 10.0), (160, 120))),
        "missing": str(tmp_path / "missing.yaml"),
    }
    extra = [a.format(**files) for a in extra]
    out = tmp_path / "out.jsonl"
    assert main(["extract", str(frameset), "--out", str(out), "--fps", "119", *extra, "--quiet"]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_readout_from_the_config_and_its_key_named(tmp_path: Path, frameset: Path, capsys) -> None:
    config = tmp_path / "device.toml"
    config.write_text("[capture]\nreadout_us = -5\n")
    out = tmp_path / "out.jsonl"
    assert main(["extract", str(frameset), "--out", str(out), "--config", str(config), "--quiet"]) == 2
    assert "device.toml [capture] readout_us must be >= 0" in capsys.readouterr().err
    assert not out.exists()
