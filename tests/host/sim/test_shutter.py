"""Rolling shutter and flicker: the image shears and brightens as stated, the truth follows each row's instants."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import CameraSpec, SimConfig
from ropecam.host.sim.generate import write_frameset
from ropecam.host.sim.shutter import flicker_gain, row_offsets_s, row_weights
from ropecam.shared.errors import ConfigError

FX, Z, HEIGHT, WIDTH = 400.0, 1.0, 120, 160


def translating_rope(speed_m_s: float, length_m: float = 0.25, duration_s: float = 0.1) -> Trajectory:
    """A straight rope hanging along +y from x = -0.1 m, moving along +x at constant speed (nodes exact)."""
    times = np.arange(0.0, duration_s + 5e-4, 1e-3)
    elements = 2
    s = np.linspace(0.0, length_m, elements + 1)
    q = np.zeros((times.size, elements + 1, 4))
    q[:, :, 0] = -0.1 + speed_m_s * times[:, None]
    q[:, :, 1] = s[None, :]
    q[:, :, 3] = 1.0
    qdot = np.zeros_like(q)
    qdot[:, :, 0] = speed_m_s
    return Trajectory(length_m, times, q.reshape(times.size, -1), qdot.reshape(times.size, -1))


def _camera(readout_ms: float) -> CameraSpec:
    # Fixed end (plane origin) at pixel (80, 0); no tilt, no distortion: u = 80 + FX x / Z, v = FX y / Z.
    return CameraSpec(FX, FX, WIDTH / 2, 0.0, WIDTH, HEIGHT, 50.0, (0.0, 0.0, Z), readout_ms=readout_ms)


def _rolling_config(tiny: Callable[..., SimConfig], readout_ms: float, exposure_ms: float) -> SimConfig:
    config = tiny(clean=True, frames=1, first_exposure_s=0.02, exposure_ms=(exposure_ms,))
    scene = dataclasses.replace(config.scene, render_diameter_m=0.01)  # 4 px wide
    rope = dataclasses.replace(config.rope, length_m=0.25)
    return dataclasses.replace(config, camera=_camera(readout_ms), scene=scene, rope=rope)


def _row_centroids(image: np.ndarray, background: float) -> tuple[np.ndarray, np.ndarray]:
    weight = np.clip(image.astype(np.float64) - background, 0, None)
    rows = np.nonzero(weight.sum(axis=1) > 50)[0]
    cols = np.arange(image.shape[1])
    return rows, (weight[rows] * cols).sum(axis=1) / weight[rows].sum(axis=1)


@pytest.mark.parametrize("readout_ms", [0.0, 15.0])
def test_rolling_shutter_shears_a_moving_rope_by_speed_times_row_delay(
    tmp_path: Path, tiny: Callable[..., SimConfig], readout_ms: float
) -> None:
    speed = 2.0  # m/s = 800 px/s: a 15 ms readout over 119 rows shifts each row by 800 * 0.015 / 119 = 0.1 px
    config = _rolling_config(tiny, readout_ms, exposure_ms=1.0)
    write_frameset(config, translating_rope(speed), tmp_path / "set", 1.0)
    frames = FrameSet(tmp_path / "set")
    truth = frames.truth()
    assert truth is not None
    rows, centres = _row_centroids(frames.read(0), config.scene.background_level)
    rows_used = (rows > 10) & (rows < 0.25 * FX - 10)  # away from the rope's ends
    slope, _ = np.polyfit(rows[rows_used], centres[rows_used], 1)
    expected = FX * speed / Z * readout_ms * 1e-3 / HEIGHT
    assert slope == pytest.approx(expected, abs=0.002), f"shear {slope:.4f} px/row, expected {expected:.4f}"
    # Each row is the rope at the middle of that row's exposure: u = 80 + FX (x(t_row + T / 2)) / Z.
    t_mid = 0.02 + row_offsets_s(HEIGHT, readout_ms * 1e-3)[rows[rows_used]] + 0.5e-3
    np.testing.assert_allclose(centres[rows_used], 80 + FX * (-0.1 + speed * t_mid) / Z, atol=0.02)
    # Truth: each point where it was when its own row's exposure started and ended.
    begin, end = truth["begin_px"][0], truth["end_px"][0]
    if readout_ms:
        t_begin = truth["begin_point_t_ns"][0] * 1e-9
        np.testing.assert_allclose(t_begin, 0.02 + readout_ms * 1e-3 * begin[:, 1] / HEIGHT, atol=1e-11)
        np.testing.assert_allclose(truth["end_point_t_ns"][0] * 1e-9 - t_begin, 1e-3, atol=1e-11)
        np.testing.assert_allclose(truth["row_offset_ns"], np.arange(HEIGHT) * readout_ms * 1e6 / HEIGHT)
        assert frames.meta["rig"]["readout_ms"] == readout_ms
    else:
        assert "begin_point_t_ns" not in truth and "row_offset_ns" not in truth
        t_begin = np.full(begin.shape[0], 0.02)
    np.testing.assert_allclose(begin[:, 0], 80 + FX * (-0.1 + speed * t_begin) / Z, atol=1e-9)
    np.testing.assert_allclose(end[:, 0], 80 + FX * (-0.1 + speed * (t_begin + 1e-3)) / Z, atol=1e-9)


def test_row_weights_average_each_rows_own_exposure() -> None:
    times = np.linspace(0.0, 0.01, 41)
    begin = np.array([0.0, 0.0013, 0.004, 0.006])
    weights = row_weights(times, begin, 0.004)
    np.testing.assert_allclose(weights.sum(axis=0), 1.0, atol=1e-12)
    # A linear function of time averages to its value at the middle of each row's exposure.
    np.testing.assert_allclose(weights.T @ (3.0 + 100.0 * times), 3.0 + 100.0 * (begin + 0.002), atol=1e-12)
    assert np.all(weights[times > 0.0101 + 1e-9] == 0)


def test_flicker_changes_mean_brightness_by_its_amplitude_at_its_frequency(
    tmp_path: Path, tiny: Callable[..., SimConfig], rod_factory: Callable[..., Trajectory]
) -> None:
    config = tiny(clean=True, frames=12, first_exposure_s=0.01, exposure_ms=(2.0,))
    scene = dataclasses.replace(config.scene, flicker=0.2, flicker_hz=100.0, background_level_dn=100.0)
    config = dataclasses.replace(config, scene=scene)
    write_frameset(config, rod_factory(0.411, 0.2), tmp_path / "set", 2.0)
    frames = FrameSet(tmp_path / "set")
    corner = np.array([frames.read(k)[150:, :60].mean() for k in range(len(frames))])  # rope-free
    t = np.array([r.t_ns for r in frames.records]) * 1e-9
    # Fit mean = B + a sin + b cos at 100 Hz over the frame's exposure: the lamp's amplitude, reduced by the
    # exposure's averaging (sinc), is what the frames show.
    omega, exposure = 2 * math.pi * 100.0, 2e-3
    design = np.stack([np.ones_like(t), np.sin(omega * (t + exposure / 2)), np.cos(omega * (t + exposure / 2))], 1)
    (base, a, b), *_ = np.linalg.lstsq(design, corner, rcond=None)
    amplitude = math.hypot(a, b) / base
    expected = 0.2 * math.sin(omega * exposure / 2) / (omega * exposure / 2)
    assert amplitude == pytest.approx(expected, abs=0.005), f"{amplitude:.4f} vs {expected:.4f}"
    assert np.abs(design @ [base, a, b] - corner).max() < 0.75  # nothing but 100 Hz (and rounding to 8 bits)
    assert abs(b) < 0.02 * base  # in phase with sin(2 pi f t) on the model's clock
    assert frames.meta["rig"]["flicker"] == {"amplitude": 0.2, "frequency_hz": 100.0}
    # Zero exposure: the instantaneous value; rows of a rolling shutter see different phases.
    gain = flicker_gain(np.array([0.0, 0.0025, 0.005]), 0.0, 0.3, 100.0)
    np.testing.assert_allclose(gain[:, 0], [1.0, 1.3, 1.0], atol=1e-6)


@pytest.mark.parametrize(
    ("changes", "message"),
    [({"camera": {"readout_ms": 30.0}}, r"camera.readout_ms must be in \[0.0, 8.40"),
     ({"camera": {"readout_ms": -1.0}}, r"camera.readout_ms must be in"),
     ({"scene": {"flicker": 1.5}}, r"scene.flicker must be in \[0.0, 0.9\], got 1.5"),
     ({"scene": {"flicker_hz": 0.0}}, r"scene.flicker_hz must be in \[1.0, 1000.0\]")],
)  # fmt: skip
def test_timing_options_are_validated(changes: dict, message: str) -> None:
    from ropecam.host.sim.config import merge_overrides
    from ropecam.host.sim.presets import preset

    with pytest.raises(ConfigError, match=message):
        merge_overrides(preset("rig"), changes)


def test_positions_at_each_points_own_time_match_the_trajectory(curl_factory: Callable[..., Trajectory]) -> None:
    from ropecam.host.sim.shutter import positions_at

    curl = curl_factory(0.411, 0.2)
    s = np.linspace(0.0, 0.411, 57)
    t = np.linspace(0.013, 0.171, 57)
    expected = np.stack([curl.positions([ti], [si])[0, 0] for ti, si in zip(t, s, strict=True)])
    np.testing.assert_allclose(positions_at(curl, t, s), expected, atol=1e-14)
