"""Trajectories built by hand for the simulator's tests (the renderer only depends on the `Trajectory` interface)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ropecam.host.calibration.geometry import CameraModel
from ropecam.host.model.config import RopeConfig
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import CameraSpec, SceneSpec, SensorSpec, SimConfig
from ropecam.host.sim.presets import plane_through_pixel


def rigid_rod(length_m: float, duration_s: float, step_s: float = 1e-3, elements: int = 4) -> Trajectory:
    """Return a rigid uniform rod released at rest from horizontal (+x), swinging down (+y) about the origin.

    theta'' = (3 g / 2 L) cos(theta), integrated with RK4; nodes on the line, slopes = the unit direction.
    """
    g = 9.81
    times = np.arange(0.0, duration_s + step_s / 2, step_s)
    state = np.zeros((times.size, 2))

    def rate(y: np.ndarray) -> np.ndarray:
        return np.array([y[1], 1.5 * g / length_m * np.cos(y[0])])

    for i in range(1, times.size):
        y = state[i - 1]
        k1 = rate(y)
        k2 = rate(y + step_s / 2 * k1)
        k3 = rate(y + step_s / 2 * k2)
        k4 = rate(y + step_s * k3)
        state[i] = y + step_s / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    theta, omega = state[:, 0], state[:, 1]
    s = np.linspace(0.0, length_m, elements + 1)
    direction = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    turning = np.stack([-np.sin(theta), np.cos(theta)], axis=-1) * omega[:, None]
    q = np.zeros((times.size, elements + 1, 4))
    qdot = np.zeros_like(q)
    q[:, :, 0:2] = s[None, :, None] * direction[:, None, :]
    q[:, :, 2:4] = direction[:, None, :]
    qdot[:, :, 0:2] = s[None, :, None] * turning[:, None, :]
    qdot[:, :, 2:4] = turning[:, None, :]
    return Trajectory(length_m, times, q.reshape(times.size, -1), qdot.reshape(times.size, -1))


def curling_rope(length_m: float, duration_s: float, step_s: float = 1e-3, elements: int = 16) -> Trajectory:
    """Return a rope bent into a circular arc whose curvature grows while it rotates (a curl, not dynamics).

    Nodal slopes are the arc's unit tangents; velocities are central differences of the nodal coordinates.
    """
    times = np.arange(0.0, duration_s + step_s / 2, step_s)
    s = np.linspace(0.0, length_m, elements + 1)
    heading = 0.2 + 2.0 * times  # rad, direction at the fixed end
    curvature = (0.5 + 6.0 * times / max(duration_s, 1e-9)) / length_m  # 1/m
    angle = heading[:, None] + curvature[:, None] * s[None, :]
    x = (np.sin(angle) - np.sin(heading)[:, None]) / curvature[:, None]
    y = (np.cos(heading)[:, None] - np.cos(angle)) / curvature[:, None]
    q = np.stack([x, y, np.cos(angle), np.sin(angle)], axis=-1).reshape(times.size, -1)
    qdot = np.gradient(q, times, axis=0)
    return Trajectory(length_m, times, q, qdot)


@pytest.fixture
def rod_factory() -> Callable[..., Trajectory]:
    """Factory of rigid-rod trajectories: ``rod_factory(length_m, duration_s)``."""
    return rigid_rod


@pytest.fixture
def curl_factory() -> Callable[..., Trajectory]:
    """Factory of curling-arc trajectories: ``curl_factory(length_m, duration_s)``."""
    return curling_rope


def tiny_config(clean: bool = False, **changes: object) -> SimConfig:
    """Return a small rig (320x200, distortion, tilted plane at 1.5 m, 0.411 m rope about 2 px wide), 3 frames.

    `clean` removes noise, background non-uniformity and vignetting; `changes` replace `SimConfig` fields.
    """
    matrix = np.array([[500.0, 0.0, 161.3], [0.0, 496.0, 99.2], [0.0, 0.0, 1.0]])
    distortion = (-0.1793, 0.3891, 0.001, -0.0005, 0.0)
    model = CameraModel(matrix, np.array(distortion), (320, 200))
    tvec = plane_through_pixel(model, 1.5, (160.0, 30.0))
    camera = CameraSpec(500.0, 496.0, 161.3, 99.2, 320, 200, 119.0, tvec, (0.05, -0.08, 0.03), distortion)
    rope = RopeConfig(length_m=0.411, diameter_m=0.001)
    scene = SceneSpec(render_diameter_m=0.006)
    config = SimConfig("tiny", camera, rope, scene=scene, frames=3, exposure_ms=(4.0,), first_exposure_s=0.1)
    if clean:
        scene = dataclasses.replace(config.scene, background_variation=0.0, vignetting=0.0, texture=0.0)
        config = dataclasses.replace(config, scene=scene, sensor=SensorSpec(0.0, 0.0))
    return dataclasses.replace(config, **changes) if changes else config


@pytest.fixture
def tiny() -> Callable[..., SimConfig]:
    """Factory of the small test rig: ``tiny(clean=False, **SimConfig field changes)``."""
    return tiny_config


@pytest.fixture(scope="session")
def realdata_dir() -> Path:
    """The real photographs in ``../shared/realdata`` (beside the repository; beside the worktrees' parent too)."""
    root = Path(__file__).resolve().parents[3]
    for candidate in (root.parent / "shared" / "realdata", root.parents[1] / "shared" / "realdata"):
        if candidate.is_dir():
            return candidate
    pytest.fail(f"{root.parent / 'shared' / 'realdata'} is missing: the rope photos are read from ../shared")


def _distance_to_polyline(point: np.ndarray, polyline: np.ndarray) -> float:
    a, b = polyline[:-1], polyline[1:]
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", point - a, d) / np.einsum("ij,ij->i", d, d), 0, 1)
    return float(np.linalg.norm(point - a - t[:, None] * d, axis=1).min())


def _cross_centres(image: np.ndarray, weight: np.ndarray, centreline: np.ndarray, skip_px: float) -> np.ndarray:
    """Intensity-weighted centres across the rope: per pixel column (or row, where the rope is steep).

    Returns the distance of each centre to the centreline polyline, for crossings more than `skip_px` (along the
    rope) from its ends.
    """
    height, width = image.shape
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(centreline, axis=0), axis=1))])
    errors = []
    for i in range(len(centreline) - 1):
        if arc[i] < skip_px or arc[i] > arc[-1] - skip_px:
            continue
        a, b = centreline[i], centreline[i + 1]
        steep = abs(b[1] - a[1]) > abs(b[0] - a[0])
        along, across = (1, 0) if steep else (0, 1)
        # Each integer column (row) crossed by this segment gives one profile.
        for line in range(int(np.ceil(min(a[along], b[along]))), int(np.floor(max(a[along], b[along]))) + 1):
            if b[along] == a[along] or not (a[along] <= line < b[along] or b[along] <= line < a[along]):
                continue
            at = a[across] + (line - a[along]) / (b[along] - a[along]) * (b[across] - a[across])
            cells = np.arange(round(at) - 6, round(at) + 7)
            if (
                cells.min() < 0
                or cells.max() >= (height if not steep else width)
                or not 0 <= line < (width if not steep else height)
            ):
                continue
            w = weight[cells, line] if not steep else weight[line, cells]
            centre = float((w * cells).sum() / w.sum())
            point = np.array([line, centre]) if not steep else np.array([centre, line])
            errors.append(_distance_to_polyline(point, centreline))
    return np.array(errors)


@pytest.fixture
def cross_centres() -> Callable[..., np.ndarray]:
    """``cross_centres(image, weight, centreline, skip_px)``: distances of the weighted centres across the rope."""
    return _cross_centres
