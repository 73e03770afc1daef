"""Presets: the issue's numbers, ropes 1.5-4 px wide, the whole swing in view; configuration overrides validated."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ropecam.host.calibration.geometry import plane_to_pixels
from ropecam.host.model.cli import load_model_config
from ropecam.host.model.config import RopeConfig, SolverConfig
from ropecam.host.sim.config import merge_overrides
from ropecam.host.sim.presets import PRESETS, preset
from ropecam.host.sim.render import RopeRenderer
from ropecam.shared.config import read_toml
from ropecam.shared.errors import ConfigError


def test_rig_and_paper_follow_the_issue() -> None:
    rig = preset("rig")
    k = rig.camera.camera_model().camera_matrix
    np.testing.assert_array_equal(k, [[1495.2341, 0, 508.0598], [0, 1483.2726, 275.6076], [0, 0, 1]])
    assert rig.camera.distortion[:2] == (-0.1793, 0.3891) and rig.camera.image_size == (1024, 544)
    assert (rig.camera.fps, rig.exposure_ms, rig.frames, rig.rope.length_m) == (119.0, (4.0,), 60, 0.411)
    assert rig.camera.plane_tvec_m[2] == 1.5
    paper = preset("paper")
    k = paper.camera.camera_model().camera_matrix
    np.testing.assert_array_equal(k, [[1200, 0, 400], [0, 1200, 256], [0, 0, 1]])
    assert paper.camera.image_size == (800, 512) and paper.camera.fps == 30.0
    assert paper.exposure_ms == (1.0, 5.0, 9.0, 15.0) and paper.rope.length_m == 1.0
    for name in ("paper", "paper-soft", "rig", "rig-soft"):
        config = preset(name)
        assert config.rope.diameter_m == 0.001 and config.rope.youngs_modulus_pa == 1.24e11
        assert (config.rope.ei_nm2 is not None) == name.endswith("-soft")
    solid_ei = 1.24e11 * np.pi * 0.001**4 / 64
    assert preset("rig-soft").rope.ei_nm2 < solid_ei / 100 and preset("paper-soft").rope.ei_nm2 < solid_ei / 50


@pytest.mark.parametrize("name", list(PRESETS))
def test_rope_width_and_swing_fit_the_image(name: str) -> None:
    config = preset(name)
    camera, plane = config.camera.camera_model(), config.camera.plane_pose()
    length = config.rope.length_m
    # Every point the rope can reach below the horizontal through the fixed end, plus 10 % of L above it.
    angle = np.linspace(-np.pi, 0, 181)
    radius = np.linspace(0, length, 41)
    disc = np.stack(np.meshgrid(radius, angle), axis=-1)
    points = np.stack([disc[..., 0] * np.cos(disc[..., 1]), -disc[..., 0] * np.sin(disc[..., 1])], axis=-1)
    above = np.stack(np.meshgrid(np.linspace(-length, length, 41), np.linspace(-0.1 * length, 0, 5)), axis=-1)
    pixels = plane_to_pixels(np.concatenate([points.reshape(-1, 2), above.reshape(-1, 2)]), camera, plane)
    width, height = config.camera.image_size
    assert pixels[:, 0].min() >= 5 and pixels[:, 0].max() <= width - 6
    assert pixels[:, 1].min() >= 5 and pixels[:, 1].max() <= height - 6
    # Apparent width of a straight rope in several directions.
    s = np.linspace(0, length, 200)
    renderer = RopeRenderer(camera, plane, s, config.render_diameter_m, np.ones_like(s), 0.5)
    for theta in np.linspace(0, np.pi, 7):
        line = s[:, None] * np.array([np.cos(theta), np.sin(theta)])
        widths = 2 * renderer.half_width_px(line, renderer.project(line))
        assert widths.min() >= 1.5 and widths.max() <= 4.0, f"{name}: {widths.min():.2f}..{widths.max():.2f} px"


@pytest.mark.parametrize(
    ("name", "length_m", "ei_nm2", "elements", "duration_s", "model_s"),
    [("rig", 0.411, None, 16, 0.5, 0.502), ("rig-soft", 0.411, 1e-5, 32, 0.5, 0.502),
     ("paper", 1.0, None, 16, 1.982, 1.984), ("paper-soft", 1.0, 1e-4, 32, 1.982, 1.984)],
)  # fmt: skip
def test_presets_model_configuration(
    name: str, length_m: float, ei_nm2: float | None, elements: int, duration_s: float, model_s: float
) -> None:
    """The presets hold the model's own types, with the values the simulator always used (same frames as before)."""
    config = preset(name)
    assert config.rope == RopeConfig(length_m=length_m, diameter_m=0.001, ei_nm2=ei_nm2)
    assert config.solver == SolverConfig(elements=elements, step_s=1e-3, duration_s=duration_s, output_every_s=1e-3)
    # The model runs two output samples past the last exposure (60 frames), as before the refactoring.
    run = config.model_solver()
    assert run == dataclasses.replace(config.solver, duration_s=run.duration_s)
    assert run.duration_s == pytest.approx(model_s, abs=1e-12)
    assert config.render_diameter_m == (0.0025 if name.startswith("rig") else 0.007)


