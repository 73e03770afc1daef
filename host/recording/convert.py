"""Decoded records -> the messages of the recorded channels: what to draw (`SceneContent`), then its bytes in JSON
(`JsonEncoder`, here) or protobuf (`ropecam.host.recording.proto.ProtobufEncoder`); ``ropecam.Status`` and
``ropecam.ModelError`` are JSON in both.

Image coordinates are (u, v) distorted pixels as x, y with z = 0 in frame ``device<ID>/image``; plane coordinates
(when a camera and plane pose are given) are metres (x along the release direction, y down) in ``device<ID>/plane``
(`ropecam.host.recording.frames` connects the two). JSON polyline points are written with a fixed number of decimals
(1e-6 px, 1e-9 m), formatted in one string operation: a rope shape has ~400 points per exposure side and the host
may see ~950 frames per second.
"""

from __future__ import annotations

import base64
import json
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Final, Protocol

import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.shared.protocol.records import FrameResult, Log, Status

__all__ = [
    "Encoder",
    "JsonEncoder",
    "Line",
    "SceneContent",
    "Sphere",
    "Transform",
    "foxglove_level",
    "frame_content",
    "model_content",
    "model_error_message",
    "point_cloud_content",
    "status_message",
]

Color = tuple[float, float, float, float]
BEGIN_COLOR: Final[Color] = (0.2, 0.5, 1.0, 1.0)
END_COLOR: Final[Color] = (1.0, 0.3, 0.2, 1.0)
TIP_COLOR: Final[Color] = (1.0, 0.9, 0.1, 1.0)
FIXED_COLOR: Final[Color] = (0.8, 0.8, 0.8, 1.0)
POINT_STRIDE: Final = 20
POINT_FIELDS: Final = (("x", 0), ("y", 4), ("z", 8), ("s_m", 12), ("shape", 16))
"""Packed float32 fields of each material point (FLOAT32 = 7 in foxglove.NumericType)."""
_FOXGLOVE_LEVELS: Final = ((40, 4), (30, 3), (20, 2), (1, 1))  # Python level >= key -> Foxglove level
_IDENTITY_POSE: Final = '{"position":{"x":0,"y":0,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}}'
_NO_PRIMITIVES: Final = '"arrows":[],"cubes":[],"cylinders":[],"triangles":[],"texts":[],"models":[]'


@dataclass(frozen=True, slots=True)
class Line:
    """A line strip: (n, 2) points (z = 0), colour, width (px on screen when `scale_invariant`, else metres)."""

    points: NDArray[np.float64]
    color: Color
    thickness: float
    scale_invariant: bool


@dataclass(frozen=True, slots=True)
class Sphere:
    """A marker at (x, y, 0) of diameter `size`."""

    point: tuple[float, float]
    color: Color
    size: float


