"""Rope photos: the photographed rope is found and straightened, and its texture is painted along the rope."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.cli import main
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim import _kernels
from ropecam.host.sim.config import SceneSpec, SimConfig
from ropecam.host.sim.generate import write_frameset
from ropecam.host.sim.rope_photo import load_rope_strip
from ropecam.shared.errors import ConfigError

BRAIDED = "trackdlo_rope/rope.png"
WITH_MASK = "mbest_dlo_dataset/S1/images/img37.jpg"


@pytest.mark.parametrize("photo", [BRAIDED, WITH_MASK])
def test_the_photographed_rope_is_found_and_straightened(realdata_dir: Path, photo: str) -> None:
    strip = load_rope_strip(realdata_dir / photo)
    # trackdlo's rope is about 15-18 px wide (SOURCES.md), mBEST's about 15 px; both several hundred px long.
    assert 12 < strip.diameter_px < 22
    assert strip.strip.shape[0] > 600 and strip.strip.shape[1] >= 9
    assert strip.strip.mean() == pytest.approx(1.0, abs=1e-5)
    steps = np.linalg.norm(np.diff(strip.path_px, axis=0), axis=1)
    np.testing.assert_allclose(steps, 1.0, atol=0.05)  # one row per photo pixel of arc
    if photo == BRAIDED:
        # The braid: brightness along the rope repeats with a period of about half a diameter to a diameter.
        centre = strip.strip[:, strip.strip.shape[1] // 2] - strip.strip[:, strip.strip.shape[1] // 2].mean()
        spectrum = np.abs(np.fft.rfft(centre))
        period = centre.size / (np.argmax(spectrum[5:]) + 5)
        assert 0.3 * strip.diameter_px < period < 1.2 * strip.diameter_px, period


def _reference_level(points: np.ndarray, radius: float, level: float, table: np.ndarray, rows_per_sample: float,
                     pixel: tuple[int, int]) -> float:  # fmt: skip
    """Level at a pixel near a straight, left-to-right polyline: the table read at (arc, across), bilinear."""
    u, v = pixel
    arc = (u - points[0, 0]) / (points[1, 0] - points[0, 0])
    side = (v - points[0, 1]) / radius  # image v down = right of the direction of travel (+u)
    row = (arc * rows_per_sample) % table.shape[0]
    col = (np.clip(side, -1, 1) + 1) / 2 * (table.shape[1] - 1)
    r0, c0 = int(row), min(int(col), table.shape[1] - 1)
    r1, c1 = (r0 + 1) % table.shape[0], min(c0 + 1, table.shape[1] - 1)
    fr, fc = row - r0, col - c0
    top = table[r0, c0] * (1 - fc) + table[r0, c1] * fc
    bottom = table[r1, c0] * (1 - fc) + table[r1, c1] * fc
    return level * (top * (1 - fr) + bottom * fr)


def test_kernel_paints_the_texture_by_material_coordinate_and_side() -> None:
    rng = np.random.default_rng(4)
    table = rng.uniform(0.5, 1.5, size=(7, 5)).astype(np.float32)
    points = np.ascontiguousarray(np.stack([np.linspace(5.0, 45.0, 81), np.full(81, 10.3)], axis=-1))
    shape = (20, 50)
    dist = np.full(shape, _kernels.FAR, dtype=np.float32)
    radius_px, level_px, cut = (np.zeros(shape, dtype=np.float32) for _ in range(3))
    box = np.array([50, 20, -1, -1], dtype=np.int32)
    stamped = _kernels.stamp_centreline(points, np.full(81, 2.0), np.full(81, 100.0), 0.5, table, 0.37, 0, 19,
                                        dist, radius_px, level_px, cut, box)  # fmt: skip
    assert stamped == 80
    for pixel in [(12, 9), (20, 10), (27, 11), (33, 12), (40, 8)]:
        expected = _reference_level(points, 2.0, 100.0, table, 0.37, pixel)
        assert level_px[pixel[1], pixel[0]] == pytest.approx(expected, rel=1e-5), pixel


def test_rope_photo_end_to_end_and_contrast(
    tmp_path: Path, realdata_dir: Path, tiny: Callable[..., SimConfig], rod_factory: Callable[..., Trajectory]
) -> None:
    rod = rod_factory(0.411, 0.2)
    looks = {}
    for name, contrast in (("plain", None), ("photo", 1.0), ("flat", 0.0)):
        config = tiny(clean=True, frames=1, first_exposure_s=0.0, exposure_ms=(0.01,))
        scene = dataclasses.replace(config.scene, render_diameter_m=0.012)
        if contrast is not None:
            scene = dataclasses.replace(scene, photo_dir=str(realdata_dir), rope_photo=BRAIDED,
                                        rope_photo_contrast=contrast)  # fmt: skip
        write_frameset(dataclasses.replace(config, scene=scene), rod, tmp_path / name, 0.01)
        frames = FrameSet(tmp_path / name)
        truth = frames.truth()
        assert truth is not None
        centre = np.rint(truth["begin_px"][0][100:-100]).astype(int)
        looks[name] = frames.read(0)[centre[:, 1], centre[:, 0]].astype(np.float64)
    assert FrameSet(tmp_path / "photo").meta["rig"]["rope_photo"] == str(realdata_dir / BRAIDED)
    plain_spread = looks["plain"].std() / looks["plain"].mean()
    photo_spread = looks["photo"].std() / looks["photo"].mean()
    assert plain_spread < 0.03 < 0.1 < photo_spread  # the braid shows along the rope
    np.testing.assert_allclose(looks["flat"], looks["plain"], atol=1.0)  # contrast 0: a plain rope


def test_missing_photo_names_key_and_path_and_writes_nothing(
    tmp_path: Path, rod_factory: Callable[..., Trajectory], capsys: pytest.CaptureFixture[str]
) -> None:
    rod = tmp_path / "rod.npz"
    rod_factory(0.411, 0.1).save(rod)
    out = tmp_path / "set"
    argv = ["simulate", "rig", "--out", str(out), "--trajectory", str(rod), "--frames", "2", "-q"]
    assert main([*argv, "--photo-dir", str(tmp_path), "--rope-photo", "nope.png"]) == 2
    err = capsys.readouterr().err
    assert "scene.rope_photo" in err and str(tmp_path / "nope.png") in err and "not found" in err
    assert not out.exists()
    with pytest.raises(ConfigError, match=r"scene.rope_photo_contrast must be in \[0.0, 2.0\], got 3"):
        SceneSpec(rope_photo_contrast=3)
    (tmp_path / "blank.png").write_bytes(b"not an image")
    assert main([*argv, "--photo-dir", str(tmp_path), "--rope-photo", "blank.png"]) == 2
    assert "not an image OpenCV can read" in capsys.readouterr().err
    assert not out.exists()


def test_plate_photo_gives_the_plate_a_real_surfaces_grain(realdata_dir: Path) -> None:
    from ropecam.host.sim.rope_photo import load_plate_texture
    from ropecam.host.sim.scene import build_scene

    texture = load_plate_texture(realdata_dir / BRAIDED, (300, 200))
    assert texture.shape == (200, 300) and abs(float(texture.mean())) < 1e-6
    assert 0.003 < texture.std() < 0.03  # a white table: grain and smudges of about 1 %
    plain = SceneSpec(background_variation=0.0, vignetting=0.0, photo_dir=str(realdata_dir))
    layers = build_scene(dataclasses.replace(plain, plate_photo=BRAIDED, plate_photo_contrast=5.0), (300, 200),
                         (150.0, 10.0), 100.0, 2.0, 0.5, seed=0)  # fmt: skip
    relative = layers.background / 25.0 - 1.0
    np.testing.assert_allclose(relative, 5.0 * texture, atol=1e-5)
    with pytest.raises(ConfigError, match=r"scene.plate_photo: plate photo '.*missing.png' not found"):
        build_scene(dataclasses.replace(plain, plate_photo="missing.png"), (300, 200), (150.0, 10.0), 100.0, 2.0,
                    0.5, seed=0)  # fmt: skip
    with pytest.raises(ConfigError, match=r"scene.plate_photo_contrast must be in \[0.0, 20.0\], got 25"):
        SceneSpec(plate_photo_contrast=25)
