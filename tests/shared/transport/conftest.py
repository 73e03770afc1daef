"""Transport fixtures: connected pairs over loop://, UDP on 127.0.0.1 and two real pty pairs joined by a relay.

The serial pair is: SerialTransport on pty A's slave <-> relay thread (A master <-> B master) <-> SerialTransport on
pty B's slave. The relay can corrupt the A -> B direction (flips, insertions, drops at a given byte rate) and records
the clean-stream offset of every fault, so a test can tell exactly which messages were damaged.
"""

from __future__ import annotations

import os
import pty
import select
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
import pytest

from ropecam.shared.transport import LoopTransport, Transport, open_transport


@dataclass
class Fault:
    """One injected fault at clean-stream byte `offset` of the A -> B direction."""

    offset: int
    kind: str  # "flip", "insert" (after the byte), "drop"


@dataclass
class Relay:
    """Copies bytes between two pty masters; optionally corrupts A -> B."""

    master_a: int
    master_b: int
    fault_rate: float = 0.0
    seed: int = 0
    faults: list[Fault] = field(default_factory=list)
    forwarded: int = 0
    _stop: threading.Event = field(default_factory=threading.Event)
    _thread: threading.Thread | None = None

    def start(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5)

    def _corrupt(self, data: bytes) -> bytes:
        if self.fault_rate <= 0:
            self.forwarded += len(data)
            return data
        draw = self._rng.random(len(data))
        hits = np.flatnonzero(draw < self.fault_rate)
        if len(hits) == 0:
            self.forwarded += len(data)
            return data
        out = bytearray()
        previous = 0
        for index in hits.tolist():
            out += data[previous:index]
            kind = ("flip", "insert", "drop")[int(self._rng.integers(3))]
            byte = data[index]
            if kind == "flip":
                out.append(byte ^ int(self._rng.integers(1, 256)))
            elif kind == "insert":
                out.append(byte)
                out.append(int(self._rng.integers(0, 256)))
            self.faults.append(Fault(self.forwarded + index, kind))
            previous = index + 1
        out += data[previous:]
        self.forwarded += len(data)
        return bytes(out)

    def _run(self) -> None:
        pending = {self.master_a: b"", self.master_b: b""}  # bytes waiting to be written TO this master
        while not self._stop.is_set():
            writers = [fd for fd, data in pending.items() if data]
            readable, writable, _ = select.select([self.master_a, self.master_b], writers, [], 0.05)
            for fd in writable:
                written = os.write(fd, pending[fd])
                pending[fd] = pending[fd][written:]
            for fd in readable:
                try:
                    data = os.read(fd, 65536)
                except OSError:
                    return
                if fd == self.master_a:
                    pending[self.master_b] += self._corrupt(data)
                else:
                    pending[self.master_a] += data


def _raw_pty() -> tuple[int, str]:
    master, slave = pty.openpty()
    name = os.ttyname(slave)
    os.close(slave)  # pyserial opens the slave by name and sets raw mode
    os.set_blocking(master, False)
    return master, name


@pytest.fixture
def pty_link(request: pytest.FixtureRequest) -> Iterator[tuple[Transport, Transport, Relay]]:
    """(device end, host end, relay); parametrize indirectly with {"fault_rate": ..., "seed": ...}."""
    options = getattr(request, "param", {}) or {}
    master_a, name_a = _raw_pty()
    master_b, name_b = _raw_pty()
    device = open_transport(f"serial://{name_a}?baud=921600")
    host = open_transport(f"serial://{name_b}?baud=921600")
    relay = Relay(master_a, master_b, **options)
    relay.start()
    try:
        yield device, host, relay
    finally:
        relay.stop()
        device.close()
        host.close()
        os.close(master_a)
        os.close(master_b)


def _udp_pair() -> tuple[Transport, Transport]:
    host = open_transport("udp://127.0.0.1:0?listen=1")
    device = open_transport(f"udp://127.0.0.1:{host.local_address[1]}")  # type: ignore[attr-defined]
    return device, host


@pytest.fixture(params=["loop", "udp", "serial"])
def link(request: pytest.FixtureRequest) -> Iterator[tuple[Transport, Transport]]:
    """A connected (device, host) pair of each transport kind."""
    if request.param == "serial":
        pair = request.getfixturevalue("pty_link")
        yield pair[0], pair[1]
        return
    device, host = LoopTransport.pair() if request.param == "loop" else _udp_pair()
    try:
        yield device, host
    finally:
        device.close()
        host.close()


def _read_available(master: int) -> bytes:
    """Everything readable now on a non-blocking pty master."""
    out = bytearray()
    while True:
        try:
            chunk = os.read(master, 65536)
        except (BlockingIOError, OSError):
            return bytes(out)
        if not chunk:
            return bytes(out)
        out += chunk


@pytest.fixture
def read_available():
    """Return a function reading everything readable now from a non-blocking pty master fd."""
    return _read_available
