"""The ANCF cable model: 2D gradient-deficient cable elements, generalized-alpha time integration."""

from ropecam.host.model.config import FixedEndMotion, RopeConfig, SolverConfig
from ropecam.host.model.solver import CableModel, SimulationStats, simulate
from ropecam.host.model.trajectory import Trajectory

__all__ = ["CableModel", "FixedEndMotion", "RopeConfig", "SimulationStats", "SolverConfig", "Trajectory", "simulate"]
