"""Measured rope shapes in metres: read the device's per-frame results, convert them, track material points.

The device reports each frame's rope at the start and at the end of the exposure as centrelines in distorted
pixels (fixed end first). Here they are converted to metres on the motion plane with the calibration, and material
points are tracked on the metric curves by arc length with uniform stretch (the paper's equations 9-12: a point at
unstretched arc length s sits at ``s * Lc / Lc0`` along the measured curve). Tracking in metres rather than pixels
keeps perspective and lens distortion out of the arc lengths.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.host.compare.shutter import frame_points
from ropecam.host.compare.tracks import MaterialPointTracks
from ropecam.shared.errors import ConfigError, DataError
from ropecam.shared.protocol.quality import WIRE_TOLERANCE_KEY

if TYPE_CHECKING:
    from ropecam.shared.protocol.records import FrameResult

__all__ = [
    "MeasuredFrame",
    "default_points",
    "measured_frame",
    "points_at_arc_lengths",
    "read_extract_jsonl",
    "shape_points_m",
    "tracks_from_frames",
]


def default_points(length_m: float) -> list[float]:
    """Material points tracked by default: a quarter, half, three quarters of the rope, and its tip."""
    return [length_m * f for f in (0.25, 0.5, 0.75, 1.0)]


@dataclass(frozen=True)
class MeasuredFrame:
    """One frame's measured shapes in distorted pixels (None where not measured) and exposure times in ns.

    ``readout_ns`` is the rolling shutter's readout time (0: global shutter): a point on image row v of the begin
    shape was seen at ``t_begin_ns + v / height * readout_ns``, of the end shape at ``t_end_ns + v / height *
    readout_ns`` (height: the camera's image height).
    """

    frame: int
    t_begin_ns: int
    t_end_ns: int
    begin_px: NDArray[np.float64] | None
    end_px: NDArray[np.float64] | None
    status: str = "OK"
    readout_ns: int = 0


def measured_frame(record: FrameResult) -> MeasuredFrame:
    """Return the `MeasuredFrame` of a decoded FrameResult (what ``ropecam-device extract`` writes of it).

    A frame the sender's byte budget cut (its quality record carries ``wire_tolerance_px``: shapes coded at 0.5-2 px
    or left out, `ropecam.shared.protocol.budget`) has no measured shapes here: the tracks and the comparison use
    only shapes within the stream's own tolerance. The recording keeps the frame as it came.
    """
    cut = WIRE_TOLERANCE_KEY in record.quality
    return MeasuredFrame(
        record.frame_index,
        record.exposure_start_t_ns,
        record.exposure_end_t_ns,
        None if cut else record.begin_px,
        None if cut else record.end_px,
        record.status.name,
        int(getattr(record, "readout_ns", 0)),  # wire v2 carries it; v1 is a global shutter
    )


def _points(value: Any, where: str) -> NDArray[np.float64] | None:
    if value is None:
        return None
    array = np.asarray(value, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 2 or array.shape[0] < 2 or not np.all(np.isfinite(array)):
        raise DataError(f"{where}: expected a list of at least two finite [u, v] points")
    return array


def read_extract_jsonl(path: str | Path) -> list[MeasuredFrame]:
    """Read the JSON lines written by `ropecam-device extract`.

    Raises
    ------
    DataError
        The file is missing, or a line is not JSON or lacks ``frame``/``t_ns`` (the message names file and line).
    """
    path = Path(path)
    frames = []
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise DataError(f"{path}: cannot read measurement file: {exc.strerror or exc}") from exc
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        where = f"{path}:{number}"
        try:
            record = json.loads(line)
            frame = int(record["frame"])
            t_begin = int(record["t_ns"])
            end_time = record.get("t_end_ns")
            t_end = t_begin if end_time is None else int(end_time)
            readout_ns = int(record.get("readout_ns", 0) or 0)
        except (json.JSONDecodeError, KeyError, TypeError, ValueError, AttributeError) as exc:
            raise DataError(f"{where}: not an extract record (needs frame, t_ns): {exc}") from exc
        if record.get("end") is not None and (end_time is None or t_end <= t_begin):
            # The end shape belongs to the end of the exposure: without its own later time it would be placed at
            # the start and bias every fit by one exposure.
            raise DataError(f"{where}: an 'end' shape needs 't_end_ns' after 't_ns', got {end_time!r}")
        if readout_ns < 0:
            raise DataError(f"{where}: 'readout_ns' must be >= 0 (0 = global shutter), got {readout_ns}")
        frames.append(
            MeasuredFrame(
                frame=frame,
                t_begin_ns=t_begin,
                t_end_ns=t_end,
                begin_px=_points(record.get("begin"), f"{where} begin"),
                end_px=_points(record.get("end"), f"{where} end"),
                status=str(record.get("status", "OK")),
                readout_ns=readout_ns,
            )
        )
    if not frames:
        raise DataError(f"{path}: no frames in the measurement file")
    return frames


def points_at_arc_lengths(
    curve_m: NDArray[np.float64], s_m: NDArray[np.float64], length_m: float
) -> tuple[NDArray[np.float64], float]:
    """Locate material points on a measured curve by arc length with uniform stretch (paper, eqs. 9-12).

    Parameters
    ----------
    curve_m
        The measured centreline, fixed end first, shape (n, 2), metres.
    s_m
        Unstretched arc lengths of the points, shape (K,).
    length_m
        The unstretched rope length Lc0.

    Returns
    -------
    points, stretch
        Positions (K, 2) (NaN beyond the measured curve) and the stretch ratio Lc / Lc0.
    """
    steps = np.linalg.norm(np.diff(curve_m, axis=0), axis=1)
    cumulative = np.concatenate([[0.0], np.cumsum(steps)])
    measured_length = float(cumulative[-1])
    stretch = measured_length / length_m
    targets = np.asarray(s_m, dtype=np.float64) * stretch
    inside = targets <= measured_length * (1 + 1e-9)
    x = np.interp(targets, cumulative, curve_m[:, 0])
    y = np.interp(targets, cumulative, curve_m[:, 1])
    points = np.column_stack([x, y])
    points[~inside] = np.nan
    return points, stretch


def shape_points_m(
    shape_px: NDArray[np.float64] | None,
    status: str,
    camera: CameraModel,
    plane: PlanePose,
    s_m: NDArray[np.float64],
    length_m: float,
) -> tuple[NDArray[np.float64], float]:
    """Material points (K, 2) in metres of one measured shape, and its stretch ratio.

    All NaN when the shape is missing or its frame's `status` is not ``"OK"`` (the comparison never uses those).

    Raises
    ------
    ValueError
        A pixel's viewing ray misses the plane (from `pixels_to_plane`): the calibration does not fit the shape.
    """
    if shape_px is None or status != "OK":
        return np.full((np.size(s_m), 2), np.nan), math.nan
    return points_at_arc_lengths(pixels_to_plane(shape_px, camera, plane), s_m, length_m)


def tracks_from_frames(
    frames: Iterable[MeasuredFrame],
    camera: CameraModel,
    plane: PlanePose,
    s_m: Sequence[float],
    length_m: float,
    skipped: list[str] | None = None,
) -> tuple[MaterialPointTracks, NDArray[np.float64]]:
    """Convert measured frames into material-point tracks in metres (two samples per frame), with each point's
    in-frame velocity: its displacement from the rope at the start to the rope at the end of the exposure over the
    exposure time (a velocity within one frame, which no frame-to-frame tracker gives).

    Returns the tracks and the stretch ratio of every sample (NaN where unmeasured). Frames whose status is not OK
    or whose shapes are missing contribute NaN samples, so nothing measured is dropped silently.

    A shape with a pixel whose viewing ray misses the plane (a wild shape, or a calibration that does not fit) also
    gives NaN samples, and a line naming its frame is appended to `skipped`: one bad shape must not stop the
    comparison of the others. When more than half of the measured shapes miss the plane, the calibration is wrong
    rather than the shapes, and that is an error.

    Raises
    ------
    ConfigError
        A material point outside [0, `length_m`].
    DataError
        No frames, or most measured shapes miss the plane (names the first such frame).
    """
    s = np.asarray(s_m, dtype=np.float64)
    if s.ndim != 1 or s.size == 0 or np.any(s < 0) or np.any(s > length_m * (1 + 1e-9)):
        raise ConfigError(f"material points must lie in [0, {length_m}] m (the rope length), got {list(s)}")
    times: list[float] = []
    positions: list[NDArray[np.float64]] = []
    stretches: list[float] = []
    numbers: list[int] = []
    velocities: list[NDArray[np.float64]] = []
    mid_exposure: list[NDArray[np.float64]] = []
    point_times: list[NDArray[np.float64]] = []
    height = float(camera.image_size[1])
    off_plane: list[str] = []
    shapes = 0
    for frame in frames:
        curves: list[NDArray[np.float64] | None] = []
        rows: list[NDArray[np.float64] | None] = []
        for t_ns, shape in ((frame.t_begin_ns, frame.begin_px), (frame.t_end_ns, frame.end_px)):
            measured = shape is not None and frame.status == "OK"
            shapes += measured
            curve = None
            if measured:
                try:
                    curve = pixels_to_plane(shape, camera, plane)
                except ValueError as exc:
                    off_plane.append(f"frame {frame.frame} (t_ns {t_ns}): {exc}")
            curves.append(curve)
            rows.append(None if curve is None else np.asarray(shape, dtype=np.float64)[:, 1])
        got = frame_points(
            curves[0], curves[1], rows[0], rows[1], frame.t_begin_ns * 1e-9, frame.t_end_ns * 1e-9,
            frame.readout_ns * 1e-9, height, s, length_m,
        )  # fmt: skip
        times += [frame.t_begin_ns * 1e-9, frame.t_end_ns * 1e-9]
        positions += [got.begin_m, got.end_m]
        point_times += [got.begin_t_s, got.end_t_s]
        stretches += [got.begin_stretch, got.end_stretch]
        velocities += [got.velocity_m_s, got.velocity_m_s]
        mid_exposure += [got.mid_t_s, got.mid_t_s]
        numbers += [frame.frame, frame.frame]
    if not times:
        raise DataError("no frames to convert")
    if off_plane and 2 * len(off_plane) > shapes:
        raise DataError(
            f"{len(off_plane)} of {shapes} measured shapes miss the motion plane, e.g. {off_plane[0]}; "
            "does the plane calibration belong to this camera?"
        )
    if skipped is not None:
        skipped.extend(f"{line}: skipped (off the plane)" for line in off_plane)
    tracks = MaterialPointTracks(
        np.asarray(times), s, np.stack(positions), np.asarray(numbers), np.stack(velocities), np.stack(mid_exposure),
        np.stack(point_times), np.tile([False, True], len(numbers) // 2),
    )  # fmt: skip
    order = np.argsort(np.asarray(times), kind="stable")
    return tracks, np.asarray(stretches)[order]
