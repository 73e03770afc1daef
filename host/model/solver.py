"""Simulate an ANCF rope: set up the model from its configuration and integrate it in time.

`simulate` is the entry point: a straight rope at rest (or rotating rigidly) at `RopeConfig.angle_deg`, released at
t = 0, integrated with generalized-alpha (Arnold & Bruls 2007; the form Exudyn uses) and a full Newton method with
the analytic tangent and a banded LU. The time loop runs compiled, in chunks between which progress is reported.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ropecam.host.model import _kernels as k
from ropecam.host.model.config import RopeConfig, SolverConfig
from ropecam.host.model.trajectory import DOF_PER_NODE, Trajectory
from ropecam.shared.errors import ModelError
from ropecam.shared.jit import KernelStatus

__all__ = ["CableModel", "SimulationStats", "generalized_alpha_coefficients", "simulate"]

ENERGY_NAMES = ("kinetic", "gravity", "axial", "bending")


def generalized_alpha_coefficients(spectral_radius: float) -> tuple[float, float, float, float]:
    """Return (alpha_m, alpha_f, gamma, beta) of generalized-alpha for the spectral radius rho_inf in [0, 1]."""
    rho = spectral_radius
    alpha_m = (2.0 * rho - 1.0) / (rho + 1.0)
    alpha_f = rho / (rho + 1.0)
    gamma = 0.5 + alpha_f - alpha_m
    beta = 0.25 * (gamma + 0.5) ** 2
    return alpha_m, alpha_f, gamma, beta


@dataclass(frozen=True, slots=True)
class SimulationStats:
    """What a run cost: wall time of the integration, steps, Newton iterations, steps retried smaller."""

    solve_time_s: float
    steps: int
    newton_iterations: int
    refined_steps: int


class CableModel:
    """An ANCF rope ready to integrate: parameters, constant matrices and work buffers.

    Parameters
    ----------
    rope
        The rope and its environment.
    solver
        Discretisation and integrator settings.
    """

    def __init__(self, rope: RopeConfig, solver: SolverConfig) -> None:
        self.rope = rope
        self.solver = solver
        n_el = solver.elements
        self.n_dof = DOF_PER_NODE * (n_el + 1)
        self.element_length_m = rope.length_m / n_el
        self.params = self._parameters(solver.step_s)
        self._scratch = np.zeros((k.N_SCRATCH, 8))
        self._mats = np.zeros((3, 8, 8))
        self.mass_band = np.zeros((self.n_dof, k.BAND_WIDTH))
        k.assemble_mass(rope.mass_per_length_kg_m, self.element_length_m, self._scratch, self.mass_band)
        self.gravity = np.zeros(self.n_dof)
        k.assemble_gravity(
            rope.mass_per_length_kg_m * rope.gravity_m_s2, self.element_length_m, self._scratch, self.gravity
        )
        self._band = np.zeros((self.n_dof, k.BAND_WIDTH))
        self._res = np.zeros(self.n_dof)
        self._delta = np.zeros(self.n_dof)
        self._pivots = np.zeros(self.n_dof, dtype=np.int32)
        self._backup = np.zeros((2, self.n_dof))
        self._counters = np.zeros(k.N_COUNTERS, dtype=np.int32)
        # Work space of `advance`, in its argument order.
        self._work = (self._band, self._res, self._delta, self._pivots, self._scratch, self._mats, self._backup)

    def _parameters(self, step_s: float) -> NDArray[np.float64]:
        rope, solver = self.rope, self.solver
        alpha_m, alpha_f, gamma, beta = generalized_alpha_coefficients(solver.spectral_radius)
        angle = math.radians(rope.angle_deg)
        motion = rope.fixed_end_motion
        p = np.zeros(k.N_PARAMS)
        p[k.P_EA] = rope.axial_stiffness_n
        p[k.P_EI] = rope.bending_stiffness_nm2
        p[k.P_RHOA] = rope.mass_per_length_kg_m
        p[k.P_GRAVITY] = rope.gravity_m_s2
        p[k.P_LE] = self.element_length_m
        p[k.P_DRAG] = 0.5 * rope.air_density_kg_m3 * rope.drag_coefficient * rope.diameter_m
        p[k.P_MASS_DAMPING] = rope.mass_damping_per_s
        p[k.P_MATERIAL_DAMPING] = rope.material_damping_s
        p[k.P_ALPHA_M], p[k.P_ALPHA_F], p[k.P_GAMMA], p[k.P_BETA] = alpha_m, alpha_f, gamma, beta
        p[k.P_STEP] = step_s
        p[k.P_TOLERANCE] = solver.newton_tolerance_m
        p[k.P_MAX_ITERATIONS] = solver.max_iterations
        p[k.P_CLAMPED] = 1.0 if rope.fixed_end == "clamped" else 0.0
        if motion.active:
            p[k.P_AMPLITUDE_X] = motion.amplitude_x_m
            p[k.P_AMPLITUDE_Y] = motion.amplitude_y_m
            p[k.P_OMEGA] = 2.0 * math.pi * motion.frequency_hz
            p[k.P_PHASE] = motion.phase_rad
        p[k.P_SLOPE_X] = math.cos(angle)
        p[k.P_SLOPE_Y] = math.sin(angle)
        return p

    def initial_state(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return (q0, v0): the straight rope along `angle_deg`, rotating rigidly at the initial rate."""
        rope = self.rope
        angle = math.radians(rope.angle_deg)
        direction = np.array([math.cos(angle), math.sin(angle)])
        normal = np.array([-math.sin(angle), math.cos(angle)])
        omega = rope.initial_angular_velocity_rad_s
        s = np.arange(self.solver.elements + 1) * self.element_length_m
        q = np.zeros((s.size, DOF_PER_NODE))
        v = np.zeros((s.size, DOF_PER_NODE))
        q[:, 0:2] = s[:, None] * direction
        q[:, 2:4] = direction
        v[:, 0:2] = omega * s[:, None] * normal
        v[:, 2:4] = omega * normal
        q, v = q.ravel(), v.ravel()
        origin_q, origin_v = q.copy(), v.copy()
        k.prescribe_fixed_end(self.params, 0.0, origin_q, origin_v, self._scratch[k.S_CV])
        q[:2] += origin_q[:2]  # a moving support starts where its motion puts it at t = 0
        v[:2] = origin_v[:2]
        v[DOF_PER_NODE::DOF_PER_NODE] += origin_v[0]
        v[DOF_PER_NODE + 1 :: DOF_PER_NODE] += origin_v[1]
        q[DOF_PER_NODE::DOF_PER_NODE] += origin_q[0]
        q[DOF_PER_NODE + 1 :: DOF_PER_NODE] += origin_q[1]
        return q, v

    def initial_acceleration(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Solve ``M qdd = f_ext - f_int - f_damp`` at t = 0 (constrained entries prescribed)."""
        qdd = np.zeros(self.n_dof)
        k.assemble_system(self.params, self.mass_band, self.gravity, q, v, qdd, 1.0, 0.0, 0, self._scratch,
                          self._mats, self._res, self._band)  # fmt: skip
        # With qdd = 0 the residual is minus the net force; the matrix is the mass matrix.
        self._band[:] = 0.0
        self._band[:, : self.mass_band.shape[1]] = self.mass_band
        n_constrained = 4 if self.rope.fixed_end == "clamped" else 2
        for i in range(n_constrained):
            self._band[i, :] = 0.0
            self._band[i, k.KL] = 1.0
            for r in range(n_constrained, min(i + k.KL, self.n_dof - 1) + 1):
                self._band[r, i - r + k.KL] = 0.0
        if k.band_factor(self._band, self._pivots) < 0:
            raise ModelError("the mass matrix is singular (check length, density and element count)")
        rhs = -self._res
        k.band_solve(self._band, self._pivots, rhs)
        prescribed = np.zeros(self.n_dof)
        k.prescribe_fixed_end(self.params, 0.0, prescribed.copy(), prescribed.copy(), self._scratch[k.S_CV])
        rhs[:n_constrained] = self._scratch[k.S_CV, :n_constrained]
        return rhs

    def energies(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Return kinetic, gravity, axial and bending energy (J) per state row, plus their total."""
        out = np.zeros((q.shape[0], 4))
        k.energies(self.params, np.ascontiguousarray(q), np.ascontiguousarray(v), self._scratch, out)
        result = {name: out[:, i].copy() for i, name in enumerate(ENERGY_NAMES)}
        result["total"] = out.sum(axis=1)
        return result

    def run(self, progress: Callable[[float], None] | None = None) -> tuple[Trajectory, SimulationStats]:
        """Integrate from t = 0 to `duration_s`; returns the sampled trajectory and run statistics.

        Parameters
        ----------
        progress
            Called with the simulated time reached (s) after each chunk.

        Raises
        ------
        ModelError
            Newton fails at a step even after refinement (or refinement is off); the message gives the time.
        """
        solver = self.solver
        every = solver.steps_per_output
        total = solver.total_steps
        n_samples = total // every + 1
        if total % every:
            raise ModelError("internal error: total steps must be a multiple of the output spacing")
        out_t = np.zeros(n_samples)
        out_q = np.zeros((n_samples, self.n_dof))
        out_v = np.zeros((n_samples, self.n_dof))
        q, v = self.initial_state()
        qdd = self.initial_acceleration(q, v)
        acc = qdd.copy()
        out_q[0], out_v[0] = q, v
        written = 1
        steps_done = 0
        iterations = 0
        refined = 0
        chunk = every * max(1, round(0.05 / (every * solver.step_s)))  # about 50 ms of rope time per call
        start = time.perf_counter()
        while steps_done < total:
            n_steps = min(chunk, total - steps_done)
            t0 = steps_done * solver.step_s
            status = k.advance(
                q, v, qdd, acc, t0, steps_done, n_steps, every, self.params, self.mass_band, self.gravity,
                *self._work, out_t[written:], out_q[written:], out_v[written:], self._counters,
            )  # fmt: skip
            done = int(self._counters[k.C_STEPS])
            written += int(self._counters[k.C_SAMPLES])
            iterations += int(self._counters[k.C_ITERATIONS])
            steps_done += done
            if status == KernelStatus.FULL:
                raise ModelError("internal error: trajectory buffer too short")
            if status < 0:
                t_fail = (steps_done + 1) * solver.step_s
                if not solver.adaptive or status == KernelStatus.SINGULAR:
                    raise ModelError(
                        f"Newton did not converge at t = {t_fail:.6g} s (status {KernelStatus(status).name}); "
                        "try a smaller step_s, more elements or adaptive = true"
                    )
                self._refine_step(q, v, qdd, acc, steps_done * solver.step_s, t_fail)
                refined += 1
                steps_done += 1
                if steps_done % every == 0:
                    out_t[written], out_q[written], out_v[written] = steps_done * solver.step_s, q, v
                    written += 1
            if progress is not None:
                progress(min(steps_done * solver.step_s, solver.duration_s))
        solve_time = time.perf_counter() - start
        out_t, out_q, out_v = out_t[:written], out_q[:written], out_v[:written]
        trajectory = Trajectory(self.rope.length_m, out_t, out_q, out_v, energies=self.energies(out_q, out_v))
        return trajectory, SimulationStats(solve_time, steps_done, iterations, refined)

    def _refine_step(self, q, v, qdd, acc, t0: float, t_fail: float) -> None:  # type: ignore[no-untyped-def]
        """Cover one failed step with 2, 4, ... 64 smaller steps; raise `ModelError` if even that fails."""
        saved = (q.copy(), v.copy(), qdd.copy(), acc.copy())
        dummy_t = np.zeros(1)
        dummy = np.zeros((1, self.n_dof))
        for level in range(1, 7):
            parts = 2**level
            self.params = self._parameters(self.solver.step_s / parts)
            status = k.advance(
                q, v, qdd, acc, t0, 0, parts, parts + 1, self.params, self.mass_band, self.gravity,
                *self._work, dummy_t, dummy, dummy, self._counters,
            )  # fmt: skip
            self.params = self._parameters(self.solver.step_s)
            if status >= 0:
                return
            for target, source in zip((q, v, qdd, acc), saved, strict=True):
                target[:] = source
        raise ModelError(f"Newton did not converge at t = {t_fail:.6g} s even with step_s / 64")


def simulate(rope: RopeConfig, solver: SolverConfig, progress: Callable[[float], None] | None = None) -> Trajectory:
    """Simulate `rope` with `solver` and return its trajectory (energies included).

    Parameters
    ----------
    rope, solver
        Model and integrator configuration.
    progress
        Optional callback with the simulated time reached (s), called every ~50 ms of rope time.

    Raises
    ------
    ModelError
        The integration fails (see `CableModel.run`).
    """
    trajectory, _ = CableModel(rope, solver).run(progress)
    return trajectory
