"""One frame's material points in metres, each with the time it was seen, for a global or a rolling shutter.

A frame holds the rope at the start and at the end of its exposure (``begin`` and ``end``, fixed end first). With a
rolling shutter (``readout_ns`` > 0) image row r is exposed ``r / height * readout_ns`` after row 0, so a point of
``begin`` on row r was seen at ``t_begin + r / height * readout`` and a point of ``end`` at ``t_end + r / height *
readout`` (docs/pipeline.md, "Time of a shape point"). Then:

* **Placement.** A measured curve is not the rope at one instant: each of its points is the rope at its row's time.
  Its length is not the rope's (a rope moving across the rows is sheared: -0.2 to +0.5 % on the simulated rig-soft
  with a 7 ms readout), so uniform stretch on it misplaces the material points (0.3 mm at L/2). Each material point
  is seen twice in a frame (begin and end, each at its own row's time), so the rope at one instant (the middle of
  the exposure of the frame's median row) is interpolated linearly in time between the two sightings, point by
  point; the points are re-placed by uniform stretch on that rope (its stretch is the one reported) and read on the
  measured curves at the same material arc lengths, so a reported position is a measured one, at its own row's time.
  Two passes (the sightings depend on the placement; the second changes nothing measurable). On the simulator's
  exact shapes of rig-soft with a 7 ms readout this leaves 0.02-0.08 mm (L/4-3L/4, 0 at the tip) of the 0.2-0.3 mm
  of uniform stretch on the sheared curve: the rope's acceleration within the exposure, which a linear
  interpolation cannot see. A frame with one shape only is placed on its sheared curve.
* **Times.** Each material point's time is its own row's (begin and end separately); the in-frame velocity is the
  displacement over the difference of the two times (the exposure, plus the row change of the point times the row
  delay) and belongs to their midpoint.

With a global shutter all of this reduces to uniform stretch on the measured curves, the frame's two exposure times
and the displacement over the exposure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["FramePoints", "frame_points"]

DESKEW_PASSES = 2
"""Passes of the rolling-shutter placement; on the simulated rig-soft (7 ms readout, exact shapes) the second
changes the points by < 0.1 um."""
VELOCITY_SAMPLES = 65
"""Material points along the rope at which the rope at one instant is interpolated (a rolling shutter)."""


@dataclass(frozen=True)
class FramePoints:
    """The material points (K, 2) m of a frame's two shapes, their times (K,) s and stretches; the in-frame
    velocity (K, 2) m/s and its time (K,) s. NaN where a shape is missing (times then the row-0 time)."""

    begin_m: NDArray[np.float64]
    end_m: NDArray[np.float64]
    begin_t_s: NDArray[np.float64]
    end_t_s: NDArray[np.float64]
    begin_stretch: float
    end_stretch: float
    velocity_m_s: NDArray[np.float64]
    mid_t_s: NDArray[np.float64]


def _arc(curve: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])


def _at(s_vertices: NDArray[np.float64], values: NDArray[np.float64], s: NDArray[np.float64]) -> NDArray[np.float64]:
    """Linear interpolation of per-vertex `values` (n,) or (n, 2) at material arc lengths `s`."""
    if values.ndim == 1:
        return np.interp(s, s_vertices, values)
    return np.column_stack([np.interp(s, s_vertices, values[:, i]) for i in range(values.shape[1])])


class _Curve:
    """A measured curve (n, 2) m, the delays (n,) s of its vertices after row 0, and the material arc length of each
    vertex: uniform stretch on the curve itself (`place`), re-placed on the rope at one instant for a rolling
    shutter (`_place_at_one_instant`)."""

    def __init__(self, curve_m: NDArray[np.float64], delay_s: NDArray[np.float64], length_m: float) -> None:
        self.curve, self.delay, self.length = curve_m, delay_s, length_m
        self.place(curve_m)

    def place(self, curve_m: NDArray[np.float64]) -> None:
        """Material arc lengths of the vertices by uniform stretch on `curve_m`."""
        arc = _arc(curve_m)
        self.stretch = float(arc[-1]) / self.length
        self.s_vertices = arc / self.stretch if self.stretch > 0 else arc

    def points(self, s_m: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The measured positions (K, 2) of material points `s_m` and their delays (K,); NaN beyond the curve."""
        points, delay = _at(self.s_vertices, self.curve, s_m), _at(self.s_vertices, self.delay, s_m)
        beyond = s_m > self.s_vertices[-1] * (1 + 1e-9)
        points[beyond] = np.nan
        return points, delay


