"""Recordings open in Foxglove without an error: every schema parses with the app's JSON-schema rules (or is a
protobuf descriptor set), every Foxglove message is valid against the official schemas (derived from the installed
foxglove-schemas-protobuf), the raw wire bytes round-trip, and both encodings hold the same messages."""

from __future__ import annotations

import base64
import json
import math
import re
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from ropecam.host.cli import main
from ropecam.host.recording.reader import decoded_messages, iter_raw
from ropecam.host.recording.schemas import (
    FOXGLOVE_TYPES,
    ROPECAM_SCHEMAS,
    VENDORED,
    derive_json_schema,
    foxglove_class,
    json_schema,
    vendored_file_text,
)
from ropecam.host.recording.wire import LEGACY_ENCODING, WIRE_SCHEMA, descriptor_set, unwrap, wrap
from ropecam.shared.errors import DataError


def official_schema(name: str) -> dict[str, Any]:
    """The current official JSON Schema of a Foxglove type, derived from the installed protobuf package."""
    return derive_json_schema(foxglove_class(name).DESCRIPTOR)


def _summary(path: Path) -> Any:
    from mcap.reader import make_reader

    with open(path, "rb") as handle:
        return make_reader(handle).get_summary()


def test_the_loader_port_rejects_what_the_foxglove_app_rejects(foxglove_loader) -> None:
    nullable = {"type": "object", "properties": {"frame_rate_hz": {"type": ["number", "null"]}}}
    with pytest.raises(ValueError, match=r"Unsupported type \['number', 'null'\] for frame_rate_hz"):
        foxglove_loader(nullable, "ropecam.Status")
    with pytest.raises(ValueError, match="has no properties"):
        foxglove_loader({"type": "object", "properties": {"counters": {"type": "object"}}}, "ropecam.Status")
    with pytest.raises(ValueError, match="array item"):
        foxglove_loader(
            {"type": "object", "properties": {"e": {"type": "array", "items": {"type": ["number", "null"]}}}}, "x"
        )
    with pytest.raises(ValueError, match="oneOf"):
        foxglove_loader({"type": "object", "properties": {"e": {"oneOf": [{"const": "a"}]}}}, "x")
    parsed = foxglove_loader(json_schema("foxglove.SceneUpdate"), "foxglove.SceneUpdate")
    assert {f["name"] for f in parsed["foxglove.SceneUpdate.entities"]} >= {"lines", "spheres", "arrows", "models"}


def test_vendored_json_schemas_are_the_ones_derived_from_the_installed_official_package() -> None:
    shipped = json.loads((Path(__file__).parents[3] / "host" / "recording" / VENDORED).read_text())
    assert shipped["schemas"] == json.loads(vendored_file_text())["schemas"]
    for name in FOXGLOVE_TYPES:
        assert json_schema(name) == official_schema(name)
    # the current release requires every field: a scene entity lists even the primitives ropecam never draws
    entity = official_schema("foxglove.SceneUpdate")["properties"]["entities"]["items"]
    assert {"arrows", "cubes", "cylinders", "triangles", "texts", "models"} <= set(entity["required"])


def test_every_schema_parses_and_every_message_is_valid(recording, foxglove_loader, frames: int) -> None:
    from google.protobuf import descriptor_pool
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    encoding, path = recording
    summary = _summary(path)
    failures = []
    for schema in summary.schemas.values():
        try:
            if schema.encoding == "jsonschema":
                document = json.loads(schema.data)
                jsonschema.Draft202012Validator.check_schema(document)
                foxglove_loader(document, schema.name)
            else:
                assert schema.encoding == "protobuf", schema.encoding
                pool = descriptor_pool.DescriptorPool()
                for file in FileDescriptorSet.FromString(schema.data).file:
                    pool.Add(file)
                pool.FindMessageTypeByName(schema.name)
        except (ValueError, KeyError, AssertionError, jsonschema.SchemaError) as exc:
            failures.append(f"schema {schema.name}: {exc}")
    assert {c.message_encoding for c in summary.channels.values()} <= {"json", "protobuf"}  # viewers know both
    assert all(c.schema_id != 0 for c in summary.channels.values())

    validators = {name: jsonschema.Draft202012Validator(official_schema(name)) for name in FOXGLOVE_TYPES}
    validators |= {name: jsonschema.Draft202012Validator(schema) for name, schema in ROPECAM_SCHEMAS.items()}
    counts: dict[str, int] = {}
    for topic, name, _, _, message in decoded_messages(path):
        counts[name] = counts.get(name, 0) + 1
        if name == WIRE_SCHEMA:
            continue
        failures += [f"{topic} ({name}): {error.message}" for error in validators[name].iter_errors(message)]
    assert failures == []
    assert counts["foxglove.SceneUpdate"] == 2 * frames  # pixels and metres
    assert counts["foxglove.PointCloud"] == 2 * frames
    assert counts["foxglove.FrameTransforms"] >= 2 and counts["foxglove.RawImage"] == 1
    assert counts["foxglove.Log"] == 1 and counts["ropecam.Status"] == 2
    frame_channels = [c for c in summary.channels.values() if c.topic != "/ropecam/wire"]
    assert {c.message_encoding for c in frame_channels if c.topic.endswith("scene")} == {encoding}


