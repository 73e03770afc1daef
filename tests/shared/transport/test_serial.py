"""Serial specifics on a real pty: a full line drops whole messages (counted), never blocks, never truncates."""

from __future__ import annotations

import os
import pty

import pytest

from ropecam.shared.errors import TransportError
from ropecam.shared.protocol import Deframer, Log, decode_message, encode_message
from ropecam.shared.transport import open_transport


@pytest.fixture
def pty_port():
    master, slave = pty.openpty()
    name = os.ttyname(slave)
    os.close(slave)
    os.set_blocking(master, False)
    yield master, name
    os.close(master)


def test_full_line_drops_whole_messages_and_counts_them(pty_port, read_available) -> None:
    master, name = pty_port
    link = open_transport(f"serial://{name}?baud=921600")
    try:
        attempts = 2000
        results = [
            link.send(encode_message(Log(20, "y" * 120), device_id=2, sequence=i, t_ns=i)) for i in range(attempts)
        ]
        assert link.stats.send_dropped > 0, "the pty buffer never filled: the test proves nothing"
        assert link.stats.sent + link.stats.send_dropped == attempts
        stream = bytearray()
        while True:  # drain the line as a receiver would, letting the pending remainder go out
            stream += read_available(master)
            if link.drain(0.05) and not (more := read_available(master)):
                break
            stream += more
        deframer = Deframer()
        sequences = [decode_message(frame).header.sequence for frame in deframer.feed(bytes(stream))]
        assert sequences == [i for i, ok in enumerate(results) if ok]  # every accepted message arrives whole
        assert deframer.stats.bad_frames == 0
    finally:
        link.close()


def test_low_latency_forced_on_a_non_ftdi_port_fails_clearly(pty_port) -> None:
    _, name = pty_port
    with pytest.raises(TransportError, match="low-latency"):
        open_transport(f"serial://{name}?low_latency=1")
    open_transport(f"serial://{name}?low_latency=auto&rtscts=1").close()  # auto: quietly off on a pty
