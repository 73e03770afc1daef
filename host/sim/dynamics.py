"""Obtain the rope's motion for a simulation by solving the ANCF model.

The simulator never integrates rope dynamics itself; it calls the project's ANCF model (`ropecam.host.model`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import RopeSpec
from ropecam.shared.errors import ModelError

__all__ = ["solve_trajectory"]


def solve_trajectory(rope: RopeSpec, duration_s: float, progress: Callable[[float], None] | None = None) -> Trajectory:
    """Solve the ANCF model for `rope` from release (t = 0) to at least `duration_s`.

    Parameters
    ----------
    rope
        Rope and discretisation parameters.
    duration_s
        Model time needed, seconds; two output steps are added so the last exposure ends inside the trajectory.
    progress
        Called with the model time reached (seconds) while solving.

    Raises
    ------
    ModelError
        The model cannot be set up or solved.
    """
    from ropecam.host.model import RopeConfig, SolverConfig, simulate

    steps = math.ceil(duration_s / rope.output_every_s + 1e-9) + 2
    rope_config = RopeConfig(
        length_m=rope.length_m,
        diameter_m=rope.diameter_m,
        youngs_modulus_pa=rope.youngs_modulus_pa,
        density_kg_m3=rope.density_kg_m3,
        ei_nm2=rope.ei_nm2,
        angle_deg=rope.angle_deg,
        drag_coefficient=rope.drag_coefficient,
        gravity_m_s2=rope.gravity_m_s2,
    )
    solver = SolverConfig(
        elements=rope.elements,
        step_s=rope.step_s,
        duration_s=steps * rope.output_every_s,
        output_every_s=rope.output_every_s,
    )
    trajectory = simulate(rope_config, solver, progress)
    if not isinstance(trajectory, Trajectory):
        raise ModelError(f"the ANCF model returned {type(trajectory).__name__}, expected a Trajectory")
    return trajectory
