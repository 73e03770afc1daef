"""JSON Schemas of the recorded channels: Foxglove's well-known message types (by their published names and field
names, so Foxglove renders them) and ropecam's own Status record.

Only the fields ropecam writes are spelled out, each with the type Foxglove's published schema gives it; Foxglove
identifies a well-known type by the schema name (``foxglove.SceneUpdate``, ...) and JSON encoding. Every schema is a
valid JSON Schema (draft 2020-12) and tests validate the recorded messages against it.
"""

from __future__ import annotations

import json
from typing import Any, Final

__all__ = ["SCHEMAS", "schema_bytes"]

_DRAFT: Final = "https://json-schema.org/draft/2020-12/schema"


def _number(description: str) -> dict[str, Any]:
    return {"type": "number", "description": description}


def _object(title: str, description: str, properties: dict[str, Any]) -> dict[str, Any]:
    return {"title": title, "description": description, "type": "object", "properties": properties}


def _time(description: str) -> dict[str, Any]:
    return {
        "type": "object",
        "title": "time",
        "description": description,
        "properties": {
            "sec": {"type": "integer", "minimum": 0},
            "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
        },
    }


def _duration(description: str) -> dict[str, Any]:
    schema = _time(description)
    schema["title"] = "duration"
    schema["properties"]["sec"] = {"type": "integer"}
    return schema


def _vector3(title: str, description: str) -> dict[str, Any]:
    return _object(title, description, {axis: _number(f"{axis} coordinate") for axis in "xyz"})


def _pose(description: str) -> dict[str, Any]:
    quaternion = _object("foxglove.Quaternion", "Orientation", {axis: _number(f"{axis} value") for axis in "xyzw"})
    return _object(
        "foxglove.Pose",
        description,
        {"position": _vector3("foxglove.Vector3", "Position"), "orientation": quaternion},
    )


def _color(description: str) -> dict[str, Any]:
    return _object("foxglove.Color", description, {c: _number(f"{c} in [0, 1]") for c in "rgba"})


def _enum(title: str, description: str, members: dict[str, int]) -> dict[str, Any]:
    return {
        "title": title,
        "description": description,
        "oneOf": [{"title": name, "const": value} for name, value in members.items()],
    }


def _line_primitive() -> dict[str, Any]:
    point = _object("foxglove.Point3", "Point", {axis: _number(f"{axis} coordinate") for axis in "xyz"})
    return _object(
        "foxglove.LinePrimitive",
        "A line strip, loop or list",
        {
            "type": _enum("foxglove.LineType", "Drawing mode", {"LINE_STRIP": 0, "LINE_LOOP": 1, "LINE_LIST": 2}),
            "pose": _pose("Origin of the points"),
            "thickness": _number("Line width"),
            "scale_invariant": {"type": "boolean", "description": "Thickness in screen pixels instead of metres"},
            "points": {"type": "array", "items": point, "description": "Points along the line"},
            "color": _color("Colour of the whole line"),
            "colors": {"type": "array", "items": _color("Per-point colour"), "description": "Per-point colours"},
            "indices": {"type": "array", "items": {"type": "integer", "minimum": 0}, "description": "Point indices"},
        },
    )


def _sphere_primitive() -> dict[str, Any]:
    return _object(
        "foxglove.SpherePrimitive",
        "A sphere or ellipsoid",
        {
            "pose": _pose("Centre and orientation"),
            "size": _vector3("foxglove.Vector3", "Diameter along each axis"),
            "color": _color("Colour"),
        },
    )


def _key_value() -> dict[str, Any]:
    return _object(
        "foxglove.KeyValuePair",
        "A key with its value",
        {"key": {"type": "string"}, "value": {"type": "string"}},
    )


def _scene_update() -> dict[str, Any]:
    entity = _object(
        "foxglove.SceneEntity",
        "A visual element of a 3D scene",
        {
            "timestamp": _time("Time of the entity"),
            "frame_id": {"type": "string", "description": "Frame of reference"},
            "id": {"type": "string", "description": "Replaces any earlier entity with the same id on the topic"},
            "lifetime": _duration("Removed after this long (zero: until replaced)"),
            "frame_locked": {"type": "boolean", "description": "Follow frame_id as it moves"},
            "metadata": {"type": "array", "items": _key_value(), "description": "Key-value metadata"},
            "lines": {"type": "array", "items": _line_primitive(), "description": "Line primitives"},
            "spheres": {"type": "array", "items": _sphere_primitive(), "description": "Sphere primitives"},
        },
    )
    deletion = _object(
        "foxglove.SceneEntityDeletion",
        "Removal of earlier entities",
        {
            "timestamp": _time("Only entities earlier than this are removed"),
            "type": _enum("foxglove.SceneEntityDeletionType", "What to remove", {"MATCHING_ID": 0, "ALL": 1}),
            "id": {"type": "string", "description": "Entity id for MATCHING_ID"},
        },
    )
    return _object(
        "foxglove.SceneUpdate",
        "An update to the entities of a 3D scene",
        {
            "deletions": {"type": "array", "items": deletion, "description": "Entities to delete"},
            "entities": {"type": "array", "items": entity, "description": "Entities to add or replace"},
        },
    )


