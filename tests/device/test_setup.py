"""`ropecam-device setup` end to end: a small synthetic frame set -> device.toml that extract measures with; a scene
without a rope; the refusal to overwrite; the [pipeline] table replaced inside an existing file."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSetWriter
from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.cli import main
from ropecam.device.setup import with_pipeline_table

ROPE = SyntheticRope(exposure_us=12000, amplitude_rad=0.7, period_s=0.9, diameter_px=3.0, phase_rad=1.2)
FRAMES = 12


def _write_set(root: Path, images, t_ns, exposure_us: float) -> None:
    with FrameSetWriter(root, (ROPE.width, ROPE.height), ROPE.fps) as writer:
        for image, t in zip(images, t_ns, strict=True):
            writer.add(image, t, exposure_us)


@pytest.fixture(scope="module")
def rope_set(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("setup") / "set"
    frames = list(ROPE.frames(FRAMES))
    images = []
    for f in frames:
        image = f.image.copy()
        image[212:226, 8:22] = 250  # a static block: edges in every frame, away from the rope
        images.append(image)
    _write_set(root, images, [f.t_ns for f in frames], ROPE.exposure_us)
    return root


def test_setup_writes_a_config_extract_measures_with(tmp_path, rope_set, capsys) -> None:
    out = tmp_path / "rig" / "device.toml"  # setup makes the folder, as `--out` says
    assert main(["setup", str(rope_set), "--out", str(out), "--rope-length-m", "0.5", "--quiet"]) == 0
    table = tomllib.loads(out.read_text())["pipeline"]
    assert table["rope_length_m"] == 0.5
    assert {"canny_low", "canny_high"} <= set(table)
    assert table.get("polarity") == "bright"
    assert 2.0 < table["rope_width_px"] < 4.5  # the synthetic rope is 3 px wide
    # The rope swings fast on every frame (12 ms, mid-swing): its blur is not read, and the width is the model's
    # for the default lens blur, which the pipeline then keeps.
    assert "lens_blur_px" not in table
    truth = next(iter(ROPE.frames(1))).begin_uv[0]
    assert np.hypot(*(np.array(table["fixed_end_uv"]) - truth)) < 3.0
    overlay = tmp_path / "rig" / "device_overlay.png"
    assert cv2.imread(str(overlay)).shape == (ROPE.height, ROPE.width, 3)
    # The small static block never passes for the rope: the pipeline measures as well without a mask, so none.
    assert "static_mask_png" not in table and not (tmp_path / "rig" / "device_mask.png").exists()
    results = tmp_path / "out.jsonl"
    assert main(["extract", str(rope_set), "--config", str(out), "--out", str(results), "--quiet"]) == 0
    records = [json.loads(line) for line in results.read_text().splitlines()]
    assert sum(r["status"] == "OK" for r in records) >= FRAMES - 2  # frame 0: its time order undecided
    assert records[-1]["fixed_end"] == pytest.approx(table["fixed_end_uv"], abs=1e-3)


def test_setup_refuses_to_overwrite_and_keeps_other_tables_with_force(tmp_path, rope_set, capsys) -> None:
    out = tmp_path / "device.toml"
    original = (
        "[capture]\nexposure_us = 4000\n\n"
        "[pipeline]\nrope_length_m = 0.4\nmaterial_points_m = [0.2, 0.4]\ncanny_low = 3.0\n\n"
        "[sender]\ndevice_id = 2\n"
    )
    out.write_text(original)
    assert main(["setup", str(rope_set), "--out", str(out), "--quiet"]) == 2
    assert "--force" in capsys.readouterr().err
    assert out.read_text() == original
    assert not (tmp_path / "device_overlay.png").exists()
    assert main(["setup", str(rope_set), "--out", str(out), "--quiet", "--force"]) == 0
    data = tomllib.loads(out.read_text())
    assert data["capture"] == {"exposure_us": 4000} and data["sender"] == {"device_id": 2}
    assert data["pipeline"]["rope_length_m"] == 0.4  # kept: setup cannot see metres
    assert data["pipeline"]["canny_low"] != 3.0  # decided


def test_setup_on_a_scene_without_a_rope_says_so(tmp_path, capsys) -> None:
    root = tmp_path / "empty"
    rng = np.random.default_rng(3)
    images = [np.clip(rng.normal(60, 2, (ROPE.height, ROPE.width)), 0, 255).astype(np.uint8) for _ in range(8)]
    _write_set(root, images, [round(i * 1e9 / ROPE.fps) for i in range(8)], ROPE.exposure_us)
    out = tmp_path / "device.toml"
    assert main(["setup", str(root), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "no rope found" in err and "Nothing was written" in err
    assert not out.exists() and not (tmp_path / "device_overlay.png").exists()


def test_setup_refuses_an_output_it_cannot_write_before_reading_frames(tmp_path, capsys) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    missing = tmp_path / "no_such_set"  # never read: the output is checked first
    assert main(["setup", str(missing), "--out", str(blocker / "rig" / "device.toml"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert f"{blocker} is a file, not a folder" in err and "Nothing was written" in err
    assert blocker.read_text() == "" and sorted(tmp_path.iterdir()) == [blocker]


def test_pipeline_table_replaced_in_place() -> None:
    old = "# head\n[capture]\nx = 1\n[pipeline]\na = 1\n[pipeline.edges]\nb = 2\n[sender]\ny = 3\n"
    new = with_pipeline_table(old, "[pipeline]\nc = 4\n")
    assert new == "# head\n[capture]\nx = 1\n[pipeline]\nc = 4\n[sender]\ny = 3\n"
    assert with_pipeline_table("[capture]\nx = 1", "[pipeline]\nc = 4\n") == "[capture]\nx = 1\n\n[pipeline]\nc = 4\n"


def test_setup_with_a_plane_measures_from_its_fixed_end(tmp_path, rope_set) -> None:
    """With `--plane` every candidate runs with the plane origin as the fixed end, as the device will; the table
    names the plane file instead of a decided `fixed_end_uv`, and extract measures from that fixed end."""
    from ropecam.host.calibration.files import write_plane
    from ropecam.host.calibration.geometry import CameraModel, PlanePose

    truth = next(iter(ROPE.frames(1))).begin_uv[0]
    focal, cx, cy = 400.0, (ROPE.width - 1) / 2, (ROPE.height - 1) / 2
    camera = CameraModel(
        np.array([[focal, 0, cx], [0, focal, cy], [0, 0, 1.0]]), np.zeros(5), (ROPE.width, ROPE.height)
    )
    pose = PlanePose.from_rvec([0.0, 0.0, 0.0], [(truth[0] - cx) / focal, (truth[1] - cy) / focal, 1.0])
    plane = write_plane(tmp_path / "plane.yaml", camera, pose)
    out = tmp_path / "device.toml"
    assert main(["setup", str(rope_set), "--out", str(out), "--plane", str(plane), "--quiet"]) == 0
    table = tomllib.loads(out.read_text())["pipeline"]
    assert table["plane_file"] == str(plane.resolve())
    assert "fixed_end_uv" not in table
    results = tmp_path / "out.jsonl"
    assert main(["extract", str(rope_set), "--config", str(out), "--out", str(results), "--quiet"]) == 0
    records = [json.loads(line) for line in results.read_text().splitlines()]
    assert sum(r["status"] == "OK" for r in records) >= FRAMES - 2  # frame 0: its time order undecided
    assert records[-1]["fixed_end"] == pytest.approx(list(truth), abs=0.05)


def test_setup_takes_the_camera_gamma_the_frame_set_states(tmp_path, rope_set) -> None:
    # The same rope through a camera with gamma 2.2: its metadata says so, setup writes the key and the rope's width
    # is read in linear light as on the linear set; told nothing, the curve widens the rope.
    frames = list(ROPE.frames(FRAMES))
    encoded = [np.round(255.0 * (f.image / 255.0) ** (1 / 2.2)).astype(np.uint8) for f in frames]
    widths = {}
    for name, metadata in (("linear", None), ("stated", {"camera": {"gamma": 2.2}}), ("unstated", None)):
        root = tmp_path / name
        images = [f.image for f in frames] if name == "linear" else encoded
        with FrameSetWriter(root, (ROPE.width, ROPE.height), ROPE.fps, metadata) as writer:
            for image, f in zip(images, frames, strict=True):
                writer.add(image, f.t_ns, ROPE.exposure_us)
        out = tmp_path / f"{name}.toml"
        assert main(["setup", str(root), "--out", str(out), "--quiet"]) == 0
        table = tomllib.loads(out.read_text())["pipeline"]
        assert table.get("gamma") == (2.2 if name == "stated" else None)
        widths[name] = table["rope_width_px"]
    assert abs(widths["stated"] - widths["linear"]) < 0.1, widths
    assert widths["unstated"] - widths["linear"] > 0.15, widths


def test_setup_on_a_rope_measured_on_too_few_frames_says_why(tmp_path, capsys) -> None:
    """A rope seen on 3 of 8 frames (the others show the plate only): setup refuses, but says that a rope was
    found and why the other frames were not measured, instead of "no rope found"."""
    root = tmp_path / "sparse"
    rng = np.random.default_rng(5)
    frames = list(ROPE.frames(8))
    seen = {0, 1, 4}
    images = [
        f.image if f.index in seen else np.clip(rng.normal(30, 2, f.image.shape), 0, 255).astype(np.uint8)
        for f in frames
    ]
    _write_set(root, images, [f.t_ns for f in frames], ROPE.exposure_us)
    out = tmp_path / "device.toml"
    assert main(["setup", str(root), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "a rope was found but too few frames measure" in err and "no rope found" not in err
    assert "NO_ROPE" in err and "Nothing was written" in err
    assert not out.exists()


def test_setup_says_why_a_faint_band_was_lost_and_which_thresholds_the_noise_gave() -> None:
    """A run whose frames were mostly LOST_TRACK with a broken or unpaired band outline (the simulated `lab-hard`:
    30 DN of contrast and strong noise) is told so, not asked whether the rope moves; and a candidate's tried line
    names the thresholds the pipeline measured from the frames' noise when they are below the candidate's."""
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.setup import _hint
    from ropecam.device.setup_decide import Run, _used

    statuses = {"LOST_TRACK": 52, "NO_ROPE": 1, "OK": 1}
    broken = {"LOST_TRACK: the band's edge is broken": 30, "LOST_TRACK: the two shapes differ in length": 22}
    assert "too faint against the frame's noise" in _hint(statuses, broken)
    assert "is the rope moving?" in _hint(statuses, {"LOST_TRACK: no corner pair": 52})
    assert "is the rope moving?" in _hint(statuses)
    run = Run(PipelineConfig(canny_low=20.0, canny_high=50.0), thresholds_used=(8.0, 12.8))
    assert _used(run) == " (measured from the frames' noise: 8.0/12.8)"
    assert _used(Run(PipelineConfig(canny_low=20.0, canny_high=50.0), thresholds_used=(20.0, 50.0))) == ""
    assert _used(Run(PipelineConfig())) == ""
