"""Decoded records -> JSON messages of the recorded channels (Foxglove well-known types, ropecam.Status).

Image coordinates are (u, v) distorted pixels as x, y with z = 0 in frame ``device<ID>/image``; plane coordinates
(when a camera and plane pose are given) are metres (x along the release direction, y down) in ``device<ID>/plane``.
Polyline points are written with a fixed number of decimals (1e-6 px, 1e-9 m), formatted in one string operation:
a rope shape has ~400 points per exposure side and the host may see ~950 frames per second.
"""

from __future__ import annotations

import base64
import json
import logging
import math
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.shared.protocol.records import FrameResult, Log, Status

__all__ = [
    "frame_point_cloud",
    "frame_scene",
    "log_message",
    "model_scene",
    "raw_image",
    "status_message",
]

_BEGIN_COLOR: Final = '{"r":0.2,"g":0.5,"b":1.0,"a":1.0}'
_END_COLOR: Final = '{"r":1.0,"g":0.3,"b":0.2,"a":1.0}'
_TIP_COLOR: Final = '{"r":1.0,"g":0.9,"b":0.1,"a":1.0}'
_FIXED_COLOR: Final = '{"r":0.8,"g":0.8,"b":0.8,"a":1.0}'
_IDENTITY_POSE: Final = '{"position":{"x":0,"y":0,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}}'
_FOXGLOVE_LEVELS: Final = ((40, 4), (30, 3), (20, 2), (1, 1))  # Python level >= key -> Foxglove level
_POINT_FIELDS: Final = [
    {"name": "x", "offset": 0, "type": 7},
    {"name": "y", "offset": 4, "type": 7},
    {"name": "z", "offset": 8, "type": 7},
    {"name": "s_m", "offset": 12, "type": 7},
    {"name": "shape", "offset": 16, "type": 7},
]


def _time(t_ns: int) -> str:
    t_ns = max(0, int(t_ns))
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return f'{{"sec":{sec},"nsec":{nsec}}}'


def _points_json(points: NDArray[np.float64], decimals: int) -> str:
    template = '{"x":%.' + str(decimals) + 'f,"y":%.' + str(decimals) + 'f,"z":0}'
    # One %-format over all coordinates: ~10x faster than json.dumps of a list of dicts.
    return "[" + ",".join([template] * len(points)) % tuple(points.ravel().tolist()) + "]"


def _line(points: NDArray[np.float64], color: str, thickness: float, scale_invariant: bool, decimals: int) -> str:
    return (
        '{"type":0,"pose":' + _IDENTITY_POSE + ',"thickness":' + repr(thickness) + ',"scale_invariant":'
        + ("true" if scale_invariant else "false") + ',"points":' + _points_json(points, decimals)
        + ',"color":' + color + ',"colors":[],"indices":[]}'
    )  # fmt: skip


def _sphere(point: NDArray[np.float64], color: str, size: float, decimals: int) -> str:
    x, y = (float(v) for v in point)
    position = ('{"x":%.' + str(decimals) + 'f,"y":%.' + str(decimals) + 'f,"z":0}') % (x, y)
    return (
        '{"pose":{"position":' + position + ',"orientation":{"x":0,"y":0,"z":0,"w":1}},'
        f'"size":{{"x":{size!r},"y":{size!r},"z":{size!r}}},"color":' + color + "}"
    )


def _metadata(record: FrameResult) -> str:
    pairs = {
        "frame_index": str(record.frame_index),
        "exposure_start_t_ns": str(record.exposure_start_t_ns),
        "exposure_end_t_ns": str(record.exposure_end_t_ns),
        "status": record.status.name,
        "method": record.method.name,
        "order_confidence": f"{record.order_confidence:.5f}",
        "pipeline_us": str(record.pipeline_us),
    }
    return json.dumps([{"key": k, "value": v} for k, v in pairs.items()], separators=(",", ":"))


def _to_plane(points: NDArray[np.float64] | None, calibration: tuple[CameraModel, PlanePose]) -> NDArray | None:
    if points is None:
        return None
    return pixels_to_plane(points, calibration[0], calibration[1])


