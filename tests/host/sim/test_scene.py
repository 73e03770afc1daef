"""Scene and sensor: seeded, levels as configured, noise of the configured size, the options visible."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import SceneSpec, SensorSpec, SimConfig
from ropecam.host.sim.generate import write_frameset
from ropecam.host.sim.render import RopeRenderer
from ropecam.host.sim.scene import CLAMP_LEVEL_DN, Sensor, build_scene, rope_levels

SIZE = (120, 80)


def _layers(scene: SceneSpec, seed: int = 1):
    return build_scene(scene, SIZE, (60.0, 10.0), 60.0, 2.0, 0.5, seed)


def test_noise_has_the_configured_size_and_is_seeded() -> None:
    scene = SceneSpec(background_variation=0.0, vignetting=0.0)
    sensor = Sensor(_layers(scene), SensorSpec(read_noise_dn=2.0, gain_dn_per_electron=0.1), seed=5)
    nothing = np.zeros(SIZE[::-1], dtype=np.float32)
    frame = sensor.expose(nothing, nothing, frame=0).astype(np.float64)
    expected = np.sqrt(2.0**2 + 0.1 * 25.0 + 1 / 12)  # read, shot at 25 DN, rounding
    assert abs(frame.mean() - 25.0) < 0.1
    assert abs(frame.std() - expected) < 0.05 * expected
    np.testing.assert_array_equal(sensor.expose(nothing, nothing, frame=0), frame.astype(np.uint8))
    assert not np.array_equal(sensor.expose(nothing, nothing, frame=1), frame.astype(np.uint8))
    quiet = Sensor(_layers(scene), SensorSpec(0.0, 0.0), seed=5).expose(nothing, nothing, frame=0)
    assert np.all(quiet == 25)


def test_background_vignetting_texture_scratch_and_clamp() -> None:
    plain = _layers(SceneSpec(background_variation=0.0, vignetting=0.0))
    assert np.all(plain.background == 25.0) and np.all(plain.vignette == 1.0) and not plain.clamp.any()
    varied = _layers(SceneSpec(background_variation=0.2, vignetting=0.3))
    assert 0.1 < (varied.background.max() - varied.background.min()) / 25.0 <= 0.4
    assert abs(varied.vignette.min() - 0.7) < 1e-3 and abs(varied.vignette.max() - 1.0) < 1e-3
    np.testing.assert_array_equal(varied.background, _layers(SceneSpec(background_variation=0.2)).background)
    assert not np.array_equal(varied.background, _layers(SceneSpec(background_variation=0.2), seed=2).background)
    textured = _layers(SceneSpec(background_variation=0.0, texture=0.1))
    assert abs(textured.background.std() / 25.0 - 0.1) < 0.02
    scratched = _layers(SceneSpec(background_variation=0.0, scratch=True))
    assert scratched.scratch_px is not None and scratched.background.max() > 25.0 + 0.5 * 90
    clamped = _layers(SceneSpec(clamp=True))
    assert clamped.clamp[10, 60] > 0.99 and clamped.clamp[60, 10] == 0.0
    sensor = Sensor(clamped, SensorSpec(0.0, 0.0), seed=0)
    nothing = np.zeros(SIZE[::-1], dtype=np.float32)
    assert abs(int(sensor.expose(nothing, nothing, 0)[10, 60]) - CLAMP_LEVEL_DN * clamped.vignette[10, 60]) <= 1


def test_uneven_rope_moves_with_the_material() -> None:
    s = np.linspace(0, 0.411, 300)
    uniform = rope_levels(SceneSpec(), s, seed=3)
    uneven = rope_levels(SceneSpec(rope_unevenness=0.3), s, seed=3)
    assert np.all(uniform == 210.0)
    assert 0.1 < (uneven.max() - uneven.min()) / 210.0 <= 0.6
    np.testing.assert_array_equal(uneven, rope_levels(SceneSpec(rope_unevenness=0.3), s, seed=3))


def test_motion_blur_conserves_the_rope_and_uses_fine_subframes(
    tiny: Callable[..., SimConfig], rod_factory: Callable[..., Trajectory]
) -> None:
    """A moving rope smears, but its total coverage (time average of its area) stays its area."""
    config = tiny()
    camera, plane = config.camera.camera_model(), config.camera.plane_pose()
    s = np.linspace(0, 0.411, 400)
    renderer = RopeRenderer(camera, plane, s, config.render_diameter_m, np.full(400, 100.0), 0.5)
    rod = rod_factory(0.411, 0.3)
    still = renderer.render(rod, 0.2, 0.2)
    area = float(still.cover.sum())
    length_px = np.linalg.norm(np.diff(still.begin_px, axis=0), axis=1).sum()
    assert abs(area - length_px * 2 * still.half_width_px.mean()) < 0.02 * area
    moving = renderer.render(rod, 0.2, 0.208)
    assert moving.subframes > 10 and moving.max_step_px <= 0.5
    assert abs(float(moving.cover.sum()) - area) < 0.02 * area
    # Smeared: near the tip, which moves about 8 px, a pixel is covered for a fraction of the exposure only.
    u, v = np.rint(renderer.project(rod.positions([0.204], [0.4])[0, 0])).astype(int)
    assert moving.cover[v, u] < 0.4 < still.cover.max()
    np.testing.assert_allclose(moving.signal, 100.0 * moving.cover, rtol=1e-4, atol=1e-4)


def test_dark_polarity_options_end_to_end(
    tmp_path: Path, tiny: Callable[..., SimConfig], curl_factory: Callable[..., Trajectory]
) -> None:
    config = tiny(frames=2)
    scene = dataclasses.replace(
        config.scene, polarity="dark", texture=0.05, rope_unevenness=0.3, scratch=True, clamp=True
    )
    config = dataclasses.replace(config, scene=scene, seed=11)
    write_frameset(config, curl_factory(0.411, 0.2), tmp_path / "set", 2.0)
    frames = FrameSet(tmp_path / "set")
    truth = frames.truth()
    assert truth is not None
    image = frames.read(1).astype(np.float64)
    assert np.median(image) > 150
    samples = np.rint(truth["begin_px"][1][len(truth["s_m"]) // 3 :: 40]).astype(int)
    assert np.median(image[samples[:, 1], samples[:, 0]]) < 110
    u0, v0, u1, v1 = frames.meta["rig"]["clamp_box_px"]
    assert abs(np.median(image[int(v0) + 2 : int(v1) - 1, int(u0) + 2 : int(u1) - 1]) - CLAMP_LEVEL_DN) < 20
