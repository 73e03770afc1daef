"""The message envelope: fixed little-endian header, payload, optional authentication trailer, CRC-32.

Layout of one message (all integers little-endian)::

    offset size field
    0      2    magic            b"RC"
    2      1    version          PROTOCOL_VERSION (2; 1 is read too: only FrameResult's payload differs)
    3      1    type             MessageType
    4      1    flags            bit 0: authenticated (trailer present); other bits must be 0
    5      2    device id        uint16
    7      4    sequence         uint32, per device and stream, wraps
    11     8    t_ns             int64, device clock when the message was made
    19     2    payload length   uint16, <= MAX_PAYLOAD_BYTES
    21     n    payload          the record (`records`)
    21+n   24   trailer          only when authenticated: counter uint64, HMAC-SHA256 tag truncated to 16 bytes
    ...    4    crc32            zlib CRC-32 of everything before it

One UDP datagram carries one message; serial wraps the same bytes in COBS framing (`framing`).
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import TYPE_CHECKING, Any, ClassVar, Final, Protocol

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.bytecodec import check_int

if TYPE_CHECKING:
    from ropecam.shared.protocol.auth import Signer

__all__ = [
    "AUTH_TRAILER_BYTES",
    "CRC_BYTES",
    "HEADER",
    "HEADER_BYTES",
    "MAGIC",
    "MAX_MESSAGE_BYTES",
    "MAX_PAYLOAD_BYTES",
    "PROTOCOL_VERSION",
    "SUPPORTED_VERSIONS",
    "TAG_BYTES",
    "Header",
    "HeaderFlags",
    "Message",
    "MessageType",
    "Record",
    "decode_message",
    "encode_message",
    "peek_header",
    "record_class",
    "register_record",
]

MAGIC: Final = b"RC"
PROTOCOL_VERSION: Final = 2
SUPPORTED_VERSIONS: Final = frozenset({1, 2})
HEADER: Final = struct.Struct("<2sBBBHIqH")
HEADER_BYTES: Final = HEADER.size
TAG_BYTES: Final = 16
COUNTER: Final = struct.Struct("<Q")
AUTH_TRAILER_BYTES: Final = COUNTER.size + TAG_BYTES
CRC: Final = struct.Struct("<I")
CRC_BYTES: Final = CRC.size
MAX_PAYLOAD_BYTES: Final = 16384
MAX_MESSAGE_BYTES: Final = HEADER_BYTES + MAX_PAYLOAD_BYTES + AUTH_TRAILER_BYTES + CRC_BYTES
_U16: Final = 0xFFFF
_U32: Final = 0xFFFF_FFFF
_I64: Final = 1 << 63


class MessageType(IntEnum):
    """Kinds of message; the byte after the version."""

    FRAME_RESULT = 1
    STATUS = 2
    LOG = 3
    CONTROL = 4
    CONTROL_ACK = 5
    RAW_FRAME_CHUNK = 6


class HeaderFlags(IntFlag):
    """Bits of the header's flags byte."""

    NONE = 0
    AUTHENTICATED = 1


@dataclass(frozen=True, slots=True)
class Header:
    """The fixed header of a message (see the module docstring for the layout)."""

    type: MessageType
    device_id: int
    sequence: int
    t_ns: int
    payload_length: int
    flags: HeaderFlags = HeaderFlags.NONE
    version: int = PROTOCOL_VERSION

    def pack(self) -> bytes:
        """Return the 21 header bytes."""
        return HEADER.pack(
            MAGIC, self.version, self.type, self.flags, self.device_id, self.sequence, self.t_ns, self.payload_length
        )


_MESSAGE_TYPES: Final = {int(member): member for member in MessageType}
_HEADER_FLAGS: Final = {int(flags): flags for flags in (HeaderFlags.NONE, HeaderFlags.AUTHENTICATED)}
"""The valid flags bytes (checked before): an IntFlag lookup instead of its slow constructor per message."""


class Record(Protocol):
    """What every message body is: a frozen dataclass with a type tag, `pack` and `unpack`."""

    TYPE: ClassVar[MessageType]

    def pack(self, t_ns_ref: int = 0) -> bytes:
        """Return the payload bytes; `t_ns_ref` is the header's t_ns (records may code times relative to it)."""
        ...

    @classmethod
    def unpack(cls, payload: bytes, t_ns_ref: int = 0) -> Record:
        """Parse payload bytes; raise `ProtocolError` on anything malformed."""
        ...


_RECORDS: dict[MessageType, type] = {}


def register_record(cls: type) -> type:
    """Class decorator: make `cls` the record type of ``cls.TYPE`` for `decode_message`."""
    message_type = cls.TYPE
    if message_type in _RECORDS and _RECORDS[message_type] is not cls:
        raise ValueError(f"{message_type.name} already has record type {_RECORDS[message_type].__name__}")
    _RECORDS[message_type] = cls
    return cls


def record_class(message_type: MessageType) -> type:
    """Return the record type registered for `message_type`."""
    record = _RECORDS.get(message_type)
    if record is None or len(_RECORDS) < len(MessageType):
        import ropecam.shared.protocol.records  # noqa: F401  (registers the record types)

        record = _RECORDS[message_type]
    return record


@dataclass(frozen=True, slots=True)
class Message:
    """A decoded message: its header, its record and, when authenticated, the counter and tag.

    `signed_bytes` is the span the tag covers (header, payload, counter); `auth.Verifier` checks it.
    """

    header: Header
    record: Record
    counter: int | None = None
    tag: bytes | None = None
    signed_bytes: bytes | None = None

    @property
    def authenticated(self) -> bool:
        """True when the message carries a tag (not yet whether the tag is valid)."""
        return self.tag is not None


