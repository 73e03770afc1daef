"""Exposure timing per image row: the rolling shutter's row weights and ground truth, and lamp flicker.

A rolling shutter starts row r's exposure ``readout_s * r / H`` after row 0's (`row_offsets_s`): `readout_s` is
the sensor's frame readout time, H line times (the convention of sensor datasheets, and the device's and host's
``readout_ns``), so row 0 starts at the frame's exposure start and the last row ``readout_s * (H - 1) / H`` later;
every row is exposed for the same time. The renderer
samples the rope at sub-frame times spanning all rows' exposures and gives each sub-frame, per row, the integral of
its linear-interpolation hat function over that row's exposure divided by the exposure time (`row_weights`), so
each row is the time average of the rope over its own exposure. With no readout every row gets the trapezoidal
weights of a global shutter.

The ground truth of a rolling-shutter frame (`rolling_centreline`) is the rope as the image shows it: each material
point at the instant its own row's exposure starts (or ends), solved as the fixed point ``t = t0 + offset(v(s, t))``
(v the point's image row), which converges because the rope moves across rows far slower than the shutter sweeps
them.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose, plane_to_pixels
from ropecam.host.model.trajectory import Trajectory, hermite_shape

__all__ = ["flicker_gain", "positions_at", "rolling_centreline", "row_offsets_s", "row_weights"]

FIXED_POINT_TOLERANCE_S = 1e-10
"""The rolling-shutter truth's instants are solved to this (a rope point moves below 1e-6 px in it)."""
FIXED_POINT_ITERATIONS = 60


def row_offsets_s(height_px: int, readout_s: float) -> NDArray[np.float64]:
    """Return (H,) exposure-start offsets of the image rows from row 0's, seconds (zeros for a global shutter)."""
    if height_px < 2:
        raise ValueError(f"height_px must be >= 2, got {height_px}")
    return readout_s * np.arange(height_px, dtype=np.float64) / height_px


def _hat_integral(x: NDArray[np.float64], h: float) -> NDArray[np.float64]:
    """Integral from -inf to x of the hat max(0, 1 - |y| / h)."""
    x = np.clip(x, -h, h)
    left = (x + h) ** 2 / (2 * h)
    right = h - (h - x) ** 2 / (2 * h)
    return np.where(x <= 0, left, right)


def row_weights(
    times_s: NDArray[np.float64], row_begin_s: NDArray[np.float64], exposure_s: float
) -> NDArray[np.float64]:
    """Return (K, H) weights of K uniformly spaced sub-frames for rows exposed from `row_begin_s` for `exposure_s`.

    Parameters
    ----------
    times_s
        (K,) sub-frame times, uniformly spaced, covering every row's exposure.
    row_begin_s
        (H,) exposure start of each row, seconds.
    exposure_s
        Exposure time, seconds (0: each row is the rope at its own start instant).

    Returns
    -------
    ndarray
        Weights such that ``sum_k w[k, r] f(times[k])`` is the time average over row r's exposure of the linear
        interpolation of f between the sub-frames; every column sums to 1.
    """
    times = np.asarray(times_s, dtype=np.float64)
    begin = np.asarray(row_begin_s, dtype=np.float64)
    if times.size == 1:
        return np.ones((1, begin.size))
    h = float(times[1] - times[0])
    if exposure_s == 0:
        return np.maximum(0.0, 1.0 - np.abs(begin[None, :] - times[:, None]) / h)
    end = begin + exposure_s
    weights = _hat_integral(end[None, :] - times[:, None], h) - _hat_integral(begin[None, :] - times[:, None], h)
    # The first and last sub-frames' hats are halves: the windows lie inside [times[0], times[-1]].
    return weights / exposure_s


