"""COBS framing against the `cobs` package as oracle, and the deframer's resynchronisation."""

from __future__ import annotations

import contextlib
import random

import pytest
from cobs import cobs
from hypothesis import given, settings
from hypothesis import strategies as st

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol import Deframer, Log, cobs_decode, cobs_encode, decode_message, encode_message, frame


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=1200) | st.lists(st.sampled_from([0, 1, 255]), max_size=700).map(bytes))
def test_cobs_matches_the_reference_package(data: bytes) -> None:
    encoded = cobs_encode(data)
    assert encoded == cobs.encode(data)
    assert b"\x00" not in encoded
    assert cobs_decode(encoded) == data


@pytest.mark.parametrize("bad", [b"\x05\x01\x02", b"\x02\x00", b"\x00"])
def test_cobs_decode_refuses_invalid_input(bad: bytes) -> None:
    with pytest.raises(ProtocolError, match="COBS"):
        cobs_decode(bad)


def _messages(count: int) -> list[bytes]:
    return [encode_message(Log(20, f"message {i}" * (i % 5)), device_id=1, sequence=i, t_ns=i) for i in range(count)]


def test_deframer_splits_any_chunking() -> None:
    messages = _messages(50)
    stream = b"".join(frame(m) for m in messages)
    rng = random.Random(4)
    deframer = Deframer()
    out = []
    position = 0
    while position < len(stream):
        step = rng.randint(1, 40)
        out.extend(deframer.feed(stream[position : position + step]))
        position += step
    assert out == messages
    assert deframer.stats.frames == 50 and deframer.stats.bad_frames == 0


def test_deframer_resynchronises_after_garbage_and_overlong_runs() -> None:
    messages = _messages(3)
    deframer = Deframer(max_frame_bytes=500)
    stream = (
        b"garbage\xff\x13" + frame(messages[0]) + bytes(range(1, 256)) * 4 + frame(messages[1]) + frame(messages[2])
    )
    decoded = []
    for chunk in deframer.feed(stream):
        with contextlib.suppress(ProtocolError):  # the garbage frames
            decoded.append(decode_message(chunk))
    assert [m.header.sequence for m in decoded] == [0, 1, 2]
    assert deframer.stats.overlong == 1
