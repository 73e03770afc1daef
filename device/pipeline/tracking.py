"""PointTracker: material points at fixed unstretched arc lengths on a rope shape (uniform stretch, eqs. 9-12)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import as_ro
from ropecam.device.pipeline.workspace import TRACK_WORK, TrackBuffers, expose
from ropecam.shared.plane import PlaneCalibration

__all__ = ["PointTracker", "plane_params"]


def plane_params(plane: PlaneCalibration) -> NDArray[np.float64]:
    """Return the plane calibration as the read-only array the plane kernels take (`_kernels.plane`)."""
    params = np.zeros(K.PLANE_PARAMS, np.float64)
    m, p = plane.camera_matrix, K.PLANE
    params[[p.fx, p.skew, p.cx, p.fy, p.cy]] = (m[0, 0], m[0, 1], m[0, 2], m[1, 1], m[1, 2])
    params[p.k1 : p.k1 + plane.distortion.size] = plane.distortion  # k1 k2 p1 p2 k3 k4 k5 k6, as OpenCV orders them
    params[p.r00 : p.r22 + 1] = plane.rotation.ravel()
    params[[p.ox, p.oy, p.oz]] = -plane.rotation.T @ plane.translation_m
    params.flags.writeable = False
    return params


@expose("buffers", TrackBuffers)
class PointTracker:
    """Locate material points on rope shapes and report their stretch ratio Lc/Lc0.

    Parameters
    ----------
    arc_m
        Arc lengths of the material points in metres of unstretched rope, from the fixed end.
    rope_length_m
        Unstretched rope length in metres.
    length0_px
        Unstretched length in pixels (Lc0); None to take the median of the first `length0_frames` shapes.
    length0_frames
        Number of shapes for the Lc0 estimate.
    buffers
        The material points' buffers (`TrackBuffers`, for these `arc_m`); None: made here for shapes of up to
        `TRACK_WORK` points (a longer shape gets a scratch array of its own per call).
    """

    def __init__(
        self,
        arc_m: tuple[float, ...],
        rope_length_m: float,
        length0_px: float | None,
        length0_frames: int = 5,
        buffers: TrackBuffers | None = None,
    ) -> None:
        if rope_length_m <= 0:
            raise ValueError(f"rope_length_m must be > 0, got {rope_length_m}")
        self.arc_m = tuple(float(a) for a in arc_m)
        fraction = np.array(self.arc_m, np.float64) / rope_length_m
        if buffers is None:
            buffers = TrackBuffers.make(fraction, TRACK_WORK)
        elif not np.array_equal(buffers.fraction, fraction):
            raise ValueError(f"buffers are for arc fractions {buffers.fraction.tolist()}, expected {fraction.tolist()}")
        self.buffers = buffers
        """(each also a read-only attribute) ``fraction`` (read-only), ``out`` (the points on both shapes),
        ``lengths_px`` (Lc (px) of the last `track_shapes` call's shapes, begin and end), ``work`` (segment
        lengths of a shape, the kernels' scratch)."""
        self.length0_px = length0_px
        self.length0_frames = int(length0_frames)
        self._lengths: list[float] = []
        self._median: float | None = None
        self.fraction_ro = self.fraction
        self.out_slots = (self.out[0], self.out[1])
        self.length0_settled_px = -1.0 if length0_px is None else float(length0_px)
        """Lc0 once it no longer changes (configured, or all its shapes seen); -1 before."""
        self.plane: NDArray[np.float64] | None = None
        """The plane calibration (`plane_params`) when material points are placed by arc length on the plane."""

    def restart(self) -> None:
        """Forget the shapes' lengths seen so far (a configured Lc0 stays): Lc0 is measured again."""
        self._lengths.clear()
        self._median = None
        self.length0_settled_px = -1.0 if self.length0_px is None else float(self.length0_px)

    def length(self, poly: NDArray[np.float32]) -> float:
        """Return the polyline length Lc in pixels, eq. (9)."""
        return float(K.polyline_length(as_ro(poly), np.int32(len(poly))))

    @property
    def lengths_seen(self) -> int:
        """Shape lengths fed to the Lc0 estimate so far (none once Lc0 is configured)."""
        return len(self._lengths)

    def withdraw(self, count: int) -> None:
        """Take back the last `count` lengths fed to the Lc0 estimate (the shapes of a frame found implausible
        after `track_shapes` measured them); Lc0 is unsettled again when fewer than `length0_frames` remain."""
        if self.length0_px is not None or count <= 0:
            return
        del self._lengths[-count:]
        self._median = float(np.median(self._lengths)) if self._lengths else None
        if len(self._lengths) < self.length0_frames:
            self.length0_settled_px = -1.0

    def observe(self, length_px: float) -> None:
        """Feed the length of a measured shape to the Lc0 estimate (until it is fixed)."""
        if self.length0_px is None and len(self._lengths) < self.length0_frames:
            self._lengths.append(length_px)
            self._median = float(np.median(self._lengths))
            if len(self._lengths) == self.length0_frames:
                self.length0_settled_px = self._median

    @property
    def reference_length_px(self) -> float | None:
        """Lc0 in pixels: configured, or the median of the shapes seen so far (None before the first)."""
        if self.length0_px is not None:
            return self.length0_px
        return self._median

    def track_shapes(
        self, begin: NDArray[np.float32], end: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], float, NDArray[np.float32], float]:
        """Measure both shapes of a frame (float32 (n, 2), fixed end first; `end` may be `begin` itself): feed
        their lengths to the Lc0 estimate (`observe`) and return (material points on `begin`, its stretch
        Lc/Lc0, the points on `end`, its stretch), as `track` on each (slots 0 and 1), in one kernel call
        (`track_shapes`) once Lc0 is settled. Their lengths are then in `lengths_px`.

        Raises
        ------
        ValueError
            When a shape has no point.
        """
        single = begin is end
        length0 = self.length0_settled_px
        if length0 < 0.0:  # Lc0 still being estimated: the lengths first (a few frames at the start)
            self.observe(self.length(begin))
            if not single:
                self.observe(self.length(end))
            reference = self.reference_length_px
            length0 = float(reference) if reference is not None else 0.0
        work = self.work
        if len(begin) > len(work) or len(end) > len(work):  # longer than this pipeline's shapes can be
            work = np.zeros(max(len(begin), len(end)), np.float64)
        try:
            status, stretch_begin, stretch_end = K.track_shapes(
                begin, end, single, self.fraction_ro, length0, self.out, self.lengths_px, work
            )
        except TypeError:  # not the splitter's writable float32 buffers: copies
            begin = np.array(begin, np.float32)
            end = begin if single else np.array(end, np.float32)
            status, stretch_begin, stretch_end = K.track_shapes(
                begin, end, single, self.fraction_ro, length0, self.out, self.lengths_px, work
            )
        if status < 0:
            raise ValueError(f"cannot track material points on polylines of {len(begin)} and {len(end)} points")
        return self.out_slots[0], stretch_begin, self.out_slots[1], stretch_end

    def set_rolling(self, rolling: float) -> None:
        """Set the rolling shutter's line time in exposures of the plane the points are placed on (``rolling`` of
        `_kernels.plane`: readout time / (image rows x exposure time); 0: a global shutter or an unknown
        exposure). Nothing without a plane; a new value makes a new read-only `plane` array (the steady frame's
        table binds it again)."""
        plane = self.plane
        if plane is None or plane[K.PLANE.rolling] == rolling:
            return
        params = plane.copy()
        params[K.PLANE.rolling] = rolling
        params.flags.writeable = False
        self.plane = params

    def place_on_plane(self, begin: NDArray[np.float32], end: NDArray[np.float32]) -> bool:
        """Move the material points of `begin` and `end` (as `track_shapes` found them, in `out`) to the same
        fractions of each shape's arc length on the plane (`plane` set; one kernel call, `place_on_plane`).
        Returns False (the points as they were) when a shape misses the plane."""
        assert self.plane is not None
        single = begin is end
        work = self.work
        # The work the kernel needs: a rolling shutter's placement `K.ROLLING_WORK` values per point of both shapes
        # (with less it would place by the sheared shapes' own arcs), else one per point of the longer shape.
        need = max(len(begin), len(end))
        if self.plane[K.PLANE.rolling] != 0.0:
            need = K.ROLLING_WORK * (len(begin) + len(end))
        if len(work) < need:
            work = np.zeros(need, np.float64)
        try:
            status = K.place_on_plane(begin, end, single, self.fraction_ro, self.plane, self.out, work)
        except TypeError:  # not the splitter's writable float32 buffers: copies
            begin = np.array(begin, np.float32)
            end = begin if single else np.array(end, np.float32)
            status = K.place_on_plane(begin, end, single, self.fraction_ro, self.plane, self.out, work)
        return status >= 0
