"""The transport contract, run on loop://, UDP over 127.0.0.1 and serial over a real pty pair."""

from __future__ import annotations

import pytest

from ropecam.shared.errors import ConfigError, TransportError
from ropecam.shared.protocol import Log, decode_message, encode_message
from ropecam.shared.transport import LoopTransport, SequenceTracker, Transport, open_transport


def _message(sequence: int, size: int = 40) -> bytes:
    return encode_message(Log(20, "x" * size), device_id=5, sequence=sequence, t_ns=sequence)


def _receive_all(end: Transport, count: int, timeout_s: float = 2.0) -> list[bytes]:
    out = []
    while len(out) < count and (data := end.receive(timeout_s)) is not None:
        out.append(data)
    return out


def test_messages_arrive_whole_and_in_order_both_ways(link: tuple[Transport, Transport]) -> None:
    device, host = link
    messages = [_message(i, size=(i * 37) % 900) for i in range(60)]
    for message in messages:
        assert device.send(message)
        assert device.drain(2.0)
        assert host.receive(2.0) == message
    reply = _message(999)
    assert host.send(reply)  # UDP listener replies to the last sender
    assert device.receive(2.0) == reply
    assert device.stats.sent == 60 and host.stats.received == 60
    assert device.stats.send_dropped == 0


def test_receive_times_out_with_none(link: tuple[Transport, Transport]) -> None:
    _, host = link
    assert host.receive(0.0) is None
    assert host.receive(0.05) is None


def test_a_burst_is_either_delivered_or_counted_as_dropped(link: tuple[Transport, Transport]) -> None:
    device, host = link
    attempts = 300
    delivered = [device.send(_message(i, 200)) for i in range(attempts)]
    device.drain(2.0)
    tracker = SequenceTracker()
    received = _receive_all(host, sum(delivered), timeout_s=1.0)
    for data in received:
        tracker.observe(5, decode_message(data).header.sequence)
    assert device.stats.sent + device.stats.send_dropped == attempts
    assert device.stats.sent == sum(delivered)
    # Every message the line accepted arrives (no loss on these links while the receiver keeps up with the burst).
    assert len(received) == device.stats.sent
    last_sent = max(i for i, ok in enumerate(delivered) if ok)
    assert tracker.stats(5).lost == sum(1 for ok in delivered[:last_sent] if not ok)


def test_closed_transport_refuses_use(link: tuple[Transport, Transport]) -> None:
    device, _ = link
    device.close()
    with pytest.raises(TransportError, match="closed"):
        device.send(b"x")
    with pytest.raises(TransportError, match="closed"):
        device.receive(0.0)


def test_loop_drops_whole_messages_when_the_peer_does_not_read() -> None:
    device, host = LoopTransport.pair(capacity=10)
    results = [device.send(_message(i)) for i in range(25)]
    assert results == [True] * 10 + [False] * 15
    assert device.stats.send_dropped == 15
    assert len(_receive_all(host, 25, 0.0)) == 10


def test_loop_urls() -> None:
    echo = open_transport("loop://")
    assert echo.send(b"abc") and echo.receive() == b"abc"
    a, b = open_transport("loop://demo-link"), open_transport("loop://demo-link")
    assert a.send(b"to b") and b.receive() == b"to b"
    assert b.send(b"to a") and a.receive() == b"to a"


@pytest.mark.parametrize(
    ("url", "fragment"),
    [
        ("tcp://x:1", "unknown scheme"),
        ("udp://127.0.0.1", "port is required"),
        ("udp://127.0.0.1:9?bogus=1", "unknown option 'bogus'"),
        ("serial:///dev/ttyS0?baud=fast", "baud"),
        ("serial:///dev/ttyS0?parity=E", "allowed: baud, low_latency, rtscts"),
    ],
)
def test_bad_urls_name_the_problem(url: str, fragment: str) -> None:
    with pytest.raises(ConfigError, match=fragment):
        open_transport(url)


def test_missing_serial_port_is_a_transport_error() -> None:
    with pytest.raises(TransportError, match="/dev/ttyDOESNOTEXIST"):
        open_transport("serial:///dev/ttyDOESNOTEXIST?baud=115200")
