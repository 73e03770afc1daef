"""Transports used from several threads: close() wakes a blocked receiver, sends and receives race safely."""

from __future__ import annotations

import gc
import os
import pty
import threading
import time
import warnings
from collections.abc import Iterator

import pytest

from ropecam.shared.errors import TransportError
from ropecam.shared.protocol import Deframer, Log, decode_message, encode_message, frame
from ropecam.shared.transport import Transport, open_transport


def _blocked_receiver(
    end: Transport, timeout_s: float | None = None
) -> tuple[threading.Thread, list[BaseException | bytes | None]]:
    outcome: list[BaseException | bytes | None] = []

    def run() -> None:
        try:
            outcome.append(end.receive(timeout_s))
        except BaseException as exc:  # the test inspects whatever ended the call
            outcome.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, outcome


@pytest.mark.parametrize("timeout_s", [None, 30.0])
def test_close_wakes_a_thread_blocked_in_receive(link: tuple[Transport, Transport], timeout_s: float | None) -> None:
    _, host = link
    thread, outcome = _blocked_receiver(host, timeout_s)
    time.sleep(0.2)  # let it block
    assert thread.is_alive() and not outcome
    started = time.monotonic()
    host.close()
    thread.join(5.0)
    assert not thread.is_alive(), f"{host!r}: close() did not wake the receiving thread"
    assert time.monotonic() - started < 2.0
    assert len(outcome) == 1 and isinstance(outcome[0], TransportError), outcome
    assert "closed" in str(outcome[0])
    host.close()  # closing twice is harmless


def test_a_message_sent_before_close_is_still_received_by_a_waiting_thread(link: tuple[Transport, Transport]) -> None:
    device, host = link
    thread, outcome = _blocked_receiver(host)
    time.sleep(0.1)
    message = encode_message(Log(20, "hello"), device_id=1, sequence=0, t_ns=0)
    assert device.send(message)
    thread.join(5.0)
    assert outcome == [message]


def test_udp_open_failure_leaks_no_socket() -> None:
    first = open_transport("udp://127.0.0.1:0?listen=1")
    port = first.local_address[1]  # type: ignore[attr-defined]
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with pytest.raises(TransportError, match="cannot open UDP socket"):
                open_transport(f"udp://127.0.0.1:{port}?listen=1")  # the port is taken
            gc.collect()
        assert not [w for w in caught if issubclass(w.category, ResourceWarning)], [str(w.message) for w in caught]
    finally:
        first.close()


@pytest.fixture
def pty_port() -> Iterator[tuple[int, str]]:
    master, slave = pty.openpty()
    name = os.ttyname(slave)
    os.close(slave)
    os.set_blocking(master, False)
    yield master, name
    os.close(master)


def test_serial_send_and_receive_threads_never_duplicate_a_pending_tail(
    pty_port: tuple[int, str], read_available
) -> None:
    master, name = pty_port
    link = open_transport(f"serial://{name}?baud=921600")
    stop = threading.Event()
    stream = bytearray()

    def receive_loop() -> None:  # the daemon's control receiver: every receive also flushes the pending tail
        while not stop.is_set():
            link.receive(0.0)

    receiver = threading.Thread(target=receive_loop, daemon=True)
    receiver.start()
    results = []
    try:
        for i in range(3000):
            results.append(link.send(encode_message(Log(20, "z" * 300), device_id=2, sequence=i, t_ns=i)))
            if i % 100 == 0:
                stream += read_available(master)  # the line drains slowly: partial writes and pending tails happen
    finally:
        stop.set()
        receiver.join(5.0)
    while True:
        stream += read_available(master)
        if link.drain(0.05) and not (more := read_available(master)):
            break
        stream += more
    link.close()
    assert link.stats.send_dropped > 0, "the line never filled: the test proves nothing"
    deframer = Deframer()
    sequences = [decode_message(item).header.sequence for item in deframer.feed(bytes(stream))]
    assert deframer.stats.bad_frames == 0 and deframer.stats.overlong == 0
    assert sequences == [i for i, ok in enumerate(results) if ok]
    assert link.stats.bytes_sent == len(stream)


def test_deframer_feed_consumes_everything_at_once() -> None:
    messages = [encode_message(Log(20, f"m{i}"), device_id=1, sequence=i, t_ns=i) for i in range(3)]
    data = b"".join(frame(m) for m in messages)
    deframer = Deframer()
    frames = deframer.feed(data)
    assert isinstance(frames, list)
    assert deframer.stats.bytes_in == len(data) and deframer.stats.frames == 3  # counted without iterating
    assert frames[:1] == messages[:1]  # a caller that stops after the first loses nothing: the rest are here
    assert frames == messages
