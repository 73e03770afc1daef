"""Obtain the rope's motion for a simulation by solving the ANCF model.

The simulator never integrates rope dynamics itself; it calls the project's ANCF model (`ropecam.host.model`) with
the configuration's own `RopeConfig` and `SolverConfig`.
"""

from __future__ import annotations

from collections.abc import Callable

from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import SimConfig

__all__ = ["solve_trajectory"]


def solve_trajectory(config: SimConfig, progress: Callable[[float], None] | None = None) -> Trajectory:
    """Solve the ANCF model for `config.rope` from release (t = 0) until after the recording's last exposure.

    Parameters
    ----------
    config
        The simulation; its `rope` and `model_solver()` (``solver`` with `duration_s` extended to cover the last
        exposure plus two output samples) go to the model unchanged.
    progress
        Called with the model time reached (seconds) while solving.

    Returns
    -------
    Trajectory
        The rope's motion, from t = 0 to at least the end of the last exposure.

    Raises
    ------
    ModelError
        The model cannot be solved (e.g. Newton fails to converge for a very soft rope).
    """
    from ropecam.host.model import simulate

    return simulate(config.rope, config.model_solver(), progress)