def test_the_layout_beside_the_recording_names_its_topics_and_frames(recording) -> None:
    from ropecam.host.recording.layout import layout_path

    _, path = recording
    layout = json.loads(layout_path(path).read_text())
    text = json.dumps(layout)
    topics = {c.topic for c in _summary(path).channels.values()}
    named = set(re.findall(r'"(/device[^".\[]+)', text)) | {layout["configById"]["RosOut!ropecam-log"]["topicToRender"]}
    model_topics = {"/device5/plane/model", "/device5/model_error"}  # recorded with --model only
    assert named - model_topics <= topics and "@DEVICE@" not in text
    frames = {t["child_frame_id"] for _, name, _, _, m in decoded_messages(path) if name == "foxglove.FrameTransforms"
              for t in m["transforms"]} | {"device5/plane"}  # fmt: skip
    assert layout["configById"]["3D!ropecam-scene"]["followTf"] in frames


def test_the_wire_channel_is_a_valid_protobuf_message() -> None:
    from google.protobuf import descriptor_pool, message_factory
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    pool = descriptor_pool.DescriptorPool()
    for file in FileDescriptorSet.FromString(descriptor_set()).file:
        pool.Add(file)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(WIRE_SCHEMA))
    for size in (0, 1, 127, 128, 300, 20_000, 70_000):
        data = bytes(range(256)) * (size // 256) + bytes(size % 256)
        assert wrap(data) == cls(data=data).SerializeToString()
        assert unwrap(wrap(data), "protobuf") == data == cls.FromString(wrap(data)).data
    assert unwrap(b"\x01\x02", LEGACY_ENCODING) == b"\x01\x02"
    with pytest.raises(DataError, match="0x12"):
        unwrap(b"\x12\x01a", "protobuf")
    with pytest.raises(DataError, match="data field of 5 bytes"):
        unwrap(b"\x0a\x05abc", "protobuf")
    with pytest.raises(DataError, match=r"ropecam\.wire\.v2"):
        unwrap(b"", "ropecam.wire.v2")


def test_raw_wire_bytes_round_trip_through_replay(recording, stream, tmp_path: Path) -> None:
    encoding, path = recording
    sent = [data for data, _ in stream]
    assert [data for data, _ in iter_raw([path])] == sent
    out = tmp_path / "again.mcap"
    assert main(["replay", str(path), "--record", str(out), "--encoding", encoding]) == 0
    assert [(data, t) for data, t in iter_raw([out])] == stream
    assert (tmp_path / "again.layout.json").is_file()


def _same(a: Any, b: Any, tolerance: float, path: str = "") -> list[str]:
    """Differences between two decoded messages; numbers within `tolerance` are equal."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: fields {sorted(set(a) ^ set(b))}"]
        return [d for key in a for d in _same(a[key], b[key], tolerance, f"{path}.{key}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} != {len(b)} items"]
        return [d for k, (x, y) in enumerate(zip(a, b, strict=True)) for d in _same(x, y, tolerance, f"{path}[{k}]")]
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return [] if math.isclose(a, b, rel_tol=1e-9, abs_tol=tolerance) else [f"{path}: {a} != {b}"]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


def test_both_encodings_hold_the_same_messages_and_protobuf_is_at_most_half_the_bytes(
    stream, tmp_path: Path, record, frames: int
) -> None:
    files = {encoding: record(stream, tmp_path / f"{encoding}.mcap", encoding) for encoding in ("json", "protobuf")}
    decoded = {encoding: list(decoded_messages(path)) for encoding, path in files.items()}
    assert [m[:4] for m in decoded["json"]] == [m[:4] for m in decoded["protobuf"]]  # topics, schemas, times
    # JSON: 1e-6 px / 1e-9 m decimals; protobuf: a 2^-7 px / 2^-17 m grid (half a step off at most)
    differences = []
    for j, p in zip(decoded["json"], decoded["protobuf"], strict=True):
        tolerance = 2**-18 + 1e-9 if "/plane/" in j[0] else 2**-8 + 1e-6
        differences += _same(j[4], p[4], tolerance, j[0])
    assert differences == []
    clouds = [m[4]["data"] for m in decoded["json"] if m[1] == "foxglove.PointCloud"]
    assert clouds == [m[4]["data"] for m in decoded["protobuf"] if m[1] == "foxglove.PointCloud"]
    assert base64.b64decode(clouds[0])

    def chunk_bytes(path: Path) -> int:
        return sum(index.compressed_size for index in _summary(path).chunk_indexes)

    per_frame = {encoding: chunk_bytes(path) / frames for encoding, path in files.items()}
    assert per_frame["protobuf"] <= 0.5 * per_frame["json"], per_frame
