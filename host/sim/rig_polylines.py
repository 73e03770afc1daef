"""Realistic device polylines of the paper's rig, for wire-size benchmarks and protocol tests.

A 0.411 m rope pinned at the plane origin is released horizontally and swings down. Its angle along the rope is the
rigid-rod pendulum angle plus a smooth bend that lags at the tip (a gently curved rope, not a straight rod); the tip
reaches about 3.5 m/s at the bottom. Each frame's begin and end shapes are the rope at the start and end of a 4 ms
exposure, projected through the paper's camera (K, k1, k2, 1024 x 544, plane 1.5 m away) with
`plane_to_pixels`, resampled at one point per pixel of arc length and given subpixel noise the way an edge detector
reports them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose, plane_to_pixels

__all__ = ["RIG_CAMERA", "RIG_PLANE", "RigFrame", "rig_frames"]

RIG_CAMERA = CameraModel(
    camera_matrix=np.array([[1495.2341, 0.0, 508.0598], [0.0, 1483.2726, 275.6076], [0.0, 0.0, 1.0]]),
    distortion=np.array([-0.1793, 0.3891, 0.0, 0.0, 0.0]),
    image_size=(1024, 544),
)
# Plane 1.5 m in front of the camera, slightly tilted, the pin near the top centre so the whole swing is in view.
RIG_PLANE = PlanePose.from_rvec([0.03, -0.05, 0.01], [0.0, -0.205, 1.5])
ROPE_LENGTH_M = 0.411
GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class RigFrame:
    """One frame's ground truth as the device would report it (pixels are distorted (u, v))."""

    t_start_ns: int
    t_end_ns: int
    begin_px: NDArray[np.float64]
    end_px: NDArray[np.float64]
    fixed_end_px: NDArray[np.float64]
    material_s_m: tuple[float, ...]
    material_begin_px: NDArray[np.float64]
    material_end_px: NDArray[np.float64]


def _rod_angle(t_s: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angle below horizontal of a uniform rod released horizontally (RK4 of th'' = 3g/(2L) cos th)."""
    dt = 1e-4
    steps = int(np.ceil(np.max(t_s) / dt)) + 2
    theta, omega = 0.0, 0.0
    history = np.empty(steps)
    k = 1.5 * GRAVITY_M_S2 / ROPE_LENGTH_M
    for i in range(steps):
        history[i] = theta
        a1, v1 = k * np.cos(theta), omega
        a2, v2 = k * np.cos(theta + 0.5 * dt * v1), omega + 0.5 * dt * a1
        a3, v3 = k * np.cos(theta + 0.5 * dt * v2), omega + 0.5 * dt * a2
        a4, v4 = k * np.cos(theta + dt * v3), omega + dt * a3
        theta += dt / 6 * (v1 + 2 * v2 + 2 * v3 + v4)
        omega += dt / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
    return np.interp(t_s, np.arange(steps) * dt, history)


def _rope_xy(t_s: float, s_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rope points (x, y) in metres on the plane at material coordinates `s_m` (inextensible)."""
    fine = np.linspace(0.0, ROPE_LENGTH_M, 2001)
    base = float(_rod_angle(np.array([t_s]))[0])
    # The free end trails the rod at first and overtakes it past the bottom: a smooth bend of up to ~0.5 rad.
    bend = 0.5 * np.sin(2.2 * t_s / 0.55 * np.pi) * np.exp(-t_s)
    angle = base + bend * (fine / ROPE_LENGTH_M) ** 2 + 0.08 * np.sin(np.pi * fine / ROPE_LENGTH_M)
    ds = fine[1] - fine[0]
    x = np.concatenate([[0.0], np.cumsum(0.5 * (np.cos(angle[1:]) + np.cos(angle[:-1])) * ds)])
    y = np.concatenate([[0.0], np.cumsum(0.5 * (np.sin(angle[1:]) + np.sin(angle[:-1])) * ds)])
    return np.column_stack([np.interp(s_m, fine, x), np.interp(s_m, fine, y)])


def _device_polyline(t_s: float, rng: np.random.Generator, noise: str, noise_px: float) -> NDArray[np.float64]:
    fine_s = np.linspace(0.0, ROPE_LENGTH_M, 4001)
    pixels = plane_to_pixels(_rope_xy(t_s, fine_s), RIG_CAMERA, RIG_PLANE)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pixels, axis=0).T))])
    count = int(np.floor(arc[-1])) + 1
    at = np.linspace(0.0, arc[-1], count)
    resampled = np.column_stack([np.interp(at, arc, pixels[:, 0]), np.interp(at, arc, pixels[:, 1])])
    if noise == "uniform":
        resampled += rng.uniform(-noise_px, noise_px, resampled.shape)
    elif noise == "gaussian":
        resampled += rng.normal(0.0, noise_px, resampled.shape)
    elif noise != "none":
        raise ValueError(f"noise must be 'uniform', 'gaussian' or 'none', got {noise!r}")
    return resampled


def rig_frames(
    count: int,
    seed: int = 0,
    fps: float = 119.0,
    exposure_us: int = 4000,
    noise: str = "uniform",
    noise_px: float = 0.02,
    material_s_m: tuple[float, ...] = (0.1, 0.2, 0.3, 0.411),
) -> list[RigFrame]:
    """Return `count` consecutive frames of the swing from release (t = 0), 1/`fps` apart.

    Parameters
    ----------
    count
        Number of frames (the swing to the far side takes about 70 frames at 119 FPS; later frames repeat it).
    seed
        Seed of the noise generator.
    fps, exposure_us
        Frame rate and exposure time of the camera.
    noise, noise_px
        ``"uniform"`` (in +-noise_px per coordinate), ``"gaussian"`` (standard deviation noise_px) or ``"none"``.
    material_s_m
        Arc lengths (unstretched, metres from the pin) of the material points.
    """
    rng = np.random.default_rng(seed)
    frames = []
    s_m = np.asarray(material_s_m, dtype=np.float64)
    period_s = 0.55  # the release-to-far-side swing; frames beyond wrap around so any count stays in view
    for index in range(count):
        t_start = (index / fps) % period_s
        t_end = t_start + exposure_us * 1e-6
        begin = _device_polyline(t_start, rng, noise, noise_px)
        end = _device_polyline(t_end, rng, noise, noise_px)
        fixed = plane_to_pixels(np.zeros((1, 2)), RIG_CAMERA, RIG_PLANE)[0]
        frames.append(
            RigFrame(
                t_start_ns=round(index / fps * 1e9),
                t_end_ns=round(index / fps * 1e9) + exposure_us * 1000,
                begin_px=begin,
                end_px=end,
                fixed_end_px=fixed,
                material_s_m=tuple(material_s_m),
                material_begin_px=plane_to_pixels(_rope_xy(t_start, s_m), RIG_CAMERA, RIG_PLANE),
                material_end_px=plane_to_pixels(_rope_xy(t_end, s_m), RIG_CAMERA, RIG_PLANE),
            )
        )
    return frames