def _place_at_one_instant(begin: _Curve, end: _Curve, exposure_s: float, length_m: float) -> float:
    """Re-place the material points of a rolling-shutter frame's two curves (their `s_vertices`) by uniform stretch
    on the rope at one instant; return that rope's stretch (see the module docstring)."""
    grid = np.linspace(0.0, length_m, VELOCITY_SAMPLES)
    stretch = math.nan
    for _ in range(DESKEW_PASSES):
        (pb, db), (pe, de) = begin.points(grid), end.points(grid)
        ok = np.all(np.isfinite(pb), axis=1) & np.all(np.isfinite(pe), axis=1)
        if ok.sum() < 2 or not (ok[0] and ok[-1]):
            break
        pb, pe, db, de, g = pb[ok], pe[ok], db[ok], de[ok], grid[ok]
        # Each material point between its two sightings, linearly in time, at one instant: the middle of the
        # exposure of the frame's median row (within a few ms of every sighting).
        t_ref = 0.5 * exposure_s + float(np.median(np.concatenate([db, de])))
        weight = (t_ref - db) / (exposure_s + de - db)
        rope = pb + (pe - pb) * weight[:, None]
        arc = _arc(rope)
        stretch = float(arc[-1]) / length_m
        moved = arc / stretch  # where the points called g sit on the rope at that instant
        for c in (begin, end):
            c.s_vertices = np.interp(c.s_vertices, g, moved)
    return stretch


def frame_points(
    begin_m: NDArray[np.float64] | None,
    end_m: NDArray[np.float64] | None,
    begin_rows: NDArray[np.float64] | None,
    end_rows: NDArray[np.float64] | None,
    t_begin_s: float,
    t_end_s: float,
    readout_s: float,
    height: float,
    s_m: NDArray[np.float64],
    length_m: float,
) -> FramePoints:
    """Material points, times and in-frame velocities of one frame (see the module docstring).

    Parameters
    ----------
    begin_m, end_m
        The measured curves in metres on the plane, fixed end first, (n, 2); None where not measured.
    begin_rows, end_rows
        The image row of each curve vertex (its pixel v), (n,).
    t_begin_s, t_end_s
        The exposure's start and end (row 0), seconds.
    readout_s, height
        The rolling shutter's readout time (0: global shutter) and the image height in rows.
    s_m, length_m
        The material points (unstretched arc lengths, (K,)) and the unstretched rope length.
    """
    k = s_m.size
    curves: list[_Curve | None] = []
    for curve, rows in ((begin_m, begin_rows), (end_m, end_rows)):
        if curve is None or rows is None:
            curves.append(None)
            continue
        delay = np.clip(rows, 0.0, height) / height * readout_s if readout_s > 0 else np.zeros(len(curve))
        curves.append(_Curve(curve, delay, length_m))
    begin, end = curves
    exposure = t_end_s - t_begin_s
    stretch = math.nan
    if readout_s > 0 and begin is not None and end is not None and exposure > 0:
        stretch = _place_at_one_instant(begin, end, exposure, length_m)
    out: list[tuple[NDArray[np.float64], NDArray[np.float64], float]] = []
    for c, t0 in ((begin, t_begin_s), (end, t_end_s)):
        if c is None:
            out.append((np.full((k, 2), np.nan), np.full(k, t0), math.nan))
            continue
        points, delay = c.points(s_m)
        out.append((points, t0 + delay, c.stretch if math.isnan(stretch) else stretch))
    (pb, tb, sb), (pe, te, se) = out
    dt = te - tb
    with np.errstate(invalid="ignore", divide="ignore"):
        velocity = np.where((dt > 0)[:, None], (pe - pb) / dt[:, None], np.nan)
    return FramePoints(pb, pe, tb, te, sb, se, velocity, 0.5 * (tb + te))
