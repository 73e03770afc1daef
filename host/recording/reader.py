"""Reading ropecam recordings (MCAP): the parts of a rolled recording, the raw wire messages in recorded order, one
device's FrameResults, and every channel decoded (JSON or protobuf). Used by `ropecam replay`, `ropecam compare`
and the tests."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ropecam.shared.errors import DataError

if TYPE_CHECKING:
    from ropecam.shared.protocol.records import FrameResult

__all__ = ["MessageDecoder", "count_raw", "decoded_messages", "device_frames", "iter_raw", "recording_parts"]


def recording_parts(path: Path) -> list[Path]:
    """Return `path` and the later parts of its rolled recording (``<stem>_001<suffix>``, ...) that exist.

    Raises
    ------
    DataError
        `path` does not exist, or a following part carries another recording's id or the wrong part index (a
        leftover of an earlier run: the message names it).
    """
    from ropecam.host.recording.writer import part_path, read_part_id

    if not path.exists():
        raise DataError(f"recording {path} does not exist")
    parts = [path]
    first = read_part_id(path)
    while (following := part_path(path, len(parts))).exists():
        if first is not None:
            found = read_part_id(following)
            if found != (first[0], len(parts)):
                what = "no recording id" if found is None else f"recording {found[0]} part {found[1]}"
                raise DataError(
                    f"{following} does not belong to the recording {path} (id {first[0]}): it holds {what}; "
                    "move it away to replay the recording, or replay it on its own"
                )
        parts.append(following)
    return parts


def iter_raw(paths: Sequence[Path]) -> Iterator[tuple[bytes, int]]:
    """Yield (wire bytes, receive time ns) of every raw-channel message of the files, in recorded order.

    Reads the raw channel of this version (``ropecam.WireMessage``, protobuf) and of older ones (bare bytes).

    Raises
    ------
    DataError
        A file cannot be read as MCAP (for a crashed recording, run `ropecam recover` first), holds no raw channel,
        or a raw message in an unknown encoding.
    """
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    from ropecam.host.recording.wire import RAW_TOPIC, unwrap

    found = False
    for path in paths:
        try:
            with open(path, "rb") as handle:
                reader = make_reader(handle)
                for _, channel, message in reader.iter_messages(topics=[RAW_TOPIC], log_time_order=False):
                    found = True
                    yield unwrap(message.data, channel.message_encoding), message.log_time
        except (McapError, OSError, EOFError) as exc:
            raise DataError(
                f"cannot read {path}: {exc} (a recording cut by a crash: `ropecam recover {path} --out FIXED.mcap`)"
            ) from exc
    if not found:
        raise DataError(f"{', '.join(map(str, paths))} hold no {RAW_TOPIC} messages: not a ropecam recording?")


def count_raw(paths: Sequence[Path]) -> int:
    """Return the number of raw-channel messages of complete recordings (from their summaries; 0 when unknown)."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    from ropecam.host.recording.wire import RAW_TOPIC

    total = 0
    for path in paths:
        try:
            with open(path, "rb") as handle:
                summary = make_reader(handle).get_summary()
        except (McapError, OSError, EOFError):
            return 0
        if summary is None or summary.statistics is None:
            return 0
        counts = summary.statistics.channel_message_counts
        total += sum(counts.get(c.id, 0) for c in summary.channels.values() if c.topic == RAW_TOPIC)
    return total


def device_frames(
    messages: Iterable[tuple[bytes, int]], device_id: int | None = None
) -> tuple[list[FrameResult], int | None]:
    """Return one device's distinct FrameResults (by exposure start) and its id (default: the first device seen).

    A frame is identified by (frame index, exposure start): a message received twice counts once, while the frames
    of a device that restarted within the recording (sequence numbers and frame indices from 0 again) are all kept.
    Undecodable messages are skipped.
    """
    from ropecam.shared.errors import ProtocolError
    from ropecam.shared.protocol.records import FrameResult
    from ropecam.shared.protocol.wire import decode_message

    frames: dict[tuple[int, int], FrameResult] = {}
    for data, _ in messages:
        try:
            message = decode_message(data)
        except ProtocolError:
            continue
        if not isinstance(message.record, FrameResult):
            continue
        if device_id is None:
            device_id = message.header.device_id
        if message.header.device_id == device_id:
            record = message.record
            frames.setdefault((record.frame_index, record.exposure_start_t_ns), record)
    return sorted(frames.values(), key=lambda f: f.exposure_start_t_ns), device_id


def _proto_to_dict(message: Any) -> dict[str, Any]:
    """Return a protobuf message as the JSON form of the Foxglove schemas (every field; time as sec/nsec)."""
    import base64

    def value(field: Any, item: Any) -> Any:
        if field.type == field.TYPE_MESSAGE:
            if field.message_type.full_name in ("google.protobuf.Timestamp", "google.protobuf.Duration"):
                return {"sec": item.seconds, "nsec": item.nanos}
            return _proto_to_dict(item)
        if field.type == field.TYPE_BYTES:
            return base64.b64encode(item).decode("ascii")
        return item

    out: dict[str, Any] = {}
    for field in message.DESCRIPTOR.fields:
        current = getattr(message, field.name)
        out[field.name] = [value(field, item) for item in current] if field.is_repeated else value(field, current)
    return out


class MessageDecoder:
    """Decode the recorded messages of any channel to dicts (JSON as is, protobuf with the file's own schema).

    Protobuf messages come out in the JSON layout of the Foxglove schemas (every field present, ``time`` as
    ``{"sec", "nsec"}``, bytes as base64, enums as numbers), so the two encodings of a message compare equal.
    """

    def __init__(self) -> None:
        self._classes: dict[int, Any] = {}

    def decode(self, schema: Any, channel: Any, data: bytes) -> dict[str, Any]:
        """Return one message as a dict.

        Raises
        ------
        DataError
            A message encoding other than json and protobuf, or a message that does not parse.
        """
        import json

        encoding = channel.message_encoding
        if encoding == "json":
            try:
                return json.loads(data)
            except ValueError as exc:
                raise DataError(f"{channel.topic}: a message is not JSON: {exc}") from exc
        if encoding != "protobuf" or schema is None:
            raise DataError(f"{channel.topic}: cannot decode message encoding {encoding!r}")
        cls = self._classes.get(schema.id)
        if cls is None:
            from google.protobuf import descriptor_pool, message_factory
            from google.protobuf.descriptor_pb2 import FileDescriptorSet

            files = FileDescriptorSet.FromString(schema.data)
            pool = descriptor_pool.DescriptorPool()
            for file in files.file:
                pool.Add(file)
            cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
            self._classes[schema.id] = cls
        from google.protobuf.message import DecodeError

        try:
            return _proto_to_dict(cls.FromString(data))
        except DecodeError as exc:
            raise DataError(f"{channel.topic}: a message does not parse as {schema.name}: {exc}") from exc


def decoded_messages(path: Path) -> Iterator[tuple[str, str | None, int, int, dict[str, Any]]]:
    """Yield (topic, schema name, log time, publish time, message as dict) of every message of a complete file.

    The raw wire channel comes out as ``{"data": base64}``.
    """
    from mcap.reader import make_reader

    decoder = MessageDecoder()
    with open(path, "rb") as handle:
        for schema, channel, message in make_reader(handle).iter_messages(log_time_order=False):
            decoded = decoder.decode(schema, channel, message.data)
            name = schema.name if schema is not None else None
            yield channel.topic, name, message.log_time, message.publish_time, decoded
