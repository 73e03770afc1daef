"""Render the rope's image over one exposure: projection, sub-frame choice and anti-aliased, motion-blurred coverage.

The rope is a band of its (rendered) diameter around the projected centreline, with flat ends. Its image is that band
convolved with a Gaussian of the total edge blur (lens PSF and the pixel's area as a box of variance 1/12), computed
in closed form from the distance to the centreline (`ropecam.host.sim._kernels`). Motion blur is the time average of
that image over the exposure, by the trapezoidal rule on sub-frames spaced so that no centreline point moves more
than `max_step_px` between two of them; the first and the last sub-frame are exactly the start and the end of the
exposure, which are the ground truth.

With a rolling shutter (`readout_s` > 0) each image row is exposed over its own interval, later the lower the row
(`ropecam.host.sim.shutter`): the sub-frames span every row's exposure, each row averages those in its own, and the
ground truth is each material point at the start and the end of the exposure of the row it is imaged in.

The result is two images: the time-averaged coverage C in [0, 1] and the time-averaged coverage x rope brightness A;
the scene composes ``background * (1 - C) + A`` (`ropecam.host.sim.scene`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose, plane_to_pixels
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim import _kernels
from ropecam.host.sim.rope_photo import RopeTexture, flat_texture
from ropecam.host.sim.shutter import rolling_centreline, row_offsets_s, row_weights
from ropecam.shared.jit import KernelStatus

__all__ = ["Exposure", "RopeRenderer", "max_pixels_per_metre"]

MAX_SUBFRAMES = 100_000


def max_pixels_per_metre(
    camera: CameraModel, plane: PlanePose, xlim_m: tuple[float, float], ylim_m: tuple[float, float]
) -> float:
    """Return the largest image scale (pixels per metre on the plane) over a rectangle of the plane.

    Parameters
    ----------
    camera, plane
        The camera and the motion plane.
    xlim_m, ylim_m
        The rectangle on the plane, metres.
    """
    step_x = (xlim_m[1] - xlim_m[0]) / 24
    step_y = (ylim_m[1] - ylim_m[0]) / 24
    xs = np.linspace(*xlim_m, 25)
    ys = np.linspace(*ylim_m, 25)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1)
    px = plane_to_pixels(grid, camera, plane)
    along_x = np.linalg.norm(np.diff(px, axis=1), axis=-1).max() / step_x
    along_y = np.linalg.norm(np.diff(px, axis=0), axis=-1).max() / step_y
    return float(max(along_x, along_y))


@dataclass(frozen=True)
class Exposure:
    """One rendered exposure; the image arrays are views into the renderer's buffers, valid until its next call.

    Attributes
    ----------
    cover
        (H, W) float32: time-averaged rope coverage in [0, 1].
    signal
        (H, W) float32: time-averaged coverage x rope brightness.
    begin_m, end_m
        (S, 2) centreline on the plane at the start and the end of the exposure, metres.
    begin_px, end_px
        (S, 2) the same, distorted pixels (u, v).
    begin_t_s, end_t_s
        (S,) the instant of each point of `begin_*`, `end_*`: the exposure's start and end for a global shutter,
        those of the point's own row for a rolling shutter.
    half_width_px
        (S,) apparent half-width of the rope at mid-exposure, pixels.
    subframes
        Number of sub-frames averaged.
    max_step_px
        Largest displacement of a centreline point between two consecutive sub-frames, pixels.
    """

    cover: NDArray[np.float32]
    signal: NDArray[np.float32]
    begin_m: NDArray[np.float64]
    end_m: NDArray[np.float64]
    begin_px: NDArray[np.float64]
    end_px: NDArray[np.float64]
    begin_t_s: NDArray[np.float64]
    end_t_s: NDArray[np.float64]
    half_width_px: NDArray[np.float64]
    subframes: int
    max_step_px: float


class RopeRenderer:
    """Render motion-blurred rope images from a trajectory through a camera.

    Parameters
    ----------
    camera, plane
        The camera and the pose of the motion plane.
    s_m
        (S,) arc lengths of the centreline samples, increasing from 0 (fixed end) to L (tip); spacing of about half a
        pixel keeps the polyline's chord error far below 0.01 px.
    diameter_m
        Diameter the rope is drawn with, metres.
    level
        (S,) rope brightness along the rope (DN), carried with the material.
    edge_sigma_px
        Total edge blur (Gaussian standard deviation), pixels.
    max_step_px
        Largest allowed motion of any centreline point between two sub-frames, pixels.
    readout_s
        Rolling shutter: delay of the last row's exposure start after the first row's, seconds (0: global).
    texture
        The rope's surface brightness (`ropecam.host.sim.rope_photo.RopeTexture`), multiplied into `level` per
        pixel from the material coordinate and the position across the rope; None: a plain rope.
    """

    def __init__(
        self,
        camera: CameraModel,
        plane: PlanePose,
        s_m: ArrayLike,
        diameter_m: float,
        level: ArrayLike,
        edge_sigma_px: float,
        max_step_px: float = 0.5,
        readout_s: float = 0.0,
        texture: RopeTexture | None = None,
    ) -> None:
        s = np.ascontiguousarray(s_m, dtype=np.float64)
        levels = np.ascontiguousarray(level, dtype=np.float64)
        if s.ndim != 1 or s.size < 2 or not np.all(np.diff(s) > 0):
            raise ValueError(f"s_m must be 1-D, increasing, with at least 2 samples, got shape {s.shape}")
        if levels.shape != s.shape or not np.all(np.isfinite(levels)):
            raise ValueError(f"level must be finite with the shape of s_m {s.shape}, got {levels.shape}")
        if not (diameter_m > 0 and math.isfinite(diameter_m)):
            raise ValueError(f"diameter_m must be > 0, got {diameter_m!r}")
        if not (edge_sigma_px > 0 and math.isfinite(edge_sigma_px)):
            raise ValueError(f"edge_sigma_px must be > 0, got {edge_sigma_px!r}")
        if not (max_step_px > 0 and math.isfinite(max_step_px)):
            raise ValueError(f"max_step_px must be > 0, got {max_step_px!r}")
        if not (readout_s >= 0 and math.isfinite(readout_s)):
            raise ValueError(f"readout_s must be >= 0, got {readout_s!r}")
        self.camera = camera
        self.plane = plane
        self.s_m = s
        self.level = levels
        self.diameter_m = float(diameter_m)
        self.edge_sigma_px = float(edge_sigma_px)
        self.max_step_px = float(max_step_px)
        self.readout_s = float(readout_s)
        self.texture = texture if texture is not None else flat_texture()
        width, height = camera.image_size
        self.row_offsets_s = row_offsets_s(height, self.readout_s)
        self._row_weight = np.empty(height, dtype=np.float64)
        self._dist = np.full((height, width), _kernels.FAR, dtype=np.float32)
        self._radius = np.zeros((height, width), dtype=np.float32)
        self._level = np.zeros((height, width), dtype=np.float32)
        self._cut = np.zeros((height, width), dtype=np.float32)
        self._box = np.array([width, height, -1, -1], dtype=np.int32)
        self._cover = np.zeros((height, width), dtype=np.float32)
        self._signal = np.zeros((height, width), dtype=np.float32)

    def project(self, points_m: ArrayLike) -> NDArray[np.float64]:
        """Return distorted pixels (u, v) of plane points (..., 2) in metres."""
        return plane_to_pixels(points_m, self.camera, self.plane)

    def half_width_px(self, points_m: NDArray[np.float64], points_px: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the apparent half-width (pixels) of the rope along a centreline (S, 2) given in metres and pixels.

        The rope's diameter, laid across the centreline in the plane, is projected and its component perpendicular
        to the projected centreline taken (tilt and distortion change the width along the rope).
        """
        tangent_m = np.gradient(points_m, self.s_m, axis=0)
        normal_m = np.stack([-tangent_m[:, 1], tangent_m[:, 0]], axis=-1)
        normal_m /= np.linalg.norm(normal_m, axis=-1, keepdims=True)
        half = 0.5 * self.diameter_m
        across = self.project(points_m + half * normal_m) - self.project(points_m - half * normal_m)
        tangent_px = np.gradient(points_px, self.s_m, axis=0)
        tangent_px /= np.linalg.norm(tangent_px, axis=-1, keepdims=True)
        return 0.5 * np.abs(across[:, 0] * tangent_px[:, 1] - across[:, 1] * tangent_px[:, 0])

    def subframes(
        self, trajectory: Trajectory, t_begin_s: float, t_end_s: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]:
        """Choose sub-frame times over an exposure so no centreline point moves more than `max_step_px` between them.

        Returns
        -------
        times_s, points_m, points_px, max_step_px
            (n + 1,) times from `t_begin_s` to `t_end_s`, (n + 1, S, 2) centrelines in metres and pixels, and the
            largest step actually taken.
        """
        if not t_end_s >= t_begin_s:
            raise ValueError(f"exposure must end after it starts, got {t_begin_s} .. {t_end_s} s")
        intervals = 1
        while True:
            times = np.linspace(t_begin_s, t_end_s, intervals + 1)
            points_m = trajectory.positions(times, self.s_m)
            points_px = self.project(points_m)
            step = float(np.linalg.norm(np.diff(points_px, axis=0), axis=-1).max())
            if step <= self.max_step_px or t_end_s == t_begin_s:
                return times, points_m, points_px, step
            if intervals >= MAX_SUBFRAMES:
                raise ValueError(f"exposure {t_begin_s}..{t_end_s} s needs more than {MAX_SUBFRAMES} sub-frames")
            intervals = min(MAX_SUBFRAMES, max(intervals + 1, math.ceil(intervals * step / self.max_step_px * 1.02)))

    def render(self, trajectory: Trajectory, t_begin_s: float, t_end_s: float) -> Exposure:
        """Render the exposure from `t_begin_s` to `t_end_s` (seconds on the trajectory's time axis).

        With a rolling shutter these are row 0's; row r's exposure is `row_offsets_s[r]` later, and the
        trajectory must cover the last row's end too.

        Returns
        -------
        Exposure
            Coverage and signal images (views into this renderer's buffers) and the exposure's centrelines.

        Raises
        ------
        ValueError
            The times lie outside the trajectory or the exposure ends before it starts.
        """
        rolling = self.readout_s > 0
        times, points_m, points_px, step = self.subframes(trajectory, t_begin_s, t_end_s + self.readout_s)
        if rolling:
            weights = row_weights(times, t_begin_s + self.row_offsets_s, t_end_s - t_begin_s)
        else:
            intervals = len(times) - 1
            weights = np.full(len(times), 1.0 / max(intervals, 1))
            if intervals:
                weights[0] = weights[-1] = 0.5 / intervals
            else:
                weights[0] = 1.0
        self._cover.fill(0.0)
        self._signal.fill(0.0)
        middle = len(times) // 2
        half_mid = self.half_width_px(points_m[middle], points_px[middle])
        # The apparent width changes by far less than 1e-3 px within one exposure: computed once, at mid-exposure.
        height = self.row_offsets_s.size
        row_first, row_last = 0, height - 1
        for k in range(len(times)):
            if rolling:
                (active,) = np.nonzero(weights[k])
                if not active.size:
                    continue
                row_first, row_last = int(active[0]), int(active[-1])
                self._row_weight[:] = weights[k]
            else:
                self._row_weight.fill(weights[k])
            status = _kernels.stamp_centreline(
                np.ascontiguousarray(points_px[k]), half_mid, self.level, self.edge_sigma_px, self.texture.table,
                self.texture.rows_per_sample, row_first, row_last, self._dist, self._radius, self._level, self._cut,
                self._box,
            )  # fmt: skip
            if status < 0:
                raise RuntimeError(f"stamp_centreline failed with {KernelStatus(status).name}")
            status = _kernels.accumulate_cover(
                self._dist, self._radius, self._level, self._cut, self._box, self.edge_sigma_px, self._row_weight,
                self._cover, self._signal,
            )  # fmt: skip
            if status < 0:
                raise RuntimeError(f"accumulate_cover failed with {KernelStatus(status).name}")
        if rolling:
            shutter = (self.camera, self.plane)
            begin_m, begin_px, begin_t = rolling_centreline(
                trajectory, self.s_m, *shutter, t_begin_s, self.readout_s, height
            )
            end_m, end_px, end_t = rolling_centreline(trajectory, self.s_m, *shutter, t_end_s, self.readout_s, height)
        else:
            begin_m, begin_px, begin_t = points_m[0], points_px[0], np.full(self.s_m.size, t_begin_s)
            end_m, end_px, end_t = points_m[-1], points_px[-1], np.full(self.s_m.size, t_end_s)
        return Exposure(
            cover=self._cover,
            signal=self._signal,
            begin_m=begin_m,
            end_m=end_m,
            begin_px=begin_px,
            end_px=end_px,
            begin_t_s=begin_t,
            end_t_s=end_t,
            half_width_px=half_mid,
            subframes=len(times),
            max_step_px=step,
        )
