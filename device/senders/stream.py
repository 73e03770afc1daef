"""The daemon's single path to the link: a thread that numbers, encodes and sends every outgoing message.

Frame results queue in a short bounded queue (the oldest is dropped, counted, when the link or the encoder falls
behind), so the pipeline never waits for the link. Status, acknowledgements and logs go through the same thread
ahead of frame results, so that one thread owns the transport's send side and the sequence numbers.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ropecam.shared.errors import ProtocolError, TransportError
from ropecam.shared.protocol import FrameResult, ShapeHint, encode_message
from ropecam.shared.transport.base import Transport

__all__ = ["ResultSender", "SenderStats"]

_log = logging.getLogger(__name__)


@dataclass(slots=True)
class SenderStats:
    """Counters of the sender thread."""

    queued: int = 0
    sent: int = 0
    dropped_queue_full: int = 0
    dropped_by_link: int = 0
    encode_errors: int = 0
    link_errors: int = 0
    bytes_sent: int = 0


class ResultSender:
    """Encode and send messages on a background thread.

    Parameters
    ----------
    transport
        An open transport; its send side belongs to this sender from now on.
    device_id
        Written into every header.
    queue_frames
        Frame results that may wait; more drop the oldest.
    first_sequence
        Sequence number of the first message (a reopened link continues the numbering).
    clock_ns
        Device clock for the header time (monotonic ns).
    """

    def __init__(
        self,
        transport: Transport,
        device_id: int,
        queue_frames: int = 16,
        first_sequence: int = 0,
        clock_ns: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        self.transport = transport
        self.device_id = device_id
        self.stats = SenderStats()
        self._clock_ns = clock_ns
        self._frames: collections.deque[FrameResult] = collections.deque(maxlen=queue_frames)
        self._urgent: collections.deque[Any] = collections.deque()
        self._wake = threading.Condition()
        self._stop = False
        self._sequence = first_sequence & 0xFFFFFFFF
        self._hint = ShapeHint()
        self._thread = threading.Thread(target=self._run, name="ropecam-sender", daemon=True)
        self._thread.start()

    def submit_frame(self, record: FrameResult) -> None:
        """Queue a frame result; drops (and counts) the oldest waiting one when the queue is full."""
        with self._wake:
            if len(self._frames) == self._frames.maxlen:
                self.stats.dropped_queue_full += 1
            self._frames.append(record)
            self.stats.queued += 1
            self._wake.notify()

    def submit(self, record: Any) -> None:
        """Queue a Status, ControlAck, Log or RawFrameChunk; these go ahead of frame results and are never dropped
        here (the transport may still drop them when the line is full)."""
        with self._wake:
            self._urgent.append(record)
            self._wake.notify()

    @property
    def next_sequence(self) -> int:
        """The sequence number the next message will carry."""
        return self._sequence

    def backlog(self) -> int:
        """Messages waiting to be sent."""
        with self._wake:
            return len(self._frames) + len(self._urgent)

    def close(self, drain_timeout_s: float = 2.0) -> None:
        """Send what is queued (up to `drain_timeout_s`), then stop the thread."""
        deadline = time.monotonic() + drain_timeout_s
        while self.backlog() and time.monotonic() < deadline and self._thread.is_alive():
            time.sleep(0.005)
        with self._wake:
            self._stop = True
            self._wake.notify()
        self._thread.join(timeout=2.0)

    def _next(self) -> Any | None:
        with self._wake:
            while not self._stop and not self._frames and not self._urgent:
                self._wake.wait(timeout=0.5)
            if self._urgent:
                return self._urgent.popleft()
            if self._frames:
                return self._frames.popleft()
            return None

    def _run(self) -> None:
        while True:
            record = self._next()
            if record is None:
                return
            options = {"hint": self._hint} if isinstance(record, FrameResult) else None
            try:
                data = encode_message(
                    record, device_id=self.device_id, sequence=self._sequence, t_ns=self._clock_ns(),
                    pack_options=options,
                )  # fmt: skip
            except (ValueError, ProtocolError) as exc:
                self.stats.encode_errors += 1
                _log.warning("cannot encode %s: %s", type(record).__name__, exc)
                continue
            self._sequence = (self._sequence + 1) & 0xFFFFFFFF
            try:
                if self.transport.send(data):
                    self.stats.sent += 1
                    self.stats.bytes_sent += len(data)
                else:
                    self.stats.dropped_by_link += 1
            except TransportError as exc:
                # A port that closes or a network that goes away: count, report, keep going (the daemon reopens).
                self.stats.link_errors += 1
                _log.warning("link error: %s", exc)
