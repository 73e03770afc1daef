"""Fixtures of the recording tests: a demo-like recording (calibrated device stream) in either encoding, and a
Python port of the Foxglove app's JSON-schema loader."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

FRAMES = 20
"""Frames of the demo-like recording (a Status every 10)."""


def foxglove_parse_json_schema(schema: dict[str, Any], type_name: str) -> dict[str, list[dict[str, Any]]]:
    """Return the datatypes the Foxglove app derives from a JSON-schema channel, or raise ValueError where it fails.

    A port of the rules of ``parseJsonSchema`` (foxglove/studio and Lichtblick, packages/mcap-support/src/
    parseJsonSchema.ts): every object schema needs ``"type": "object"`` and ``properties``; a field is an enum
    (``oneOf`` whose alternatives all have a numeric ``const``), boolean, string (no contentEncoding or base64),
    number, integer, object (recursively), or array whose items are one of boolean, string without
    contentEncoding, number, integer or object; anything else (``null``, a list of types such as
    ``["number", "null"]``, no type) is an error.
    """
    datatypes: dict[str, list[dict[str, Any]]] = {}

    def add(node: dict[str, Any], name: str, path: list[str]) -> None:
        if node.get("type") != "object":
            raise ValueError(f'Expected "type": "object" for schema {name}, got {node.get("type")!r}')
        properties = node.get("properties")
        if not isinstance(properties, dict):  # Object.entries(undefined) throws in the app
            raise ValueError(f"schema {name} has no properties")
        fields: list[dict[str, Any]] = []
        for field_name, field in properties.items():
            where = ".".join([*path, field_name])
            if isinstance(field.get("oneOf"), list):
                if not all(isinstance(alt.get("const"), (int, float)) for alt in field["oneOf"]):
                    raise ValueError(f"Unsupported type for {where}: oneOf alternatives must have number values")
                fields += [{"name": a.get("title"), "type": "uint32", "isConstant": True} for a in field["oneOf"]]
                fields.append({"name": field_name, "type": "uint32"})
                continue
            kind = field.get("type")
            if kind == "boolean":
                fields.append({"name": field_name, "type": "bool"})
            elif kind == "string":
                if field.get("contentEncoding") not in (None, "base64"):
                    raise ValueError(f"Unsupported contentEncoding {field['contentEncoding']!r} in {where}")
                is_bytes = field.get("contentEncoding") == "base64"
                fields.append({"name": field_name, "type": "uint8" if is_bytes else "string", "isArray": is_bytes})
            elif kind in ("number", "integer"):
                fields.append({"name": field_name, "type": "float64" if kind == "number" else "uint32"})
            elif kind == "object":
                add(field, f"{name}.{field_name}", [*path, field_name])
                fields.append({"name": field_name, "type": f"{name}.{field_name}", "isComplex": True})
            elif kind == "array":
                items = field.get("items")
                item_kind = items.get("type") if isinstance(items, dict) else None
                if item_kind == "string" and items.get("contentEncoding") is not None:
                    raise ValueError(f"Unsupported contentEncoding for array item {where}")
                if item_kind == "object":
                    add(items, f"{name}.{field_name}", [*path, field_name])
                elif item_kind not in ("boolean", "string", "number", "integer"):
                    raise ValueError(f"Unsupported type {item_kind!r} for array item {where}")
                fields.append({"name": field_name, "type": item_kind, "isArray": True})
            else:
                raise ValueError(f"Unsupported type {kind!r} for {where}")
        datatypes[name] = fields

    add(schema, type_name, [])
    return datatypes


@pytest.fixture(name="foxglove_loader")
def foxglove_loader_fixture():
    """`foxglove_loader(schema, name)` -> datatypes; ValueError where the Foxglove app fails."""
    return foxglove_parse_json_schema


def demo_like_messages() -> list[tuple[bytes, int]]:
    """(wire bytes, receive time) of a device stream: a Log, FRAMES frames, Status messages and one raw image."""
    import numpy as np

    from ropecam.host.sim.stream import SimulatedDevice
    from ropecam.shared.protocol import encode_message, split_frame

    device = SimulatedDevice(5, fps=10.0, frame_count=FRAMES, seed=4)
    start_ns = 1_800_000_000_000_000_000
    messages = [(data, start_ns + round(offset_s * 1e9) + 2_500_000) for offset_s, data in device.messages(FRAMES)]
    image = (np.arange(64 * 48) % 251).astype(np.uint8).reshape(48, 64)
    for k, chunk in enumerate(split_frame(3, image, chunk_bytes=1000)):
        t_ns = start_ns + 10**9 + k
        messages.append((encode_message(chunk, device_id=5, sequence=1000 + k, t_ns=t_ns), t_ns + 2_500_000))
    return messages


def record(messages: list[tuple[bytes, int]], path: Path, encoding: str, calibrated: bool = True) -> Path:
    """Record `messages` through a `Session` (as `ropecam monitor --record` does) in `encoding`; return `path`."""
    from ropecam.host.receiver import check_packet
    from ropecam.host.recording.proto import make_encoder
    from ropecam.host.recording.writer import Recorder, RecordingConfig
    from ropecam.host.session import Session
    from ropecam.host.sim.rig_polylines import RIG_CAMERA, RIG_PLANE

    calibration = (RIG_CAMERA, RIG_PLANE) if calibrated else None
    session = Session(Recorder(RecordingConfig(path)), calibration, encoder=make_encoder(encoding))
    for data, receive_t_ns in messages:
        session.handle(check_packet(data, receive_t_ns))
    session.close()
    return path


@pytest.fixture(name="record")
def record_fixture():
    """`record(messages, path, encoding, calibrated=True)` -> path (see `record`)."""
    return record


@pytest.fixture
def frames() -> int:
    """Frames in the demo-like stream."""
    return FRAMES


@pytest.fixture(scope="module")
def stream() -> list[tuple[bytes, int]]:
    """The demo-like stream (see `demo_like_messages`)."""
    return demo_like_messages()


@pytest.fixture(scope="module", params=["protobuf", "json"])
def recording(request, stream, tmp_path_factory) -> tuple[str, Path]:
    """(encoding, path) of the demo-like stream recorded with a plane calibration."""
    folder = tmp_path_factory.mktemp(f"rec-{request.param}")
    return request.param, record(stream, folder / "run.mcap", request.param)