def _point_cloud() -> dict[str, Any]:
    numeric = {
        "UNKNOWN": 0,
        "UINT8": 1,
        "INT8": 2,
        "UINT16": 3,
        "INT16": 4,
        "UINT32": 5,
        "INT32": 6,
        "FLOAT32": 7,
        "FLOAT64": 8,
    }
    field_schema = _object(
        "foxglove.PackedElementField",
        "A field packed into each point",
        {
            "name": {"type": "string"},
            "offset": {"type": "integer", "minimum": 0},
            "type": _enum("foxglove.NumericType", "Numeric type of the field", numeric),
        },
    )
    return _object(
        "foxglove.PointCloud",
        "Points with packed fields",
        {
            "timestamp": _time("Time of the points"),
            "frame_id": {"type": "string", "description": "Frame of reference"},
            "pose": _pose("Origin of the cloud"),
            "point_stride": {"type": "integer", "minimum": 0, "description": "Bytes per point"},
            "fields": {"type": "array", "items": field_schema, "description": "Fields of each point"},
            "data": {"type": "string", "contentEncoding": "base64", "description": "Packed points, base64"},
        },
    )


def _log() -> dict[str, Any]:
    levels = {"UNKNOWN": 0, "DEBUG": 1, "INFO": 2, "WARNING": 3, "ERROR": 4, "FATAL": 5}
    return _object(
        "foxglove.Log",
        "A log message",
        {
            "timestamp": _time("Time of the message"),
            "level": _enum("foxglove.LogLevel", "Severity", levels),
            "message": {"type": "string"},
            "name": {"type": "string", "description": "Process or node name"},
            "file": {"type": "string"},
            "line": {"type": "integer", "minimum": 0},
        },
    )


def _raw_image() -> dict[str, Any]:
    return _object(
        "foxglove.RawImage",
        "A raw image",
        {
            "timestamp": _time("Time of the image"),
            "frame_id": {"type": "string", "description": "Frame of reference"},
            "width": {"type": "integer", "minimum": 0},
            "height": {"type": "integer", "minimum": 0},
            "encoding": {"type": "string", "description": "Pixel encoding, e.g. mono8"},
            "step": {"type": "integer", "minimum": 0, "description": "Bytes per row"},
            "data": {"type": "string", "contentEncoding": "base64", "description": "Pixels, base64"},
        },
    )


def _status() -> dict[str, Any]:
    schema = _object(
        "ropecam.Status",
        "Device health, about once a second (see docs/protocol.md)",
        {
            "timestamp": _time("Device time of the status"),
            "device_id": {"type": "integer", "minimum": 0, "maximum": 65535},
            "frame_rate_hz": {"type": ["number", "null"]},
            "frames_captured": {"type": "integer", "minimum": 0},
            "frames_dropped": {"type": "integer", "minimum": 0},
            "messages_dropped": {"type": "integer", "minimum": 0},
            "exposure_us": {"type": "integer", "minimum": 0},
            "gain_db": {"type": "number"},
            "uptime_ns": {"type": "integer", "minimum": 0},
            "cpu_load": {"type": ["number", "null"], "description": "null when unknown"},
            "temperature_c": {"type": ["number", "null"], "description": "null when unknown"},
            "counters": {"type": "object", "additionalProperties": {"type": "integer"}},
        },
    )
    schema["required"] = ["device_id", "frames_captured", "frames_dropped"]
    return schema


def _model_error() -> dict[str, Any]:
    distances = {"type": "array", "items": {"type": ["number", "null"], "minimum": 0}}
    schema = _object(
        "ropecam.ModelError",
        "Distance of measured material points from the ANCF model (ropecam replay --model)",
        {
            "timestamp": _time("Host receive time of the frame"),
            "device_id": {"type": "integer", "minimum": 0, "maximum": 65535},
            "frame_index": {"type": "integer", "minimum": 0},
            "release_time_s": {"type": "number", "description": "Fitted release time on the device clock"},
            "model_time_s": {
                "type": "array",
                "items": {"type": ["number", "null"]},
                "description": "At exposure start, end (s since the release); null: past the end of the model run",
            },
            "s_m": {"type": "array", "items": {"type": "number", "minimum": 0}, "description": "Material points"},
            "error_begin_mm": distances | {"description": "Per point at exposure start; null: not measured"},
            "error_end_mm": distances | {"description": "Per point at exposure end; null: not measured"},
            # null also for every point of a frame whose status is not OK and past the end of the model run
        },
    )
    schema["required"] = ["device_id", "frame_index", "s_m", "error_begin_mm", "error_end_mm"]
    return schema


SCHEMAS: Final[dict[str, dict[str, Any]]] = {
    "foxglove.SceneUpdate": _scene_update(),
    "foxglove.PointCloud": _point_cloud(),
    "foxglove.Log": _log(),
    "foxglove.RawImage": _raw_image(),
    "ropecam.Status": _status(),
    "ropecam.ModelError": _model_error(),
}
for _schema in SCHEMAS.values():
    _schema["$schema"] = _DRAFT


def schema_bytes(name: str) -> bytes:
    """Return the JSON Schema named `name` as UTF-8 bytes (what the MCAP schema record holds)."""
    return json.dumps(SCHEMAS[name], separators=(",", ":")).encode()
