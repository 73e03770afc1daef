"""Fixtures of the receiver, recording, replay and monitor tests: a simulated device and a monitor subprocess."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from ropecam.host.monitor.process import MonitorProcess
from ropecam.host.sim.stream import SimulatedDevice
from ropecam.shared.transport.base import Transport


@pytest.fixture(scope="session")
def sim_device() -> SimulatedDevice:
    """A simulated device (id 7) with 12 distinct encoded rig frames."""
    return SimulatedDevice(7, frame_count=12, seed=3)


def free_udp_port() -> int:
    """Return a UDP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture
def monitor_process() -> Iterator[type[MonitorProcess]]:
    """Factory of monitor subprocesses; any still running at the end is killed."""
    started: list[MonitorProcess] = []

    class Tracked(MonitorProcess):
        def __init__(self, args: list[str]) -> None:
            super().__init__(args)
            started.append(self)

    yield Tracked
    for monitor in started:
        monitor.kill()


def read_mcap(path: Path) -> list[tuple[str, str | None, int, bytes]]:
    """Return (topic, schema name, log time, data) of every message of a complete MCAP file, in file order.

    Raw wire messages come out as the wire bytes (unwrapped), others as stored.
    """
    from mcap.reader import make_reader

    from ropecam.host.recording.wire import RAW_TOPIC, unwrap

    with open(path, "rb") as handle:
        reader = make_reader(handle)
        return [
            (
                channel.topic,
                schema.name if schema else None,
                message.log_time,
                unwrap(message.data, channel.message_encoding) if channel.topic == RAW_TOPIC else message.data,
            )
            for schema, channel, message in reader.iter_messages(log_time_order=False)
        ]


def read_messages(path: Path) -> list[tuple[str, str | None, int, dict]]:
    """Return (topic, schema name, log time, message as dict) of every message, JSON or protobuf alike."""
    from ropecam.host.recording.reader import decoded_messages

    return [(topic, schema, log_time, data) for topic, schema, log_time, _, data in decoded_messages(path)]


def send_paced(link: Transport, messages: list[bytes], fps: float = 119.0) -> list[float]:
    """Send `messages` at `fps`; return the monotonic send time of each."""
    start = time.monotonic()
    times = []
    for k, data in enumerate(messages):
        delay = start + k / fps - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        link.send(data)
        times.append(time.monotonic())
    return times


@pytest.fixture
def udp_port() -> int:
    """A free UDP port on 127.0.0.1."""
    return free_udp_port()


@pytest.fixture(name="read_mcap")
def read_mcap_fixture():
    """`read_mcap(path)` -> [(topic, schema name, log time, data)]."""
    return read_mcap


@pytest.fixture(name="read_messages")
def read_messages_fixture():
    """`read_messages(path)` -> [(topic, schema name, log time, message dict)]."""
    return read_messages


@pytest.fixture(name="send_paced")
def send_paced_fixture():
    """`send_paced(link, messages, fps)` -> send times."""
    return send_paced
