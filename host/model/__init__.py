"""The ANCF cable model: 2D gradient-deficient cable elements, generalized-alpha time integration.

The solver (and its Numba kernels) loads on first use of `CableModel`, `SimulationStats` or `simulate`, so that
importing the configuration types stays cheap (command-line help, config validation).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ropecam.host.model.config import FixedEndMotion, RopeConfig, SolverConfig
from ropecam.host.model.trajectory import Trajectory

if TYPE_CHECKING:
    from ropecam.host.model.solver import CableModel, SimulationStats, simulate

__all__ = ["CableModel", "FixedEndMotion", "RopeConfig", "SimulationStats", "SolverConfig", "Trajectory", "simulate"]

_LAZY = {"CableModel", "SimulationStats", "simulate"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module("ropecam.host.model.solver"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
