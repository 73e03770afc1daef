"""A short, bounded fuzz run (the long one is tools/fuzz.py protocol): only ProtocolError may escape the decoder,
nothing may escape the deframer."""

from __future__ import annotations

import contextlib
import random
import struct
import zlib

from hypothesis import given, settings
from hypothesis import strategies as st

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol import Deframer, decode_message, encode_message, frame
from ropecam.shared.protocol.examples import example_records
from ropecam.shared.protocol.wire import CRC_BYTES, HEADER_BYTES

CORPUS = [
    encode_message(record, device_id=1, sequence=i, t_ns=10**15) for i, record in enumerate(example_records().values())
]


def _repair(data: bytearray) -> bytes:
    if len(data) >= HEADER_BYTES + CRC_BYTES:
        length = len(data) - HEADER_BYTES - CRC_BYTES - (24 if data[4] & 1 else 0)
        if 0 <= length <= 0xFFFF:
            struct.pack_into("<H", data, 19, length)
        body = bytes(data[:-CRC_BYTES])
        return body + struct.pack("<I", zlib.crc32(body))
    return bytes(data)


def _check(data: bytes, deframer: Deframer) -> None:
    with contextlib.suppress(ProtocolError):
        decode_message(data)
    for chunk in deframer.feed(data + frame(data)):
        with contextlib.suppress(ProtocolError):
            decode_message(chunk)


def test_mutated_messages_with_repaired_crc() -> None:
    rng = random.Random(20)
    deframer = Deframer()
    for _ in range(3000):
        data = bytearray(rng.choice(CORPUS))
        for _ in range(rng.randint(1, 4)):
            position = rng.randrange(len(data))
            operation = rng.randrange(3)
            if operation == 0:
                data[position] ^= 1 << rng.randrange(8)
            elif operation == 1:
                data[position : position + 1] = rng.randbytes(rng.randint(0, 3))
            else:
                data[position] = rng.choice((0, 0x7F, 0x80, 0xFF))
        _check(_repair(data), deframer)
        _check(bytes(data), deframer)


@settings(max_examples=500, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes(data: bytes) -> None:
    _check(data, Deframer())
    _check(_repair(bytearray(b"RC\x01" + data)), Deframer())