def test_model_config_file_applies_to_the_simulator(tmp_path: Path) -> None:
    """A file for `ropecam model simulate --config` works for `ropecam simulate --config`: same tables, same keys."""
    path = tmp_path / "rope.toml"
    path.write_text(
        "[rope]\nei_nm2 = 2e-5\nfixed_end = 'clamped'\ndrag_coefficient = 1.122\nmass_damping_per_s = 0.3\n"
        "material_damping_s = 1e-3\nangle_deg = -15.0\n"
        "[rope.fixed_end_motion]\namplitude_y_m = 0.005\nfrequency_hz = 2.0\n"
        "[solver]\nelements = 24\nstep_s = 5e-4\nspectral_radius = 0.7\nmax_iterations = 40\n"
    )
    rope, solver = load_model_config(path)
    data = read_toml(path)
    config = merge_overrides(preset("rig"), data, where=str(path))
    for key in set(data["rope"]) - {"fixed_end_motion"}:
        assert getattr(config.rope, key) == getattr(rope, key), key
    assert config.rope.fixed_end_motion == rope.fixed_end_motion
    for key in data["solver"]:
        assert getattr(config.solver, key) == getattr(solver, key), key
    assert config.rope.length_m == 0.411 and config.scene.render_diameter_m == 0.0025  # the rest stays the preset's
    allowed = ", ".join(sorted(f.name for f in dataclasses.fields(SolverConfig)))
    with pytest.raises(ConfigError, match=rf"my\.toml\.solver: unknown key 'element' \(allowed: {allowed}\)"):
        merge_overrides(config, {"solver": {"element": 3}}, where="my.toml")
    with pytest.raises(
        ConfigError, match=r"overrides\.rope\.fixed_end: must be one of 'pinned', 'clamped', got 'free'"
    ):
        merge_overrides(config, {"rope": {"fixed_end": "free"}})
    with pytest.raises(ConfigError, match=r"solver: step_s \(0.6\) must not be longer than duration_s"):
        merge_overrides(config, {"solver": {"step_s": 0.6}})
    with pytest.raises(ConfigError, match=r"scene.render_diameter_m must be > 0"):
        merge_overrides(config, {"scene": {"render_diameter_m": 0.0}})
    with pytest.raises(ConfigError, match=r"scene.clamp .*fixed_end_motion"):
        merge_overrides(config, {"scene": {"clamp": True}})


