"""Identify model parameters from measured material-point tracks by nonlinear least squares.

The parameters that can be fitted: ``ei`` (bending stiffness, fitted in log space), ``damping`` (Kelvin-Voigt
material damping time), ``drag`` (drag coefficient) and ``t0`` (the release time on the measurement clock). The
residuals are the position differences of every measured material point at every measured time. Each evaluation
of physical parameters runs the model once; changes of `t0` alone only re-sample the cached trajectory.
Uncertainties are the usual linearised ones: ``sigma^2 (J^T J)^-1`` with sigma^2 the residual variance.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ropecam.host.compare.tracks import MaterialPointTracks, model_positions
from ropecam.host.model.config import RopeConfig, SolverConfig
from ropecam.host.model.solver import CableModel
from ropecam.host.model.trajectory import Trajectory
from ropecam.shared.errors import ModelError

__all__ = ["FITTABLE", "FitResult", "fit_parameters", "model_for_tracks"]

FITTABLE = ("ei", "damping", "drag", "t0")
# Internal scaling: the optimiser works on (value - start) / scale (log for ei), all of order one.
_SCALE = {"ei": 1.0, "damping": 1e-4, "drag": 0.1, "t0": 1e-3}
_BOUNDS = {"ei": (-np.inf, np.inf), "damping": (0.0, 1.0), "drag": (0.0, 10.0), "t0": (-np.inf, np.inf)}


@dataclass(frozen=True)
class FitResult:
    """Outcome of an identification.

    `values` and `std_errors` are in physical units (ei: N m^2, damping: s, drag: -, t0: s).
    """

    names: tuple[str, ...]
    start: dict[str, float]
    values: dict[str, float]
    std_errors: dict[str, float]
    rms_before_m: float
    rms_after_m: float
    rope: RopeConfig
    release_time_s: float
    evaluations: int
    success: bool
    message: str


def model_for_tracks(
    rope: RopeConfig, solver: SolverConfig, tracks: MaterialPointTracks, release_time_s: float, margin_s: float = 0.05
) -> Trajectory:
    """Simulate the model from the release until `margin_s` after the last measurement (at least two steps)."""
    duration = max(float(tracks.times_s[-1] - release_time_s) + margin_s, 2 * solver.step_s)
    trajectory, _ = CableModel(rope, dataclasses.replace(solver, duration_s=duration)).run()
    return trajectory


def _physical(rope: RopeConfig, names: Sequence[str], values: dict[str, float]) -> RopeConfig:
    changes = {}
    if "ei" in names:
        changes["ei_nm2"] = values["ei"]
    if "damping" in names:
        changes["material_damping_s"] = values["damping"]
    if "drag" in names:
        changes["drag_coefficient"] = values["drag"]
    return dataclasses.replace(rope, **changes)


def fit_parameters(
    tracks: MaterialPointTracks,
    rope: RopeConfig,
    solver: SolverConfig,
    names: Sequence[str] = ("ei", "t0"),
    release_time_s: float = 0.0,
    progress: Callable[[int, float], None] | None = None,
    max_evaluations: int = 60,
) -> FitResult:
    """Fit `names` (a subset of FITTABLE) so the model matches `tracks`.

    Parameters
    ----------
    tracks
        Measured material points in metres (plane frame).
    rope, solver
        The model; the rope's fitted fields are start values (e.g. EI from the datasheet).
    names
        Parameters to fit.
    release_time_s
        Start value (or the fixed value, when "t0" is not fitted) of the release time on the measurement clock.
    progress
        Called with (model evaluations so far, current RMS error in m).
    max_evaluations
        Budget of model evaluations for the optimiser.

    Raises
    ------
    ValueError
        An unknown parameter name, or no measured sample.
    ModelError
        The model cannot be simulated at a start value.
    """
    from scipy.optimize import least_squares

    names = tuple(dict.fromkeys(names))
    unknown = [n for n in names if n not in FITTABLE]
    if unknown or not names:
        raise ValueError(f"parameters to fit must be among {', '.join(FITTABLE)}, got {', '.join(names) or 'none'}")
    mask = tracks.measured
    if not mask.any():
        raise ValueError("the tracks hold no measured sample")
    start = {
        "ei": rope.bending_stiffness_nm2,
        "damping": rope.material_damping_s,
        "drag": rope.drag_coefficient,
        "t0": release_time_s,
    }
    measured = tracks.positions_m[mask]
    cache: dict[tuple[float, ...], Trajectory] = {}
    evaluations = [0]
    earliest_t0 = min(release_time_s, float(tracks.times_s[0]))

    def decode(theta: NDArray[np.float64]) -> dict[str, float]:
        values = dict(start)
        for name, x in zip(names, theta, strict=True):
            values[name] = start[name] * math.exp(x) if name == "ei" else start[name] + x * _SCALE[name]
        return values

    def trajectory_for(values: dict[str, float]) -> Trajectory:
        key = tuple(round(values[n], 15) for n in ("ei", "damping", "drag"))
        needed = tracks.times_s[-1] - values["t0"]
        cached = cache.get(key)
        if cached is None or cached.times_s[-1] < needed:
            # Long enough for any release time down to the earliest plausible one, so t0 steps reuse it.
            cached = model_for_tracks(_physical(rope, names, values), solver, tracks, min(values["t0"], earliest_t0))
            cache.clear()  # keep memory bounded: finite differences revisit only the latest point
            cache[key] = cached
            evaluations[0] += 1
        return cached

    def residuals(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        values = decode(theta)
        modelled = model_positions(trajectory_for(values), tracks, values["t0"])
        diff = (modelled[mask] - measured).ravel()
        if progress is not None:
            progress(evaluations[0], float(np.sqrt(np.mean(diff**2) * 2)))
        return diff

    theta0 = np.zeros(len(names))
    lower = np.array([_bounds(n, start[n])[0] for n in names])
    upper = np.array([_bounds(n, start[n])[1] for n in names])
    try:
        r0 = residuals(theta0)
        result = least_squares(
            residuals, theta0, bounds=(lower, upper), diff_step=1e-3, x_scale=1.0, max_nfev=max_evaluations,
            xtol=1e-10, ftol=1e-12, gtol=1e-10,
        )  # fmt: skip
    except ModelError as exc:
        raise ModelError(f"identification stopped: the model failed ({exc})") from exc
    values = decode(result.x)
    dof = max(result.fun.size - len(names), 1)
    sigma2 = float(result.fun @ result.fun) / dof
    std_internal = _std_from_jacobian(result.jac, sigma2)
    std = {}
    for name, sd in zip(names, std_internal, strict=True):
        std[name] = values[name] * sd if name == "ei" else sd * _SCALE[name]
    fitted_rope = _physical(rope, names, values)
    return FitResult(
        names=names,
        start={n: start[n] for n in names},
        values={n: values[n] for n in names},
        std_errors=std,
        rms_before_m=float(np.sqrt(np.mean(r0**2) * 2)),
        rms_after_m=float(np.sqrt(np.mean(result.fun**2) * 2)),
        rope=fitted_rope,
        release_time_s=values["t0"],
        evaluations=evaluations[0],
        success=bool(result.success),
        message=str(result.message),
    )


def _bounds(name: str, start: float) -> tuple[float, float]:
    low, high = _BOUNDS[name]
    if name == "ei":
        return low, high
    return (low - start) / _SCALE[name], (high - start) / _SCALE[name]


def _std_from_jacobian(jacobian: NDArray[np.float64], sigma2: float) -> NDArray[np.float64]:
    jtj = jacobian.T @ jacobian
    try:
        covariance = np.linalg.inv(jtj) * sigma2
    except np.linalg.LinAlgError:
        return np.full(jacobian.shape[1], np.inf)
    return np.sqrt(np.clip(np.diag(covariance), 0.0, None))
