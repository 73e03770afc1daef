"""The camera's processing options change the image the way docs/simulator.md says (acceptance 4 of #18)."""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np
import pytest

from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import SceneSpec, SensorSpec, SimConfig
from ropecam.host.sim.processing import encode_gamma, jpeg_round_trip, unsharp_mask
from ropecam.host.sim.render import RopeRenderer
from ropecam.host.sim.scene import Sensor, build_scene
from ropecam.shared.errors import ConfigError

SIZE = (96, 64)


def _flat_sensor(level_dn: float, **sensor: float) -> Sensor:
    scene = SceneSpec(background_level_dn=level_dn, rope_level_dn=level_dn + 100, background_variation=0.0,
                      vignetting=0.0)  # fmt: skip
    layers = build_scene(scene, SIZE, (48.0, 5.0), 40.0, 2.0, 0.5, seed=0)
    return Sensor(layers, SensorSpec(read_noise_dn=0.0, gain_dn_per_electron=0.0, **sensor), seed=0)


def test_gamma_maps_linear_mid_grey_to_the_expected_code() -> None:
    nothing = np.zeros(SIZE[::-1], dtype=np.float32)
    frame = _flat_sensor(127.5, gamma=2.2).expose(nothing, nothing, 0)
    assert np.all(frame == round(255 * 0.5 ** (1 / 2.2)))  # 186
    assert np.all(_flat_sensor(127.5).expose(nothing, nothing, 0) == 128)  # gamma 1: linear (rint(127.5) = 128)
    light = np.array([[0.0, 10.0, 255.0, 300.0, -4.0]], dtype=np.float32)
    expected = [[0.0, 255 * math.sqrt(10 / 255), 255.0, 255 * math.sqrt(300 / 255), 0.0]]
    np.testing.assert_allclose(encode_gamma(light, 2.0), expected, rtol=1e-6)


def test_sharpening_overshoots_an_edge_by_the_unsharp_amount() -> None:
    step = np.full((16, 40), 50.0, dtype=np.float32)
    step[:, 20:] = 150.0
    amount, sigma = 1.5, 1.0
    out = unsharp_mask(step, amount, sigma)
    kernel = cv2.getGaussianKernel(2 * math.ceil(4 * sigma) + 1, sigma).ravel()  # OpenCV's float32 kernel size
    half = kernel.size // 2
    dark_share = kernel[half + 1 :].sum()  # weight the first bright pixel's blur takes from the dark side
    assert out[8, 20] == pytest.approx(150 + amount * 100 * dark_share, abs=0.05)
    assert out[8, 19] == pytest.approx(50 - amount * 100 * dark_share, abs=0.05)
    assert np.all(np.abs(out[:, :10] - 50.0) < 1e-3) and np.all(np.abs(out[:, 30:] - 150.0) < 1e-3)  # flat: kept


def test_jpeg_round_trip_leaves_8x8_block_artefacts() -> None:
    v, u = np.mgrid[0:64, 0:96].astype(np.float64)
    smooth = 90 + 60 * np.exp(-((u - 40) ** 2 + (v - 30) ** 2) / (2 * 18.0**2)) + 0.3 * u
    frame = np.clip(np.rint(smooth), 0, 255).astype(np.uint8)

    def boundary_ratio(image: np.ndarray) -> float:
        steps = np.abs(np.diff(image.astype(np.float64), axis=1)).mean(axis=0)  # steps[j]: column j -> j + 1
        at_block = steps[7::8]
        inside = np.delete(steps, np.arange(7, steps.size, 8))
        return float(at_block.mean() / inside.mean())

    assert boundary_ratio(frame) < 1.1
    decoded = jpeg_round_trip(frame, 20)
    assert boundary_ratio(decoded) > 1.5
    assert 0.5 < np.abs(decoded.astype(float) - frame).mean() < 5
    assert np.abs(jpeg_round_trip(frame, 95).astype(float) - frame).mean() < 0.6
    # Through the sensor: off by default, on with jpeg_quality.
    nothing = np.zeros(SIZE[::-1], dtype=np.float32)
    sensor = _flat_sensor(30.0, jpeg_quality=20)
    sensor.layers.background[:] = smooth.astype(np.float32)
    np.testing.assert_array_equal(sensor.expose(nothing, nothing, 0), decoded)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [("gamma", 0.5, r"sensor.gamma must be in \[1.0, 3.0\], got 0.5"),
     ("sharpen", 4.0, r"sensor.sharpen must be in \[0.0, 3.0\]"),
     ("sharpen_sigma_px", 0.1, r"sensor.sharpen_sigma_px must be in \[0.3, 5.0\]"),
     ("jpeg_quality", 101, r"sensor.jpeg_quality must be in \[0, 100\], got 101")],
)  # fmt: skip
def test_processing_options_are_validated(key: str, value: float, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        SensorSpec(**{key: value})


def test_lens_psf_widens_the_ropes_edges_by_its_sigma(tiny: Callable[..., SimConfig],
                                                       rod_factory: Callable[..., Trajectory]) -> None:  # fmt: skip
    """Across the rope, the coverage's variance is (width^2 / 12) + psf^2 + 1/12: the PSF adds its own variance."""
    config = tiny()
    camera, plane = config.camera.camera_model(), config.camera.plane_pose()
    s = np.linspace(0, 0.411, 500)
    rod = rod_factory(0.411, 0.1)  # at rest and horizontal at t = 0
    variances = {}
    for psf in (0.5, 1.5):
        sigma = math.sqrt(psf**2 + 1 / 12)
        renderer = RopeRenderer(camera, plane, s, 0.024, np.full(500, 100.0), sigma)  # about 8 px wide
        cover = renderer.render(rod, 0.0, 0.0).cover.astype(np.float64)
        centre = renderer.project(rod.positions([0.0], s)[0])
        columns = np.rint(centre[150:350:10, 0]).astype(int)
        rows = np.arange(cover.shape[0])
        per_column = []
        for col in columns:
            weight = cover[:, col]
            mean = (weight * rows).sum() / weight.sum()
            per_column.append((weight * (rows - mean) ** 2).sum() / weight.sum())
        variances[psf] = float(np.median(per_column))
    assert variances[1.5] - variances[0.5] == pytest.approx(1.5**2 - 0.5**2, rel=0.05)


def test_motion_blur_is_averaged_in_linear_light_before_the_gamma_curve() -> None:
    half = np.full(SIZE[::-1], 0.5, dtype=np.float32)  # a pixel covered half of the exposure by a 200 DN rope
    frame = _flat_sensor(20.0, gamma=2.2).expose(half, 200.0 * half, 0)
    linear_mean = 0.5 * 20.0 + 0.5 * 200.0
    assert np.all(frame == round(255 * (linear_mean / 255) ** (1 / 2.2)))  # 174, not the mean of the codes (154)