def encode_message(
    record: Record,
    *,
    device_id: int,
    sequence: int,
    t_ns: int,
    signer: Signer | None = None,
    pack_options: Mapping[str, Any] | None = None,
    version: int = PROTOCOL_VERSION,
) -> bytes:
    """Return the complete bytes of one message carrying `record`.

    Parameters
    ----------
    record
        A record instance (`records`).
    device_id
        Sender (data) or addressee (control), 0..65535.
    sequence
        Per-device sequence number, 0..2**32-1 (the sender wraps it).
    t_ns
        Device (or host) clock when the message was made, int64 nanoseconds.
    signer
        Adds the authentication trailer (required for control messages the device should accept).
    pack_options
        Extra keyword arguments of the record's `pack` (FrameResult: ``shape_config``, ``hint``).
    version
        Protocol version written in the header (one of SUPPORTED_VERSIONS; a record whose payload changed
        between versions, ``VERSIONED``, is packed in that version).

    Raises
    ------
    ValueError
        An argument is out of range, or the payload exceeds MAX_PAYLOAD_BYTES.
    """
    device_id = check_int("device_id", device_id, high=_U16)
    sequence = check_int("sequence", sequence, high=_U32)
    t_ns = check_int("t_ns", t_ns, low=-_I64, high=_I64 - 1)
    if version not in SUPPORTED_VERSIONS:
        raise ValueError(f"version must be one of {sorted(SUPPORTED_VERSIONS)}, got {version!r}")
    options = dict(pack_options or {})
    if getattr(record, "VERSIONED", False):
        options["version"] = version
    payload = record.pack(t_ns, **options)
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise ValueError(f"{type(record).__name__} payload is {len(payload)} bytes, more than {MAX_PAYLOAD_BYTES}")
    flags = HeaderFlags.AUTHENTICATED if signer is not None else HeaderFlags.NONE
    header = Header(record.TYPE, device_id, sequence, t_ns, len(payload), flags, version).pack()
    body = header + payload
    if signer is not None:
        counter = signer.next_counter()
        signed = body + COUNTER.pack(counter)
        body = signed + signer.tag(signed)
    return body + CRC.pack(zlib.crc32(body))


def peek_header(data: bytes | bytearray | memoryview) -> Header:
    """Parse and check the header of `data` (magic, version, type, flags, length) without the CRC.

    Raises
    ------
    ProtocolError
        Too short, bad magic, unsupported version, unknown type or flags, or a length that disagrees with `data`.
    """
    if len(data) < HEADER_BYTES + CRC_BYTES:
        raise ProtocolError(f"message of {len(data)} bytes is shorter than header and CRC ({HEADER_BYTES + CRC_BYTES})")
    magic, version, type_code, flags, device_id, sequence, t_ns, length = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise ProtocolError(f"bad magic {bytes(magic)!r}, expected {MAGIC!r}")
    if version not in SUPPORTED_VERSIONS:
        raise ProtocolError(f"unsupported protocol version {version} (supported: {sorted(SUPPORTED_VERSIONS)})")
    message_type = _MESSAGE_TYPES.get(type_code)
    if message_type is None:
        raise ProtocolError(f"unknown message type {type_code}")
    if flags & ~int(HeaderFlags.AUTHENTICATED):
        raise ProtocolError(f"unknown header flags 0x{flags:02x}")
    if length > MAX_PAYLOAD_BYTES:
        raise ProtocolError(f"payload length {length} exceeds {MAX_PAYLOAD_BYTES}")
    trailer = AUTH_TRAILER_BYTES if flags & HeaderFlags.AUTHENTICATED else 0
    expected = HEADER_BYTES + length + trailer + CRC_BYTES
    if len(data) != expected:
        raise ProtocolError(f"message is {len(data)} bytes, header says {expected} (payload {length})")
    return Header(message_type, device_id, sequence, t_ns, length, _HEADER_FLAGS[flags], version)


def decode_message(data: bytes | bytearray | memoryview) -> Message:
    """Check and parse one complete message (the bytes of one datagram or one deframed serial frame).

    Raises
    ------
    ProtocolError
        Anything malformed: header (see `peek_header`), CRC mismatch, or a payload its record type rejects.
        Nothing else escapes, whatever the bytes.
    """
    data = bytes(data)
    header = peek_header(data)
    (crc,) = CRC.unpack_from(data, len(data) - CRC_BYTES)
    actual = zlib.crc32(memoryview(data)[: len(data) - CRC_BYTES])
    if crc != actual:
        raise ProtocolError(f"CRC mismatch: message says 0x{crc:08x}, bytes give 0x{actual:08x}")
    payload_end = HEADER_BYTES + header.payload_length
    payload = data[HEADER_BYTES:payload_end]
    counter = tag = signed = None
    if header.flags & HeaderFlags.AUTHENTICATED:
        (counter,) = COUNTER.unpack_from(data, payload_end)
        signed = data[: payload_end + COUNTER.size]
        tag = data[payload_end + COUNTER.size : payload_end + AUTH_TRAILER_BYTES]
    try:
        cls = record_class(header.type)
        if getattr(cls, "VERSIONED", False):
            record = cls.unpack(payload, header.t_ns, header.version)
        else:
            record = cls.unpack(payload, header.t_ns)
    except (ValueError, TypeError, OverflowError) as exc:
        # Records validate their fields in __post_init__; on the wire a rejected value is a protocol error.
        raise ProtocolError(f"{header.type.name} payload holds an invalid value: {exc}") from exc
    return Message(header, record, counter, tag, signed)
