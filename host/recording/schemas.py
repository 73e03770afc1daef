"""Schemas of the recorded channels: Foxglove's well-known types and ropecam's own records.

Foxglove types (``foxglove.SceneUpdate``, ``foxglove.PointCloud``, ``foxglove.FrameTransforms``, ``foxglove.Log``,
``foxglove.RawImage``) exist in two encodings:

- protobuf: the schema record is the ``FileDescriptorSet`` of the official ``foxglove-schemas-protobuf`` package.
- JSON: the official JSON Schema, derived from those same descriptors by `derive_json_schema` with the rules of
  Foxglove's own generator (``generateJsonSchema`` of foxglove-sdk): every field required, ``google.protobuf``
  ``Timestamp``/``Duration`` as ``time``/``duration`` objects, ``bytes`` as base64 strings, enums as ``oneOf`` of
  constants. The derived schemas are vendored in ``foxglove_jsonschema.json`` (package data, MIT licence of the
  Foxglove schemas) so that JSON recording needs no protobuf; a test checks the file against the installed
  package. Enum fields also carry ``"type": "integer"`` so that loaders without ``oneOf`` support read them too.

ropecam's own types (``ropecam.Status``, ``ropecam.ModelError``) are JSON: only types and constructs the Foxglove
app's JSON-schema loader reads (objects with ``properties``, no ``null`` or type unions): an unknown value is left
out of the message, never written as null.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any, Final

from ropecam.host.recording.wire import WIRE_SCHEMA
from ropecam.host.recording.wire import descriptor_set as wire_descriptor_set

__all__ = [
    "FOXGLOVE_TYPES",
    "ROPECAM_SCHEMAS",
    "derive_json_schema",
    "descriptor_set",
    "foxglove_class",
    "json_schema",
    "schema_bytes",
    "schema_record",
]

FOXGLOVE_TYPES: Final = (
    "foxglove.SceneUpdate",
    "foxglove.PointCloud",
    "foxglove.FrameTransforms",
    "foxglove.Log",
    "foxglove.RawImage",
)
"""The Foxglove well-known types ropecam records."""
VENDORED: Final = "foxglove_jsonschema.json"

# FieldDescriptor.type values (google/protobuf/descriptor.proto)
_DOUBLE, _FLOAT, _INT64, _UINT64, _INT32, _FIXED64, _FIXED32, _BOOL, _STRING = 1, 2, 3, 4, 5, 6, 7, 8, 9
_MESSAGE, _BYTES, _UINT32, _ENUM, _SFIXED32, _SFIXED64, _SINT32, _SINT64 = 11, 12, 13, 14, 15, 16, 17, 18


def _scalar(field_type: int) -> dict[str, Any]:
    if field_type in (_DOUBLE, _FLOAT):
        return {"type": "number"}
    if field_type in (_UINT32, _FIXED32, _UINT64, _FIXED64):
        return {"type": "integer", "minimum": 0}
    if field_type in (_INT32, _INT64, _SINT32, _SINT64, _SFIXED32, _SFIXED64):
        return {"type": "integer"}
    if field_type == _BOOL:
        return {"type": "boolean"}
    if field_type == _STRING:
        return {"type": "string"}
    if field_type == _BYTES:
        return {"type": "string", "contentEncoding": "base64"}
    raise ValueError(f"protobuf field type {field_type} has no JSON Schema mapping")


def _time(title: str) -> dict[str, Any]:
    sec = {"type": "integer", "minimum": 0} if title == "time" else {"type": "integer"}
    return {
        "type": "object",
        "title": title,
        "properties": {"sec": sec, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
    }


def derive_json_schema(descriptor: Any) -> dict[str, Any]:
    """Return the JSON Schema of a Foxglove protobuf message type, as Foxglove's generator writes it.

    Parameters
    ----------
    descriptor
        ``google.protobuf.descriptor.Descriptor`` of a ``foxglove.*`` message (e.g. ``SceneUpdate.DESCRIPTOR``).
    """
    properties: dict[str, Any] = {}
    for field in descriptor.fields:
        if field.type == _MESSAGE:
            name = field.message_type.full_name
            if name == "google.protobuf.Timestamp":
                schema = _time("time")
            elif name == "google.protobuf.Duration":
                schema = _time("duration")
            else:
                schema = derive_json_schema(field.message_type)
        elif field.type == _ENUM:
            values = field.enum_type.values
            schema = {
                "title": field.enum_type.full_name,
                "type": "integer",
                "oneOf": [{"title": value.name, "const": value.number} for value in values],
            }
        else:
            schema = _scalar(field.type)
        properties[field.name] = {"type": "array", "items": schema} if field.is_repeated else schema
    return {
        "title": descriptor.full_name,
        "type": "object",
        "properties": properties,
        "required": list(properties),
    }


def foxglove_class(name: str) -> Any:
    """Return the official protobuf class of ``foxglove.<Name>`` (ImportError when the package is missing)."""
    import importlib

    short = name.removeprefix("foxglove.")
    module = importlib.import_module(f"foxglove_schemas_protobuf.{short}_pb2")
    return getattr(module, short)


@cache
def descriptor_set(name: str) -> bytes:
    """Return the serialized ``FileDescriptorSet`` of a Foxglove type (its protobuf schema record in MCAP).

    Raises
    ------
    ImportError
        ``foxglove-schemas-protobuf`` is not installed.
    """
    from google.protobuf.descriptor_pb2 import FileDescriptorProto, FileDescriptorSet

    files = FileDescriptorSet()
    seen: set[str] = set()

    def add(file_descriptor: Any) -> None:
        if file_descriptor.name in seen:
            return
        seen.add(file_descriptor.name)
        for dependency in file_descriptor.dependencies:
            add(dependency)
        proto = FileDescriptorProto()
        file_descriptor.CopyToProto(proto)
        files.file.append(proto)

    add(foxglove_class(name).DESCRIPTOR.file)
    return files.SerializeToString()


@cache
def _vendored() -> dict[str, dict[str, Any]]:
    text = resources.files("ropecam.host.recording").joinpath(VENDORED).read_text(encoding="utf-8")
    return json.loads(text)["schemas"]


def _status() -> dict[str, Any]:
    def integer(description: str) -> dict[str, Any]:
        return {"type": "integer", "minimum": 0, "description": description}

    counter = {
        "title": "ropecam.Counter",
        "type": "object",
        "properties": {"name": {"type": "string"}, "value": {"type": "integer"}},
        "required": ["name", "value"],
    }
    properties = {
        "timestamp": _time("time") | {"description": "Device time of the status, on the host clock"},
        "device_id": {"type": "integer", "minimum": 0, "maximum": 65535},
        "frame_rate_hz": {"type": "number", "description": "Left out when unknown"},
        "frames_captured": integer("Frames the camera delivered"),
        "frames_dropped": integer("Frames the device lost"),
        "messages_dropped": integer("Messages the sender dropped"),
        "exposure_us": integer("Exposure time"),
        "gain": {"type": "number"},
        "uptime_ns": integer("Time since the daemon started"),
        "cpu_load": {"type": "number", "description": "Left out when unknown"},
        "temperature_c": {"type": "number", "description": "Left out when unknown"},
        "counters": {"type": "array", "items": counter, "description": "Further named counters"},
    }
    return {
        "title": "ropecam.Status",
        "description": "Device health, about once a second (see docs/protocol.md)",
        "type": "object",
        "properties": properties,
        "required": ["timestamp", "device_id", "frames_captured", "frames_dropped", "counters"],
    }


def _model_error() -> dict[str, Any]:
    point = {
        "title": "ropecam.ModelErrorPoint",
        "type": "object",
        "properties": {
            "s_m": {"type": "number", "minimum": 0, "description": "Material point (arc length from the fixed end)"},
            "error_begin_mm": {"type": "number", "minimum": 0, "description": "At exposure start; left out: not "
                               "measured, frame not OK or past the end of the model run"},
            "error_end_mm": {"type": "number", "minimum": 0, "description": "At exposure end; as error_begin_mm"},
        },
        "required": ["s_m"],
    }  # fmt: skip
    properties = {
        "timestamp": _time("time") | {"description": "Time of the exposure on the host clock"},
        "device_id": {"type": "integer", "minimum": 0, "maximum": 65535},
        "frame_index": {"type": "integer", "minimum": 0},
        "release_time_s": {"type": "number", "description": "Fitted release time on the device clock"},
        "model_time_begin_s": {"type": "number", "description": "At exposure start, s since the release; left out "
                               "past the end of the model run"},
        "model_time_end_s": {"type": "number", "description": "At exposure end; as model_time_begin_s"},
        "points": {"type": "array", "items": point, "description": "Distance from the model per material point"},
    }  # fmt: skip
    return {
        "title": "ropecam.ModelError",
        "description": "Distance of measured material points from the ANCF model (ropecam replay --model)",
        "type": "object",
        "properties": properties,
        "required": ["timestamp", "device_id", "frame_index", "release_time_s", "points"],
    }


ROPECAM_SCHEMAS: Final[dict[str, dict[str, Any]]] = {"ropecam.Status": _status(), "ropecam.ModelError": _model_error()}


def json_schema(name: str) -> dict[str, Any]:
    """Return the JSON Schema of a recorded type (a `FOXGLOVE_TYPES` name or a `ROPECAM_SCHEMAS` name).

    Raises
    ------
    KeyError
        An unknown name.
    """
    if name in ROPECAM_SCHEMAS:
        return ROPECAM_SCHEMAS[name]
    return _vendored()[name]


def schema_bytes(name: str, encoding: str = "jsonschema") -> bytes:
    """Return the MCAP schema data of `name` in `encoding` (``jsonschema`` or ``protobuf``).

    Raises
    ------
    KeyError
        An unknown name or a ropecam type asked for in protobuf.
    ImportError
        ``protobuf`` asked for without ``foxglove-schemas-protobuf`` installed.
    """
    if name == WIRE_SCHEMA:
        return wire_descriptor_set()
    if encoding == "protobuf":
        if name not in FOXGLOVE_TYPES:
            raise KeyError(f"{name} has no protobuf schema (only the Foxglove types {FOXGLOVE_TYPES} do)")
        return descriptor_set(name)
    return json.dumps(json_schema(name), separators=(",", ":")).encode()


def schema_record(name: str, message_encoding: str) -> tuple[str, bytes]:
    """Return (schema encoding, schema data) of the MCAP schema record of `name` for messages in `message_encoding`.

    Raises
    ------
    KeyError, ImportError
        As `schema_bytes`.
    """
    encoding = "protobuf" if message_encoding == "protobuf" else "jsonschema"
    return encoding, schema_bytes(name, encoding)


def vendored_file_text() -> str:
    """Return the content of ``foxglove_jsonschema.json`` derived from the installed official package."""
    import importlib.metadata

    schemas = {name: derive_json_schema(foxglove_class(name).DESCRIPTOR) for name in FOXGLOVE_TYPES}
    document = {
        "$comment": "JSON Schemas derived by ropecam.host.recording.schemas.derive_json_schema from the protobuf "
        f"descriptors of foxglove-schemas-protobuf {importlib.metadata.version('foxglove-schemas-protobuf')} "
        "(Foxglove schemas, MIT licence, https://github.com/foxglove/foxglove-sdk). Regenerate with "
        "`python -m ropecam.host.recording.schemas > host/recording/foxglove_jsonschema.json`.",
        "schemas": schemas,
    }
    return json.dumps(document, indent=1) + "\n"


if __name__ == "__main__":
    print(vendored_file_text(), end="")
