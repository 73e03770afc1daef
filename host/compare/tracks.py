"""Measured material-point tracks in metres and their comparison with a model trajectory."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ropecam.host.model.trajectory import Trajectory

__all__ = ["MaterialPointTracks", "PointErrors", "model_positions", "model_velocities", "point_errors"]


@dataclass(frozen=True)
class MaterialPointTracks:
    """Positions of material points measured over time, in the plane frame (metres, y down).

    Parameters
    ----------
    times_s
        Measurement times on the device clock, shape (M,) (two per frame: exposure start and end).
    s_m
        Arc lengths of the tracked points along the unstretched rope, shape (K,).
    positions_m
        Shape (M, K, 2); NaN where a point was not measured.
    frames
        Optional, shape (M,): the frame number each sample belongs to (default -1: unknown).
    in_frame_velocities_m_s
        Optional, shape (M, K, 2): each point's velocity measured within the sample's frame, its displacement from
        the rope at the start to the rope at the end of the exposure over the time between the two (both samples
        of a frame carry it); NaN where either shape misses the point (default: all NaN).
    mid_exposure_s
        Optional, shape (M,) or (M, K): the time each in-frame velocity belongs to, the middle between the point's
        two times (with a global shutter the middle of the exposure); default `times_s`. Stored as (M, K).
    point_times_s
        Optional, shape (M, K): when each point of each sample was seen. A rolling shutter exposes row r
        ``r / height * readout`` after row 0, so the points of one shape have their own times (docs/compare.md,
        "Rolling shutter"); default: `times_s` for every point (a global shutter). The model is evaluated there.
    exposure_end
        Optional, shape (M,): True where the sample is the rope at the end of its frame's exposure; default: the
        samples after their (M,) `mid_exposure_s`.
    """

    times_s: NDArray[np.float64]
    s_m: NDArray[np.float64]
    positions_m: NDArray[np.float64]
    frames: NDArray[np.int64] | None = None
    in_frame_velocities_m_s: NDArray[np.float64] | None = None
    mid_exposure_s: NDArray[np.float64] | None = None
    point_times_s: NDArray[np.float64] | None = None
    exposure_end: NDArray[np.bool_] | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.times_s, dtype=np.float64)
        s = np.asarray(self.s_m, dtype=np.float64)
        p = np.asarray(self.positions_m, dtype=np.float64)
        if t.ndim != 1 or s.ndim != 1 or p.shape != (t.size, s.size, 2):
            raise ValueError(f"positions_m must have shape (M={t.size}, K={s.size}, 2), got {p.shape}")
        if not np.all(np.isfinite(t)) or not np.all(np.isfinite(s)) or np.any(s < 0):
            raise ValueError("times_s and s_m must be finite, and s_m >= 0")
        frames = np.full(t.size, -1, np.int64) if self.frames is None else np.asarray(self.frames, dtype=np.int64)
        velocities = np.full(p.shape, np.nan) if self.in_frame_velocities_m_s is None else self.in_frame_velocities_m_s
        velocities = np.asarray(velocities, dtype=np.float64)
        mid = t if self.mid_exposure_s is None else np.asarray(self.mid_exposure_s, dtype=np.float64)
        if frames.shape != t.shape or velocities.shape != p.shape or mid.shape not in (t.shape, p.shape[:2]):
            raise ValueError(
                f"frames must have shape ({t.size},), mid_exposure_s ({t.size},) or ({t.size}, {s.size}), "
                f"in_frame_velocities_m_s {p.shape}; got {frames.shape}, {mid.shape}, {velocities.shape}"
            )
        if self.exposure_end is not None:
            ends = np.asarray(self.exposure_end, dtype=bool)
        else:
            ends = t > (mid if mid.ndim == 1 else mid.min(axis=1))
        if ends.shape != t.shape:
            raise ValueError(f"exposure_end must have shape ({t.size},), got {ends.shape}")
        mid = np.repeat(mid[:, None], s.size, axis=1) if mid.ndim == 1 else mid
        point_t = np.repeat(t[:, None], s.size, axis=1) if self.point_times_s is None else self.point_times_s
        point_t = np.asarray(point_t, dtype=np.float64)
        if point_t.shape != (t.size, s.size) or not np.all(np.isfinite(point_t)):
            raise ValueError(f"point_times_s must be finite with shape ({t.size}, {s.size}), got {point_t.shape}")
        order = np.argsort(t, kind="stable")
        object.__setattr__(self, "point_times_s", point_t[order])
        object.__setattr__(self, "times_s", t[order])
        object.__setattr__(self, "s_m", s)
        object.__setattr__(self, "positions_m", p[order])
        object.__setattr__(self, "frames", frames[order])
        object.__setattr__(self, "in_frame_velocities_m_s", velocities[order])
        object.__setattr__(self, "mid_exposure_s", mid[order])
        object.__setattr__(self, "exposure_end", ends[order])

    @property
    def last_time_s(self) -> float:
        """The latest time any point was seen (a rolling shutter's lowest rows come after the samples' times)."""
        assert self.point_times_s is not None  # set by __post_init__
        return float(max(self.times_s[-1], self.point_times_s.max()))

    @property
    def measured(self) -> NDArray[np.bool_]:
        """Mask (M, K) of measured samples."""
        return np.all(np.isfinite(self.positions_m), axis=-1)


def model_positions(trajectory: Trajectory, tracks: MaterialPointTracks, release_time_s: float) -> NDArray[np.float64]:
    """Evaluate the model at the tracks' arc lengths, each point at its own time (`point_times_s`: a rolling
    shutter sees each row at its own time); shape (M, K, 2).

    Model time is ``t - release_time_s``; before the release the rope is in its initial state.
    """
    point_t = tracks.point_times_s
    assert point_t is not None  # set by __post_init__
    if np.any(point_t - release_time_s > trajectory.times_s[-1] + 1e-9):
        raise ValueError("the model trajectory ends before the last measurement")
    model_t = np.clip(point_t - release_time_s, trajectory.times_s[0], trajectory.times_s[-1])
    if np.array_equal(point_t, np.repeat(tracks.times_s[:, None], tracks.s_m.size, axis=1)):
        return trajectory.positions(model_t[:, 0], tracks.s_m)  # a global shutter: one time per sample
    out = np.empty((*point_t.shape, 2))
    for k in range(tracks.s_m.size):
        out[:, k] = trajectory.positions(model_t[:, k], tracks.s_m[k : k + 1])[:, 0]
    return out


def model_velocities(trajectory: Trajectory, tracks: MaterialPointTracks, release_time_s: float) -> NDArray[np.float64]:
    """Evaluate the model's velocity (m/s) of each point at its in-frame velocity's time (`mid_exposure_s`: the
    middle between the point's two times, with a global shutter mid-exposure); shape (M, K, 2).

    This is what an in-frame velocity (displacement over the time between the two shapes) measures to second order
    in that time. Before the release the model rests (zero velocity).
    """
    mid = tracks.mid_exposure_s
    assert mid is not None  # set by __post_init__
    model_t = np.clip(mid - release_time_s, trajectory.times_s[0], trajectory.times_s[-1])
    if np.all(mid == mid[:, :1]):  # one time per sample (a global shutter)
        velocities = trajectory.velocities(model_t[:, 0], tracks.s_m)
    else:
        velocities = np.empty((*mid.shape, 2))
        for k in range(tracks.s_m.size):
            velocities[:, k] = trajectory.velocities(model_t[:, k], tracks.s_m[k : k + 1])[:, 0]
    velocities[mid - release_time_s < trajectory.times_s[0]] = 0.0
    return velocities


@dataclass(frozen=True)
class PointErrors:
    """Position error of each material point: RMS and max over time (m), and the error series (M, K)."""

    s_m: NDArray[np.float64]
    rms_m: NDArray[np.float64]
    max_m: NDArray[np.float64]
    error_m: NDArray[np.float64]

    @property
    def overall_rms_m(self) -> float:
        """RMS over all measured samples of all points."""
        values = self.error_m[np.isfinite(self.error_m)]
        return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def point_errors(tracks: MaterialPointTracks, modelled_m: NDArray[np.float64]) -> PointErrors:
    """Compare measured and modelled positions (M, K, 2) point by point."""
    error = np.linalg.norm(tracks.positions_m - modelled_m, axis=-1)  # NaN where not measured
    with np.errstate(invalid="ignore"):
        counts = np.sum(np.isfinite(error), axis=0)
        rms = np.sqrt(np.nansum(error**2, axis=0) / np.maximum(counts, 1))
        worst = np.where(counts > 0, np.nanmax(np.where(np.isfinite(error), error, -np.inf), axis=0), np.nan)
    rms[counts == 0] = np.nan
    return PointErrors(tracks.s_m, rms, worst, error)
