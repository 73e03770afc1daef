"""In-process transport (``loop://``) for tests, replay and demos: bounded queues between two ends."""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from typing import Final

from ropecam.shared.errors import TransportError
from ropecam.shared.transport.base import TRANSPORT_OPTIONS, Transport, parse_url

__all__ = ["LoopTransport", "open_loop"]

DEFAULT_CAPACITY: Final = 4096
_waiting: dict[str, LoopTransport] = {}
_waiting_lock = threading.Lock()


class _Queue:
    """A bounded, thread-safe message queue."""

    def __init__(self, capacity: int) -> None:
        self.items: deque[bytes] = deque()
        self.capacity = capacity
        self.ready = threading.Condition()

    def put(self, message: bytes) -> bool:
        with self.ready:
            if len(self.items) >= self.capacity:
                return False
            self.items.append(message)
            self.ready.notify()
            return True

    def get(self, timeout_s: float | None, closed: Callable[[], bool]) -> bytes | None:
        """Pop the oldest message, waiting up to `timeout_s` unless `closed()` becomes true (then None)."""
        with self.ready:
            if not self.items and timeout_s != 0.0:
                self.ready.wait_for(lambda: bool(self.items) or closed(), timeout=timeout_s)
            if closed():
                return None
            return self.items.popleft() if self.items else None

    def wake_all(self) -> None:
        """Wake every thread waiting in `get` (they re-check their `closed`)."""
        with self.ready:
            self.ready.notify_all()


class LoopTransport(Transport):
    """One end of an in-process link; `send` puts into the peer's queue, dropping when it holds `capacity`."""

    def __init__(self, url: str, inbox: _Queue, outbox: _Queue) -> None:
        super().__init__(url)
        self._inbox = inbox
        self._outbox = outbox

    @classmethod
    def pair(cls, capacity: int = DEFAULT_CAPACITY, url: str = "loop://pair") -> tuple[LoopTransport, LoopTransport]:
        """Return two connected ends (a device and a host)."""
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        a_to_b, b_to_a = _Queue(capacity), _Queue(capacity)
        return cls(url, b_to_a, a_to_b), cls(url, a_to_b, b_to_a)

    def send(self, message: bytes) -> bool:
        """Queue `message` for the peer; False (counted) when its queue is full."""
        if self._closed:
            raise TransportError(f"{self.url}: send on a closed transport")
        if not self._outbox.put(bytes(message)):
            self.stats.send_dropped += 1
            return False
        self.stats.sent += 1
        self.stats.bytes_sent += len(message)
        return True

    def receive(self, timeout_s: float | None = 0.0) -> bytes | None:
        """Return the next message from the peer, waiting up to `timeout_s`."""
        if self._closed:
            raise TransportError(f"{self.url}: receive on a closed transport")
        message = self._inbox.get(timeout_s, lambda: self._closed)
        if self._closed:
            raise TransportError(f"{self.url}: closed while receiving")
        if message is not None:
            self.stats.received += 1
            self.stats.bytes_received += len(message)
        return message

    def close(self) -> None:
        """Close this end; a thread blocked in its `receive` wakes up and raises TransportError."""
        super().close()
        self._inbox.wake_all()


def open_loop(url: str) -> LoopTransport:
    """Open ``loop://`` (talks to itself) or ``loop://NAME`` (connects the first and second opener of NAME).

    Option ``capacity`` (messages per direction, default 4096).
    """
    _, name, _, options = parse_url(url, TRANSPORT_OPTIONS["loop"])
    capacity = int(options.get("capacity", DEFAULT_CAPACITY))  # type: ignore[call-overload]
    if capacity < 1:
        raise TransportError(f"{url}: capacity must be >= 1, got {capacity}")
    if not name:
        queue = _Queue(capacity)
        return LoopTransport(url, queue, queue)
    with _waiting_lock:
        first = _waiting.pop(name, None)
        if first is None:
            a, b = LoopTransport.pair(capacity, url)
            _waiting[name] = b
            return a
        return first
