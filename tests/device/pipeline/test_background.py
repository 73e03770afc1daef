"""The static background's texture divided out before the edges (`ropecam.device.pipeline.background`), and setup's
decision to do so on a textured sheet (`ropecam.device.setup_background`)."""

from __future__ import annotations

import json
import tomllib

import cv2
import numpy as np
import pytest

from ropecam.device.capture.background_file import read_background_png, write_background_png
from ropecam.device.capture.frameset import FrameSetWriter
from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.cli import main
from ropecam.device.pipeline.background import BackgroundFlattening, learn_background
from ropecam.device.pipeline.tone import ToneCurve
from ropecam.device.setup_background import median_gradient
from ropecam.shared.errors import ConfigError

# A dark rope swinging in front of a white sheet with a static grain (8 % of its level): the sheet's gradients are
# four times the shot noise's, as on the simulated lab-dark preset.
ROPE = SyntheticRope(background=200.0, rope_level=40.0, noise_dn=0.0, amplitude_rad=0.7, period_s=0.9,
                     diameter_px=3.0, phase_rad=1.2, exposure_us=4000)  # fmt: skip
FRAMES = 24


def _texture(shape: tuple[int, int], amount: float, seed: int = 3) -> np.ndarray:
    grain = cv2.GaussianBlur(np.random.default_rng(seed).standard_normal(shape).astype(np.float32), (0, 0), 1.0)
    return 1.0 + amount * grain / grain.std()


def _textured_frames(count: int, amount: float = 0.08, noise_dn: float = 2.0):
    texture = _texture((ROPE.height, ROPE.width), amount)
    rng = np.random.default_rng(5)
    frames = list(ROPE.frames(count))
    images = [
        np.clip(f.image.astype(np.float32) * texture + rng.normal(0.0, noise_dn, texture.shape), 0, 255)
        .round()
        .astype(np.uint8)
        for f in frames
    ]
    return frames, images


def test_flattening_divides_a_static_texture_out_and_keeps_the_rope() -> None:
    frames, images = _textured_frames(FRAMES)
    background = learn_background(images)
    flat = BackgroundFlattening(background, 1.0)
    raw = median_gradient([images[7]], 1.0)
    out = flat.apply(images[7])
    assert median_gradient([out], 1.0) < raw / 2.5  # the grain gone, the noise left
    # The rope keeps its depth: on its axis (the middle of the centreline at the exposure's start), as drawn
    # without the grain, within the noise.
    col, row = np.round(frames[7].begin_uv[len(frames[7].begin_uv) // 2]).astype(int)
    assert frames[7].image[row, col] < 150
    assert abs(int(out[row, col]) - int(frames[7].image[row, col])) < 10


def test_a_plain_background_changes_nothing_but_the_tone_curve() -> None:
    _, images = _textured_frames(3, amount=0.0)
    flat = BackgroundFlattening(np.full(images[0].shape, 180.0, np.float32), 2.2)
    assert np.array_equal(flat.apply(images[1]), ToneCurve(2.2, images[1].shape).apply(images[1]))


def test_background_png_round_trip_and_bad_files(tmp_path) -> None:
    background = np.linspace(10.0, 200.0, 12 * 16, dtype=np.float32).reshape(12, 16)
    path = tmp_path / "bg.png"
    write_background_png(path, background)
    assert np.allclose(read_background_png(path, (12, 16)), background, atol=1 / 256)
    with pytest.raises(ConfigError, match=r"background_png: background .*16x12 px, the frames are 20x12"):
        read_background_png(path, (12, 20))
    eight = tmp_path / "eight.png"
    cv2.imwrite(str(eight), np.zeros((12, 16), np.uint8))
    with pytest.raises(ConfigError, match=r"background_png: .*expected a 16-bit grey PNG"):
        read_background_png(eight, (12, 16))
    with pytest.raises(ConfigError, match=r"background_png: background image .* does not exist"):
        read_background_png(tmp_path / "none.png", (12, 16))


def test_setup_divides_a_textured_sheet_out_and_extract_measures(tmp_path) -> None:
    frames, images = _textured_frames(FRAMES)
    root = tmp_path / "set"
    with FrameSetWriter(root, (ROPE.width, ROPE.height), ROPE.fps) as writer:
        for image, f in zip(images, frames, strict=True):
            writer.add(image, f.t_ns, ROPE.exposure_us)
    out = tmp_path / "device.toml"
    assert main(["setup", str(root), "--out", str(out), "--rope-length-m", "0.5", "--quiet"]) == 0
    table = tomllib.loads(out.read_text())["pipeline"]
    assert table["background_png"] == str(tmp_path / "device_background.png")
    assert read_background_png(table["background_png"], images[0].shape).shape == images[0].shape
    results = tmp_path / "out.jsonl"
    assert main(["extract", str(root), "--config", str(out), "--out", str(results), "--quiet"]) == 0
    records = [json.loads(line) for line in results.read_text().splitlines()]
    assert sum(r["status"] == "OK" for r in records) >= FRAMES - 2


def test_a_clamp_wider_than_the_level_keeps_the_sheet_round_it_flat() -> None:
    """A dark clamp 40 px wide on the textured sheet (as `lab-dark`'s) is left as it is (gain 1) and the sheet 4-12 px
    round it is flattened as the sheet far from it (its gradients no higher). A plainness test against a Gaussian
    of the background took the clamp's inside for plain and divided it (the last assertion fails with it); on the
    simulator's shaded clamp with its rod that also darkened a ring of sheet round it whose gradients broke the
    rope's outline where it leaves the clamp (`flat_gain`). This plain block does not make that ring with the old
    test, so the ring assertion guards the property, not that regression."""
    from ropecam.device.pipeline.edges import EdgeDetector

    height, width = 160, 200
    sheet = 180.0 * _texture((height, width), 0.08)
    sheet[40:70, 80:120] = 25.0
    background = cv2.GaussianBlur(sheet.astype(np.float32), (0, 0), 0.7)
    frame = np.clip(background + np.random.default_rng(4).normal(0.0, 2.0, sheet.shape), 0, 255)
    out = BackgroundFlattening(background, 1.0).apply(frame.round().astype(np.uint8))
    detector = EdgeDetector(height, width, 1.0, 1e9, 1e9)
    detector.detect(out, np.zeros(height, np.int32), np.full(height, width - 1, np.int32))
    ring = np.zeros((height, width), bool)
    ring[28:82, 68:132] = True
    ring[36:74, 76:124] = False
    far = np.zeros((height, width), bool)
    far[100:150, 20:180] = True
    assert np.percentile(detector.mag[ring], 90) < 1.3 * np.percentile(detector.mag[far], 90)
    assert np.array_equal(out[45:65, 85:115], frame[45:65, 85:115].round().astype(np.uint8))  # the clamp: gain 1
