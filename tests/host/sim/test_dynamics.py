"""The presets' motion from the ANCF model: stiff ropes swing like rods, the soft variants visibly curl."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.cli import main
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.dynamics import solve_trajectory
from ropecam.host.sim.presets import preset


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
    trajectory = solve_trajectory(config.rope, config.duration_s, reached.append)
    assert trajectory.times_s[0] == 0.0 and trajectory.times_s[-1] >= config.duration_s
    assert trajectory.length_m == config.rope.length_m and trajectory.n_elements == config.rope.elements
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
