"""The release-time fit shared by `ropecam compare` and `ropecam replay --model`: tracks, t0 by least squares, model.

Both commands go through `fit_release`, so the same frames give the same release time, model run and errors.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ropecam.host.compare.measurement import default_points, tracks_from_frames
from ropecam.shared.errors import DataError

if TYPE_CHECKING:
    from ropecam.host.calibration.geometry import CameraModel, PlanePose
    from ropecam.host.compare.identify import FitResult
    from ropecam.host.compare.measurement import MeasuredFrame
    from ropecam.host.compare.tracks import MaterialPointTracks, PointErrors
    from ropecam.host.model.config import RopeConfig, SolverConfig
    from ropecam.host.model.trajectory import Trajectory

__all__ = ["ReleaseFit", "default_points", "fit_release"]


@dataclass(frozen=True)
class ReleaseFit:
    """The model aligned with a measurement: material-point tracks, the t0 fit, the model run and its errors."""

    tracks: MaterialPointTracks
    fit: FitResult
    trajectory: Trajectory
    errors: PointErrors
    skipped: tuple[str, ...] = ()
    """Shapes left out because they miss the motion plane (one line each, naming the frame)."""

    @property
    def release_time_s(self) -> float:
        """Fitted release time on the measurement (device) clock, s."""
        return self.fit.release_time_s


def fit_release(
    frames: Sequence[MeasuredFrame],
    calibration: tuple[CameraModel, PlanePose],
    rope: RopeConfig,
    solver: SolverConfig,
    points_m: Sequence[float] | None = None,
    release_time_s: float | None = None,
    progress: Callable[[int, float], None] | None = None,
    label: str = "the measurement",
) -> ReleaseFit:
    """Fit the model's release time to measured frames and run the model from it over the whole measurement.

    Parameters
    ----------
    frames
        Measured shapes in pixels (non-OK frames and missing shapes count as unmeasured).
    calibration
        (camera, plane pose): pixels to metres on the plane.
    rope, solver
        The model.
    points_m
        Material points (unstretched arc lengths, m); default `default_points`.
    release_time_s
        Start value of the fit (device clock, s); default: the first measured sample.
    progress
        Called with (model evaluations, RMS error m) during the fit.
    label
        Names the measurement in error messages.

    Raises
    ------
    DataError
        No frame has a measured rope shape, or most shapes do not map onto the plane.
    ConfigError
        A material point outside the rope.
    ModelError
        The model cannot be simulated.
    """
    from ropecam.host.compare.identify import fit_parameters, model_for_tracks
    from ropecam.host.compare.tracks import model_positions, point_errors

    points = list(points_m) if points_m else default_points(rope.length_m)
    if not frames:
        raise DataError(f"{label} holds no frames: nothing to compare with the model")
    skipped: list[str] = []
    tracks, _ = tracks_from_frames(frames, *calibration, points, rope.length_m, skipped)
    measured = tracks.measured.any(axis=1)
    if not measured.any():
        raise DataError(f"{label}: no frame has a measured rope shape (status OK): nothing to compare")
    start = release_time_s if release_time_s is not None else float(tracks.times_s[measured][0])
    fit = fit_parameters(tracks, rope, solver, names=("t0",), release_time_s=start, progress=progress)
    trajectory = model_for_tracks(fit.rope, solver, tracks, fit.release_time_s)
    errors = point_errors(tracks, model_positions(trajectory, tracks, fit.release_time_s))
    return ReleaseFit(tracks, fit, trajectory, errors, tuple(skipped))