def test_unknown_preset_and_bad_overrides_are_named() -> None:
    with pytest.raises(ConfigError, match=r"unknown preset .rigg.*rig-soft"):
        preset("rigg")
    config = preset("rig")
    with pytest.raises(ConfigError, match=r"my\.toml.*unknown key 'exposure'"):
        merge_overrides(config, {"exposure": 3}, where="my.toml")
    with pytest.raises(ConfigError, match=r"scene\.polarity"):
        merge_overrides(config, {"scene": {"polarity": "grey"}})
    with pytest.raises(ConfigError, match="frames"):
        merge_overrides(config, {"frames": 0})
    with pytest.raises(ConfigError, match="exposure_ms"):
        merge_overrides(config, {"exposure_ms": [9.0]})  # longer than 1/119 s
    with pytest.raises(ConfigError, match="differ by at least 5 DN"):
        merge_overrides(config, {"scene": {"rope_level_dn": 28.0}})
    changed = merge_overrides(config, {"rope": {"ei_nm2": 3e-6}, "camera": {"plane_rvec": [0.0, 0.1, 0.0]}})
    assert changed.rope.ei_nm2 == 3e-6 and changed.camera.plane_rvec == (0.0, 0.1, 0.0)
    assert changed.rope.length_m == config.rope.length_m


def test_documented_config_example_is_valid() -> None:
    """The TOML example in docs/simulator.md loads onto a preset."""
    import re
    import tomllib
    from pathlib import Path

    text = (Path(__file__).resolve().parents[3] / "docs" / "simulator.md").read_text()
    example = re.search(r"```toml\n(.*?)```", text, re.DOTALL)
    assert example is not None
    config = merge_overrides(preset("rig"), tomllib.loads(example.group(1)), where="docs/simulator.md")
    assert config.frames == 120 and config.scene.polarity == "dark" and config.rope.ei_nm2 == 3e-6


LAB = ("lab", "lab-dark", "lab-mjpeg", "lab-rolling", "lab-hard")


def test_lab_presets_follow_the_issue() -> None:
    lab = preset("lab")
    assert lab.camera.image_size == (1024, 544) and lab.camera.fps == 119.0 and lab.exposure_ms == (4.0,)
    assert lab.camera.readout_ms == 0.0 and lab.sensor.gamma == 2.2 and lab.sensor.sharpen > 0
    assert lab.scene.polarity == "bright" and lab.scene.clamp and lab.scene.rod_width_px > 0
    assert lab.scene.rope_photo == "trackdlo_rope/rope.png" and lab.scene.flicker > 0
    assert lab.sensor.read_noise_dn > 0 and lab.scene.render_diameter_m is None  # drawn at its physical width
    assert preset("lab-dark").scene.polarity == "dark" and preset("lab-dark").scene.background_variation >= 0.3
    assert preset("lab-mjpeg").sensor.jpeg_quality == 85
    assert preset("lab-rolling").camera.readout_ms == 7.0
    hard = preset("lab-hard")
    assert hard.scene.distractor and hard.sensor.read_noise_dn > lab.sensor.read_noise_dn

    def code(linear: float) -> float:  # the output code of a linear level through the gamma curve
        return 255 * (linear / 255) ** (1 / 2.2)

    assert code(hard.scene.rope_level) - code(hard.scene.background_level) == pytest.approx(30, abs=1)
    for name in LAB:  # the lab scenes differ from `lab` only where their names say
        config = preset(name)
        assert config.rope == lab.rope and config.camera.plane_tvec_m == lab.camera.plane_tvec_m


@pytest.mark.parametrize("name", LAB)
def test_lab_scenes_at_the_paper_exposures(name: str) -> None:
    from ropecam.host.sim.presets import with_paper_timing

    config = with_paper_timing(preset(name))
    paper = preset("paper")
    assert config.preset == f"{name}+paper-exposures"
    assert config.camera.image_size == (800, 512) and config.camera.fps == 30.0
    assert config.exposure_ms == (1.0, 5.0, 9.0, 15.0) and config.rope == paper.rope
    assert config.scene == dataclasses.replace(preset(name).scene, render_diameter_m=0.006)
    assert config.sensor == preset(name).sensor and config.camera.readout_ms == preset(name).camera.readout_ms
