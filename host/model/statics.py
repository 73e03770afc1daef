"""Static equilibrium of a clamped rope (a cantilever) under gravity and a tip load, by Newton with load stepping."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.host.model import _kernels as k
from ropecam.host.model.config import RopeConfig, SolverConfig
from ropecam.host.model.solver import CableModel
from ropecam.host.model.trajectory import DOF_PER_NODE, Trajectory
from ropecam.shared.errors import ModelError

__all__ = ["solve_static"]


def solve_static(
    rope: RopeConfig,
    elements: int,
    tip_load_n: tuple[float, float] = (0.0, 0.0),
    load_steps: int = 20,
    tolerance_m: float = 1e-12,
    max_iterations: int = 50,
) -> Trajectory:
    """Return the equilibrium of a clamped rope under gravity and a tip force, as a one-sample trajectory.

    Parameters
    ----------
    rope
        The rope; `fixed_end` must be "clamped" (a pinned rope has no unique equilibrium). The clamp holds the
        slope along `angle_deg`.
    elements
        Number of elements N.
    tip_load_n
        Force (Fx, Fy) in N on the free tip, plane frame (y down).
    load_steps
        Gravity and tip load are applied in this many equal increments (large deflections need several).

    Raises
    ------
    ModelError
        The rope is not clamped, or Newton fails at a load step.
    """
    if rope.fixed_end != "clamped":
        raise ModelError(f"statics needs fixed_end = 'clamped', got {rope.fixed_end!r}")
    if load_steps < 1:
        raise ValueError(f"load_steps must be >= 1, got {load_steps}")
    model = CableModel(rope, SolverConfig(elements=elements, step_s=1.0, duration_s=1.0))
    q, _ = model.initial_state()
    v = np.zeros_like(q)
    qdd = np.zeros_like(q)
    load = model.gravity.copy()
    load[-DOF_PER_NODE] += tip_load_n[0]
    load[-DOF_PER_NODE + 1] += tip_load_n[1]
    res = np.zeros(model.n_dof)
    band = np.zeros((model.n_dof, k.BAND_WIDTH))
    pivots = np.zeros(model.n_dof, dtype=np.int32)
    scratch = np.zeros((k.N_SCRATCH, 8))
    mats = np.zeros((3, 8, 8))
    for step in range(1, load_steps + 1):
        applied = load * (step / load_steps)
        for _ in range(max_iterations):
            k.assemble_system(model.params, model.mass_band, applied, q, v, qdd, 0.0, 0.0, 1, scratch, mats, res,
                              band)  # fmt: skip
            if k.band_factor(band, pivots) < 0:
                raise ModelError(f"singular stiffness at load step {step}/{load_steps}")
            res *= -1.0
            k.band_solve(band, pivots, res)
            q += res
            if np.max(np.abs(res)) <= tolerance_m:
                break
        else:
            raise ModelError(f"static Newton did not converge at load step {step}/{load_steps}")
    return Trajectory(rope.length_m, np.zeros(1), q[None, :].copy(), np.zeros((1, q.size)))


def nodal_positions(trajectory: Trajectory) -> NDArray[np.float64]:
    """Return the nodes' (x, y) of the first sample, shape (N + 1, 2)."""
    return trajectory.q[0].reshape(-1, DOF_PER_NODE)[:, :2]
