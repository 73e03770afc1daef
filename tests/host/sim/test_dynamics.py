"""The presets' motion from the ANCF model: stiff ropes swing like rods, the soft variants visibly curl."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.cli import main
from ropecam.host.model import simulate
from ropecam.host.model.config import FixedEndMotion, RopeConfig, SolverConfig
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import SimConfig
from ropecam.host.sim.dynamics import solve_trajectory
from ropecam.host.sim.presets import preset
from ropecam.shared.config import from_mapping


def _curl(trajectory: Trajectory) -> tuple[float, float]:
    """Largest bow away from the chord (fraction of L) and largest angle between the end directions (degrees)."""
    s = np.linspace(0.0, trajectory.length_m, 60)
    points = trajectory.sample_positions(s)
    chord = points[:, -1] - points[:, 0]
    normal = np.stack([-chord[:, 1], chord[:, 0]], axis=-1) / np.linalg.norm(chord, axis=-1, keepdims=True)
    bow = np.abs(np.einsum("tsk,tk->ts", points - points[:, :1], normal)).max()
    tangent = np.diff(points, axis=1)
    angle = np.unwrap(np.arctan2(tangent[..., 1], tangent[..., 0]), axis=1)
    return float(bow / trajectory.length_m), float(np.degrees(np.abs(angle[:, -1] - angle[:, 0]).max()))


@pytest.mark.parametrize(("name", "bow_range"), [("rig", (0.0, 0.02)), ("rig-soft", (0.1, 0.5)),
                                                 ("paper", (0.0, 0.02)), ("paper-soft", (0.2, 0.6))])  # fmt: skip
def test_presets_motion(name: str, bow_range: tuple[float, float]) -> None:
    config = preset(name)
    reached: list[float] = []
    trajectory = solve_trajectory(config, reached.append)
    assert trajectory.times_s[0] == 0.0 and trajectory.times_s[-1] >= config.duration_s
    assert trajectory.length_m == config.rope.length_m and trajectory.n_elements == config.solver.elements
    assert reached and reached[-1] <= trajectory.times_s[-1] + 1e-9
    bow, bend_deg = _curl(trajectory)
    assert bow_range[0] <= bow <= bow_range[1], f"{name}: bows {bow:.3f} L"
    if name.endswith("soft"):
        assert bend_deg > 45, f"{name}: ends only {bend_deg:.0f} degrees apart"
    # The fixed end stays at the plane origin, the tip starts at (L, 0).
    np.testing.assert_allclose(trajectory.sample_positions([0.0])[:, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(trajectory.tip()[0], [config.rope.length_m, 0.0], atol=1e-9)


def test_simulate_solves_the_model(tmp_path: Path) -> None:
    out = tmp_path / "rig"
    assert main(["simulate", "rig", "--out", str(out), "--frames", "2", "--first-exposure-ms", "200", "-q"]) == 0
    frames = FrameSet(out)
    truth = frames.truth()
    assert len(frames) == 2 and truth is not None
    motion = Trajectory.load(out / "trajectory.npz")
    assert motion.times_s[-1] >= truth["t_end_ns"][-1] * 1e-9
    assert truth["t_begin_ns"][0] == 200_000_000
    # The metadata records the model configuration as run: the [rope] and [solver] of `ropecam model simulate`.
    rig = frames.meta["rig"]
    assert rig["trajectory_source"] == "ANCF model"
    assert from_mapping(RopeConfig, rig["model"]["rope"]) == preset("rig").rope
    solver = from_mapping(SolverConfig, rig["model"]["solver"])
    assert solver == dataclasses.replace(preset("rig").solver, duration_s=solver.duration_s)
    assert solver.duration_s == pytest.approx(motion.times_s[-1])


def test_model_features_reach_the_model(tiny: Callable[..., SimConfig]) -> None:
    """Clamped end, support motion, drag and damping go to the ANCF model unchanged; only the duration grows."""
    motion = FixedEndMotion(amplitude_x_m=0.01, frequency_hz=3.0)
    rope = RopeConfig(length_m=0.411, diameter_m=0.001, ei_nm2=1e-4, fixed_end="clamped", angle_deg=10.0,
                      drag_coefficient=1.122, mass_damping_per_s=0.5, material_damping_s=1e-3,
                      fixed_end_motion=motion)  # fmt: skip
    solver = SolverConfig(elements=4, step_s=1e-3, duration_s=0.01, output_every_s=2e-3, spectral_radius=0.8)
    config = tiny(rope=rope, solver=solver)
    run = config.model_solver()
    assert run == dataclasses.replace(solver, duration_s=run.duration_s)
    trajectory = solve_trajectory(config)
    assert trajectory.times_s[-1] >= config.duration_s + 2 * solver.output_every_s - 1e-9
    np.testing.assert_array_equal(trajectory.q, simulate(rope, run).q)
    # The support moves and the clamped end keeps its initial direction.
    fixed = trajectory.sample_positions([0.0])[:, 0]
    np.testing.assert_allclose(fixed[:, 0], 0.01 * np.sin(2 * np.pi * 3.0 * trajectory.times_s), atol=1e-9)
    slope = trajectory.q[:, 2:4] / np.linalg.norm(trajectory.q[:, 2:4], axis=1, keepdims=True)
    np.testing.assert_allclose(slope, np.tile([np.cos(np.radians(10)), np.sin(np.radians(10))], (len(slope), 1)),
                               atol=1e-9)  # fmt: skip
    plain = solve_trajectory(tiny(rope=RopeConfig(length_m=0.411, diameter_m=0.001, ei_nm2=1e-4, angle_deg=10.0),
                                  solver=solver))  # fmt: skip
    assert np.abs(plain.tip() - trajectory.tip()).max() > 1e-3


def test_solver_duration_is_a_minimum(tiny: Callable[..., SimConfig]) -> None:
    short = tiny(solver=SolverConfig(elements=4, duration_s=0.01))
    assert short.model_solver().duration_s == pytest.approx(
        np.ceil(short.duration_s / 1e-3 + 1e-9) * 1e-3 + 2e-3, abs=1e-12
    )
    long = tiny(solver=SolverConfig(elements=4, duration_s=0.5))
    assert long.model_solver() == long.solver
