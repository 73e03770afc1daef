"""The raw wire channel ``/ropecam/wire``: every received message byte for byte, in a form viewers read silently.

Each wire message is stored as a protobuf ``ropecam.WireMessage { bytes data = 1; }``: a well-known message
encoding with its schema in the file, so Foxglove and other MCAP viewers list the channel without an error (it
holds opaque bytes; `ropecam replay` is what decodes them). Recordings made before this stored the bytes bare, with
the message encoding ``ropecam.wire.v1``; `unwrap` reads both. The protobuf encoding of this one-field message is
written and read here directly (tag, length, bytes), so neither needs the protobuf library; the schema record is the
``FileDescriptorSet`` of the message, also built here (`descriptor_set`), and a test parses it with protobuf.
"""

from __future__ import annotations

from typing import Final

from ropecam.shared.errors import DataError

__all__ = ["LEGACY_ENCODING", "RAW_TOPIC", "WIRE_ENCODING", "WIRE_SCHEMA", "descriptor_set", "unwrap", "wrap"]

RAW_TOPIC: Final = "/ropecam/wire"
WIRE_SCHEMA: Final = "ropecam.WireMessage"
WIRE_ENCODING: Final = "protobuf"
LEGACY_ENCODING: Final = "ropecam.wire.v1"
"""Message encoding of the bare bytes in older recordings (no schema)."""
_DATA_TAG: Final = b"\x0a"  # field 1, wire type 2 (length-delimited)


def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def _field(number: int, payload: bytes | str | int) -> bytes:
    if isinstance(payload, int):
        return _varint(number << 3) + _varint(payload)
    data = payload.encode() if isinstance(payload, str) else payload
    return _varint(number << 3 | 2) + _varint(len(data)) + data


def wrap(data: bytes) -> bytes:
    """Return `data` as an encoded ``ropecam.WireMessage``."""
    return _DATA_TAG + _varint(len(data)) + data if data else b""  # proto3 leaves an empty field out


def unwrap(message: bytes, message_encoding: str) -> bytes:
    """Return the wire bytes of a raw-channel message stored with `message_encoding`.

    Raises
    ------
    DataError
        An unknown encoding, or a ``ropecam.WireMessage`` that is not one (wrong tag, length past the end).
    """
    if message_encoding == LEGACY_ENCODING:
        return bytes(message)
    if message_encoding != WIRE_ENCODING:
        raise DataError(f"{RAW_TOPIC} has message encoding {message_encoding!r}; expected {WIRE_ENCODING!r}")
    if not message:
        return b""
    if message[:1] != _DATA_TAG:
        raise DataError(f"{RAW_TOPIC} message starts with byte {message[0]:#04x}; expected the data field tag 0x0a")
    length, shift, position = 0, 0, 1
    while position < len(message):
        byte = message[position]
        position += 1
        length |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            break
    if position + length != len(message):
        raise DataError(f"{RAW_TOPIC} message of {len(message)} bytes holds a data field of {length} bytes")
    return bytes(message[position:])


def descriptor_set() -> bytes:
    """Return the serialized ``FileDescriptorSet`` declaring ``ropecam.WireMessage`` (the channel's schema data)."""
    field = _field(1, "data") + _field(3, 1) + _field(4, 1) + _field(5, 12) + _field(10, "data")  # bytes, optional
    message = _field(1, "WireMessage") + _field(2, field)
    file = _field(1, "ropecam/WireMessage.proto") + _field(2, "ropecam") + _field(4, message) + _field(12, "proto3")
    return _field(1, file)