def positions_at(trajectory: Trajectory, t_s: NDArray[np.float64], s_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return (S, 2) positions (metres) of material points `s_m` each at its own time `t_s` (both (S,)).

    The same interpolation as `Trajectory.positions` (cubic Hermite in time, the ANCF element's cubic in space),
    evaluated once per (time, point) pair instead of on the grid of all times by all points.
    """
    # Trajectory has no public pairwise evaluation; its time interpolation (`_state_at`) is reused as it is.
    q, _ = trajectory._state_at(t_s)
    le = trajectory.element_length_m
    element = np.clip(np.floor(s_m / le).astype(np.intp), 0, trajectory.n_elements - 1)
    shape = hermite_shape(np.clip(s_m / le - element, 0.0, 1.0), le)
    nodes = q.reshape(s_m.size, trajectory.n_elements + 1, 4)
    rows = np.arange(s_m.size)
    left, right = nodes[rows, element], nodes[rows, element + 1]
    x = shape[:, 0] * left[:, 0] + shape[:, 1] * left[:, 2] + shape[:, 2] * right[:, 0] + shape[:, 3] * right[:, 2]
    y = shape[:, 0] * left[:, 1] + shape[:, 1] * left[:, 3] + shape[:, 2] * right[:, 1] + shape[:, 3] * right[:, 3]
    return np.stack([x, y], axis=-1)


def rolling_centreline(
    trajectory: Trajectory,
    s_m: NDArray[np.float64],
    camera: CameraModel,
    plane: PlanePose,
    t0_s: float,
    readout_s: float,
    height_px: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return the rope as a rolling shutter sees it: each point at ``t0_s`` plus its own row's offset.

    Parameters
    ----------
    trajectory, s_m
        The motion and the material points (S,).
    camera, plane
        Projection to pixels.
    t0_s
        Row 0's instant (its exposure start, or end).
    readout_s, height_px
        The rolling shutter (`row_offsets_s`); a point's row is its v coordinate, clipped to the image.

    Returns
    -------
    points_m, points_px, times_s
        (S, 2) metres, (S, 2) distorted pixels and (S,) the instants.

    Raises
    ------
    ValueError
        The fixed point does not converge (the rope crosses rows about as fast as the shutter).
    """
    scale = readout_s / height_px
    times = np.full(s_m.size, t0_s)
    for _ in range(FIXED_POINT_ITERATIONS):
        points_m = positions_at(trajectory, times, s_m)
        points_px = plane_to_pixels(points_m, camera, plane)
        new_times = t0_s + scale * np.clip(points_px[:, 1], 0.0, height_px - 1)
        change = float(np.abs(new_times - times).max())
        times = new_times
        if change <= FIXED_POINT_TOLERANCE_S:
            points_m = positions_at(trajectory, times, s_m)
            return points_m, plane_to_pixels(points_m, camera, plane), times
    raise ValueError(
        f"the rolling-shutter instants did not converge in {FIXED_POINT_ITERATIONS} iterations (last change "
        f"{change:.3g} s): the rope moves across rows almost as fast as a {readout_s * 1e3:g} ms readout"
    )


def flicker_gain(
    row_begin_s: NDArray[np.float64], exposure_s: float, amplitude: float, frequency_hz: float
) -> NDArray[np.float32]:
    """Return (H, 1) illumination factors: the mean of ``1 + amplitude sin(2 pi f t)`` over each row's exposure.

    Parameters
    ----------
    row_begin_s
        (H,) exposure start of each row, seconds on the model's clock (t = 0 at the release).
    exposure_s
        Exposure time, seconds (0: the value at the start instant).
    amplitude, frequency_hz
        The lamps' relative modulation and its frequency (twice the mains frequency for a lamp on AC).
    """
    omega = 2.0 * math.pi * frequency_hz
    begin = np.asarray(row_begin_s, dtype=np.float64)
    if exposure_s == 0:
        mean = np.sin(omega * begin)
    else:
        mean = (np.cos(omega * begin) - np.cos(omega * (begin + exposure_s))) / (omega * exposure_s)
    return (1.0 + amplitude * mean).astype(np.float32)[:, None]