def frame_scene(
    record: FrameResult,
    device_id: int,
    t_ns: int,
    calibration: tuple[CameraModel, PlanePose] | None = None,
) -> bytes:
    """Return a ``foxglove.SceneUpdate`` (JSON bytes) with the begin and end shapes, tips and fixed end.

    Parameters
    ----------
    record
        The decoded FrameResult.
    device_id
        Sender; names the frame (``device<ID>/image`` or ``device<ID>/plane``).
    t_ns
        Timestamp of the entity (the host receive time, like the MCAP log time), ns since the epoch.
    calibration
        (camera, plane pose): when given, the scene is in metres on the plane instead of pixels.
    """
    if calibration is None:
        frame_id, decimals, thickness, size, invariant = f"device{device_id}/image", 6, 2.0, 8.0, True

        def convert(points: Any) -> Any:
            return None if points is None else np.asarray(points, dtype=np.float64).reshape(-1, 2)

    else:
        frame_id, decimals, thickness, size, invariant = f"device{device_id}/plane", 9, 0.004, 0.012, False

        def convert(points: Any) -> Any:
            return (
                None if points is None else _to_plane(np.asarray(points, dtype=np.float64).reshape(-1, 2), calibration)
            )

    lines = []
    for shape, color in ((record.begin_px, _BEGIN_COLOR), (record.end_px, _END_COLOR)):
        if shape is not None:
            lines.append(_line(convert(shape), color, thickness, invariant, decimals))
    spheres = []
    markers = ((record.begin_tip_px, _TIP_COLOR), (record.end_tip_px, _TIP_COLOR), (record.fixed_end_px, _FIXED_COLOR))
    for point, color in markers:
        if point is not None:
            spheres.append(_sphere(convert(point)[0], color, size, decimals))
    entity = (
        '{"timestamp":' + _time(t_ns) + ',"frame_id":' + json.dumps(frame_id) + ',"id":"rope",'
        '"lifetime":{"sec":0,"nsec":0},"frame_locked":false,"metadata":' + _metadata(record)
        + ',"lines":[' + ",".join(lines) + '],"spheres":[' + ",".join(spheres) + "]}"
    )  # fmt: skip
    return ('{"deletions":[],"entities":[' + entity + "]}").encode()


def model_scene(shapes_m: NDArray[np.float64], color: str, device_id: int, t_ns: int, frame_index: int) -> bytes:
    """Return a ``foxglove.SceneUpdate`` (entity ``model``, frame ``device<ID>/plane``) of model rope shapes in metres.

    Parameters
    ----------
    shapes_m
        (shapes, points, 2) positions on the plane, e.g. the model at exposure start and end.
    color
        Foxglove colour object as JSON text.
    """
    lines = ",".join(_line(shape, color, 0.003, False, 9) for shape in shapes_m)
    metadata = json.dumps([{"key": "frame_index", "value": str(frame_index)}], separators=(",", ":"))
    entity = (
        '{"timestamp":' + _time(t_ns) + ',"frame_id":' + json.dumps(f"device{device_id}/plane") + ',"id":"model",'
        '"lifetime":{"sec":0,"nsec":0},"frame_locked":false,"metadata":' + metadata + ',"lines":[' + lines
        + '],"spheres":[]}'
    )  # fmt: skip
    return ('{"deletions":[],"entities":[' + entity + "]}").encode()


def frame_point_cloud(
    record: FrameResult, device_id: int, t_ns: int, calibration: tuple[CameraModel, PlanePose] | None = None
) -> bytes:
    """Return a ``foxglove.PointCloud`` (JSON bytes) of the measured material points.

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
    frame = f"device{device_id}/{'image' if calibration is None else 'plane'}"
    message = {
        "timestamp": json.loads(_time(t_ns)),
        "frame_id": frame,
        "pose": json.loads(_IDENTITY_POSE),
        "point_stride": 20,
        "fields": _POINT_FIELDS,
        "data": base64.b64encode(packed.tobytes()).decode("ascii"),
    }
    return json.dumps(message, separators=(",", ":")).encode()


def raw_image(image: NDArray[np.uint8], device_id: int, t_ns: int) -> bytes:
    """Return a ``foxglove.RawImage`` (JSON bytes, mono8) of a grey frame the device sent on request."""
    height, width = image.shape
    message = {
        "timestamp": json.loads(_time(t_ns)),
        "frame_id": f"device{device_id}/image",
        "width": width,
        "height": height,
        "encoding": "mono8",
        "step": width,
        "data": base64.b64encode(np.ascontiguousarray(image).tobytes()).decode("ascii"),
    }
    return json.dumps(message, separators=(",", ":")).encode()


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def status_message(record: Status, device_id: int, t_ns: int) -> bytes:
    """Return a ``ropecam.Status`` (JSON bytes); nan fields become null."""
    message = {
        "timestamp": json.loads(_time(t_ns)),
        "device_id": device_id,
        "frame_rate_hz": _finite_or_none(record.frame_rate_hz),
        "frames_captured": record.frames_captured,
        "frames_dropped": record.frames_dropped,
        "messages_dropped": record.messages_dropped,
        "exposure_us": record.exposure_us,
        "gain_db": record.gain_db,
        "uptime_ns": record.uptime_ns,
        "cpu_load": _finite_or_none(record.cpu_load),
        "temperature_c": _finite_or_none(record.temperature_c),
        "counters": dict(record.counters),
    }
    return json.dumps(message, separators=(",", ":")).encode()


def foxglove_level(python_level: int) -> int:
    """Map a Python logging level to Foxglove's LogLevel (DEBUG 1, INFO 2, WARNING 3, ERROR 4, FATAL 5)."""
    if python_level >= logging.CRITICAL:
        return 5
    for threshold, level in _FOXGLOVE_LEVELS:
        if python_level >= threshold:
            return level
    return 0


def log_message(record: Log, name: str, t_ns: int) -> bytes:
    """Return a ``foxglove.Log`` (JSON bytes) for a device log line; `name` says who logged it."""
    message = {
        "timestamp": json.loads(_time(t_ns)),
        "level": foxglove_level(record.level),
        "message": record.text,
        "name": name,
        "file": "",
        "line": 0,
    }
    return json.dumps(message, separators=(",", ":")).encode()