@dataclass(frozen=True, slots=True)
class SceneContent:
    """One entity of a ``foxglove.SceneUpdate``: what is drawn, in which frame, in pixels or metres."""

    frame_id: str
    entity_id: str
    metres: bool
    lines: Sequence[Line] = ()
    spheres: Sequence[Sphere] = ()
    metadata: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class Transform:
    """Pose of `child` in `parent`: translation (m) and rotation quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


class Encoder(Protocol):
    """Bytes of the Foxglove well-known messages in one message encoding (``json`` or ``protobuf``)."""

    encoding: str

    def scene(self, content: SceneContent, t_ns: int) -> bytes: ...
    def point_cloud(self, frame_id: str, packed: bytes, t_ns: int) -> bytes: ...
    def raw_image(self, image: NDArray[np.uint8], device_id: int, t_ns: int) -> bytes: ...
    def log(self, record: Log, name: str, t_ns: int) -> bytes: ...
    def transforms(self, transforms: Sequence[Transform], t_ns: int) -> bytes: ...


def _metadata(record: FrameResult) -> dict[str, str]:
    return {
        "frame_index": str(record.frame_index),
        "exposure_start_t_ns": str(record.exposure_start_t_ns),
        "exposure_end_t_ns": str(record.exposure_end_t_ns),
        "status": record.status.name,
        "method": record.method.name,
        "order_confidence": f"{record.order_confidence:.5f}",
        "pipeline_us": str(record.pipeline_us),
    }


def frame_content(
    record: FrameResult, device_id: int, calibration: tuple[CameraModel, PlanePose] | None = None
) -> SceneContent:
    """Return the scene of one frame: the begin and end shapes, the tips and the fixed end.

    Parameters
    ----------
    record
        The decoded FrameResult.
    device_id
        Sender; names the frame (``device<ID>/image`` or ``device<ID>/plane``).
    calibration
        (camera, plane pose): when given, the scene is in metres on the plane instead of pixels.

    Raises
    ------
    ValueError
        With `calibration`: a pixel whose viewing ray misses the plane.
    """

    def convert(points: Any) -> NDArray[np.float64]:
        xy = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        return xy if calibration is None else pixels_to_plane(xy, calibration[0], calibration[1])

    metres = calibration is not None
    frame_id = f"device{device_id}/{'plane' if metres else 'image'}"
    thickness, size = (0.004, 0.012) if metres else (2.0, 8.0)
    lines = [
        Line(convert(shape), color, thickness, not metres)
        for shape, color in ((record.begin_px, BEGIN_COLOR), (record.end_px, END_COLOR))
        if shape is not None
    ]
    markers = ((record.begin_tip_px, TIP_COLOR), (record.end_tip_px, TIP_COLOR), (record.fixed_end_px, FIXED_COLOR))
    spheres = []
    for point, color in markers:
        if point is not None:
            x, y = convert(point)[0]
            spheres.append(Sphere((float(x), float(y)), color, size))
    return SceneContent(frame_id, "rope", metres, lines, spheres, _metadata(record))


def model_content(shapes_m: NDArray[np.float64], color: Color, device_id: int, frame_index: int) -> SceneContent:
    """Return the scene (entity ``model``, frame ``device<ID>/plane``) of model rope shapes, (shapes, n, 2) metres."""
    lines = [Line(np.asarray(shape, dtype=np.float64), color, 0.003, False) for shape in shapes_m]
    return SceneContent(f"device{device_id}/plane", "model", True, lines, (), {"frame_index": str(frame_index)})


def point_cloud_content(
    record: FrameResult, device_id: int, calibration: tuple[CameraModel, PlanePose] | None = None
) -> tuple[str, bytes]:
    """Return (frame id, packed points) of the measured material points (`POINT_FIELDS`, `POINT_STRIDE` bytes each).

    Each point packs float32 x, y, z (pixels or, with `calibration`, metres on the plane), ``s_m`` (arc length
    from the fixed end) and ``shape`` (0 begin, 1 end of the exposure); unmeasured points are left out.
    """
    rows = []
    for shape_index, points in enumerate((record.material_begin_px, record.material_end_px)):
        for s_m, point in zip(record.material_s_m, points, strict=True):
            if not math.isnan(point[0]):
                rows.append((point[0], point[1], s_m, shape_index))
    table = np.array(rows, dtype=np.float64).reshape(-1, 4)
    xy = table[:, :2]
    if calibration is not None and len(xy):
        xy = pixels_to_plane(xy, *calibration)
    packed = np.zeros((len(table), 5), dtype="<f4")
    packed[:, 0:2] = xy
    packed[:, 3:5] = table[:, 2:4]
    return f"device{device_id}/{'image' if calibration is None else 'plane'}", packed.tobytes()


def time_json(t_ns: int) -> dict[str, int]:
    """Return a Foxglove ``time`` object (sec, nsec) of `t_ns` ns since the epoch (negative: 0)."""
    sec, nsec = divmod(max(0, int(t_ns)), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def _time(t_ns: int) -> str:
    sec, nsec = divmod(max(0, int(t_ns)), 1_000_000_000)
    return f'{{"sec":{sec},"nsec":{nsec}}}'


def _color(color: Color) -> str:
    r, g, b, a = color
    return f'{{"r":{r!r},"g":{g!r},"b":{b!r},"a":{a!r}}}'


def _points_json(points: NDArray[np.float64], decimals: int) -> str:
    template = '{"x":%.' + str(decimals) + 'f,"y":%.' + str(decimals) + 'f,"z":0}'
    # One %-format over all coordinates: ~10x faster than json.dumps of a list of dicts.
    return "[" + ",".join([template] * len(points)) % tuple(points.ravel().tolist()) + "]"


class JsonEncoder:
    """The Foxglove messages as JSON, valid against the official JSON Schemas (every field present)."""

    encoding: Final = "json"

    def _line(self, line: Line, decimals: int) -> str:
        return (
            '{"type":0,"pose":' + _IDENTITY_POSE + ',"thickness":' + repr(line.thickness) + ',"scale_invariant":'
            + ("true" if line.scale_invariant else "false") + ',"points":' + _points_json(line.points, decimals)
            + ',"color":' + _color(line.color) + ',"colors":[],"indices":[]}'
        )  # fmt: skip

    def _sphere(self, sphere: Sphere, decimals: int) -> str:
        position = ('{"x":%.' + str(decimals) + 'f,"y":%.' + str(decimals) + 'f,"z":0}') % sphere.point
        size = sphere.size
        return (
            '{"pose":{"position":' + position + ',"orientation":{"x":0,"y":0,"z":0,"w":1}},'
            f'"size":{{"x":{size!r},"y":{size!r},"z":{size!r}}},"color":' + _color(sphere.color) + "}"
        )

    def scene(self, content: SceneContent, t_ns: int) -> bytes:
        """Return a ``foxglove.SceneUpdate`` with one entity (`content`) stamped `t_ns`."""
        decimals = 9 if content.metres else 6
        metadata = json.dumps([{"key": k, "value": v} for k, v in content.metadata.items()], separators=(",", ":"))
        entity = (
            '{"timestamp":' + _time(t_ns) + ',"frame_id":' + json.dumps(content.frame_id) + ',"id":'
            + json.dumps(content.entity_id) + ',"lifetime":{"sec":0,"nsec":0},"frame_locked":false,"metadata":'
            + metadata + ',"lines":[' + ",".join(self._line(line, decimals) for line in content.lines)
            + '],"spheres":[' + ",".join(self._sphere(s, decimals) for s in content.spheres) + "],"
            + _NO_PRIMITIVES + "}"
        )  # fmt: skip
        return ('{"deletions":[],"entities":[' + entity + "]}").encode()

    def point_cloud(self, frame_id: str, packed: bytes, t_ns: int) -> bytes:
        """Return a ``foxglove.PointCloud`` of packed points (`POINT_FIELDS`)."""
        message = {
            "timestamp": time_json(t_ns),
            "frame_id": frame_id,
            "pose": json.loads(_IDENTITY_POSE),
            "point_stride": POINT_STRIDE,
            "fields": [{"name": name, "offset": offset, "type": 7} for name, offset in POINT_FIELDS],
            "data": base64.b64encode(packed).decode("ascii"),
        }
        return json.dumps(message, separators=(",", ":")).encode()

    def raw_image(self, image: NDArray[np.uint8], device_id: int, t_ns: int) -> bytes:
        """Return a ``foxglove.RawImage`` (mono8) of a grey frame the device sent on request."""
        height, width = image.shape
        message = {
            "timestamp": time_json(t_ns),
            "frame_id": f"device{device_id}/image",
            "width": width,
            "height": height,
            "encoding": "mono8",
            "step": width,
            "data": base64.b64encode(np.ascontiguousarray(image).tobytes()).decode("ascii"),
        }
        return json.dumps(message, separators=(",", ":")).encode()

    def log(self, record: Log, name: str, t_ns: int) -> bytes:
        """Return a ``foxglove.Log`` for a device log line; `name` says who logged it."""
        message = {
            "timestamp": time_json(t_ns),
            "level": foxglove_level(record.level),
            "message": record.text,
            "name": name,
            "file": "",
            "line": 0,
        }
        return json.dumps(message, separators=(",", ":")).encode()

    def transforms(self, transforms: Sequence[Transform], t_ns: int) -> bytes:
        """Return a ``foxglove.FrameTransforms``."""
        items = [
            {
                "timestamp": time_json(t_ns),
                "parent_frame_id": t.parent,
                "child_frame_id": t.child,
                "translation": dict(zip("xyz", t.translation, strict=True)),
                "rotation": dict(zip("xyzw", t.rotation, strict=True)),
            }
            for t in transforms
        ]
        return json.dumps({"transforms": items}, separators=(",", ":")).encode()


def status_message(record: Status, device_id: int, t_ns: int) -> bytes:
    """Return a ``ropecam.Status`` (JSON bytes); unknown (nan) values are left out."""
    message: dict[str, Any] = {
        "timestamp": time_json(t_ns),
        "device_id": device_id,
        "frames_captured": record.frames_captured,
        "frames_dropped": record.frames_dropped,
        "messages_dropped": record.messages_dropped,
        "exposure_us": record.exposure_us,
        "gain": record.gain,
        "uptime_ns": record.uptime_ns,
        "counters": [{"name": name, "value": value} for name, value in record.counters],
    }
    for name in ("frame_rate_hz", "cpu_load", "temperature_c"):
        value = getattr(record, name)
        if math.isfinite(value):
            message[name] = value
    return json.dumps(message, separators=(",", ":")).encode()


def model_error_message(
    device_id: int,
    frame_index: int,
    t_ns: int,
    release_time_s: float,
    model_times_s: tuple[float | None, float | None],
    s_m: Sequence[float],
    errors_mm: tuple[Sequence[float | None], Sequence[float | None]],
) -> bytes:
    """Return a ``ropecam.ModelError`` (JSON bytes); None times and distances are left out."""
    message: dict[str, Any] = {
        "timestamp": time_json(t_ns),
        "device_id": device_id,
        "frame_index": frame_index,
        "release_time_s": release_time_s,
    }
    for name, value in zip(("model_time_begin_s", "model_time_end_s"), model_times_s, strict=True):
        if value is not None:
            message[name] = value
    points = []
    for s, begin, end in zip(s_m, *errors_mm, strict=True):
        point: dict[str, float] = {"s_m": s}
        if begin is not None:
            point["error_begin_mm"] = begin
        if end is not None:
            point["error_end_mm"] = end
        points.append(point)
    message["points"] = points
    return json.dumps(message, separators=(",", ":")).encode()


def foxglove_level(python_level: int) -> int:
    """Map a Python logging level to Foxglove's LogLevel (DEBUG 1, INFO 2, WARNING 3, ERROR 4, FATAL 5)."""
    if python_level >= logging.CRITICAL:
        return 5
    for threshold, level in _FOXGLOVE_LEVELS:
        if python_level >= threshold:
            return level
    return 0
