"""The envelope: header layout, CRC, and every kind of malformed message refused with a ProtocolError."""

from __future__ import annotations

import struct
import zlib

import pytest

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol import Log, MessageType, decode_message, encode_message
from ropecam.shared.protocol.bytecodec import ByteReader, ByteWriter, unzigzag, zigzag
from ropecam.shared.protocol.wire import HEADER_BYTES, MAX_PAYLOAD_BYTES, PROTOCOL_VERSION, peek_header


def _log_message(**kwargs: int) -> bytes:
    args = {"device_id": 513, "sequence": 0x01020304, "t_ns": -5, **kwargs}
    return encode_message(Log(20, "hello"), **args)


def test_header_layout_is_the_documented_one() -> None:
    data = _log_message()
    magic, version, kind, flags, device, sequence, t_ns, length = struct.unpack_from("<2sBBBHIqH", data)
    assert (magic, version, kind, flags) == (b"RC", PROTOCOL_VERSION, MessageType.LOG, 0)
    assert (device, sequence, t_ns, length) == (513, 0x01020304, -5, len(data) - HEADER_BYTES - 4)
    assert struct.unpack_from("<I", data, len(data) - 4)[0] == zlib.crc32(data[:-4])


@pytest.mark.parametrize(
    ("mutate", "fragment"),
    [
        (lambda d: b"XX" + d[2:], "magic"),
        (lambda d: d[:2] + b"\x09" + d[3:], "version"),
        (lambda d: d[:3] + b"\x63" + d[4:], "type"),
        (lambda d: d[:4] + b"\x80" + d[5:], "flags"),
        (lambda d: d[:-1], "bytes, header says"),
        (lambda d: d + b"\x00", "bytes, header says"),
        (lambda d: d[:10], "shorter"),
        (lambda d: d[:-6] + bytes([d[-6] ^ 1]) + d[-5:], "CRC"),
    ],
)
def test_malformed_messages_are_refused(mutate, fragment: str) -> None:
    with pytest.raises(ProtocolError, match=fragment):
        decode_message(mutate(_log_message()))


def test_payload_that_its_record_rejects_is_a_protocol_error() -> None:
    # A Log payload with trailing bytes and a correct CRC: the envelope is fine, the record is not.
    good = _log_message()
    payload = good[HEADER_BYTES:-4] + b"\x01"
    header = bytearray(good[:HEADER_BYTES])
    struct.pack_into("<H", header, 19, len(payload))
    body = bytes(header) + payload
    with pytest.raises(ProtocolError, match="trailing"):
        decode_message(body + struct.pack("<I", zlib.crc32(body)))


def test_argument_ranges_are_checked_when_encoding() -> None:
    with pytest.raises(ValueError, match="device_id"):
        _log_message(device_id=70000)
    with pytest.raises(ValueError, match="sequence"):
        _log_message(sequence=-1)
    with pytest.raises(ValueError, match="text"):
        Log(20, "x" * (MAX_PAYLOAD_BYTES + 1))


def test_peek_header_reads_without_crc() -> None:
    header = peek_header(_log_message())
    assert header.type is MessageType.LOG and header.device_id == 513


@pytest.mark.parametrize("value", [0, 1, -1, 63, -64, 64, 2**40, -(2**40), 2**62, -(2**62)])
def test_zigzag_varints_round_trip(value: int) -> None:
    assert unzigzag(zigzag(value)) == value
    writer = ByteWriter()
    writer.svarint(value)
    reader = ByteReader(writer.getvalue())
    assert reader.svarint("v") == value
    reader.finish("v")


def test_reader_refuses_overlong_and_truncated_varints() -> None:
    with pytest.raises(ProtocolError, match="longer"):
        ByteReader(b"\xff" * 11).uvarint("x")
    with pytest.raises(ProtocolError, match="truncated"):
        ByteReader(b"\x80").uvarint("x")
    with pytest.raises(ProtocolError, match="maximum"):
        ByteReader(b"\x05").uvarint("x", 4)
