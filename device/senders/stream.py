"""The daemon's single path to the link: a thread that numbers, encodes and sends every outgoing message.

Frame results queue in a short bounded queue (the oldest is dropped, counted, when the link or the encoder falls
behind), so the pipeline never waits for the link. Status, acknowledgements and logs go through the same thread
ahead of frame results, so that one thread owns the transport's send side and the sequence numbers.

A link that fails `broken_after` sends in a row (an unplugged serial adapter, a network that went away) sets the
`link_broken` event; the daemon then closes this sender and opens a new link. After `close` the sender numbers no
more messages (a new sender continues from `next_sequence` without overlap) and refuses new ones (counted).
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
from ropecam.shared.protocol.budget import encode_within_budget
from ropecam.shared.protocol.shapes import ShapeCodecConfig
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
    dropped_closed: int = 0
    """Messages submitted after `close`, or still queued when the drain timeout ran out."""
    budget_cuts: int = 0
    """Frame results sent with looser shapes, or without shapes, to stay within the byte budget (`budget`)."""


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
    broken_after
        Consecutive failed sends (TransportError) after which `link_broken` is set.
    link_broken
        Event set when the link is considered broken (shared with the control listener); a new one by default.
    shape_config
        Tolerance and quantum of the shape codec for frame results (the codec's default 0.05 px when None).
    frame_budget_bytes
        Most bytes a frame result may take on a serial line (COBS-framed); one over it is sent with looser shapes
        or without them, and says so (`ropecam.shared.protocol.budget`). 0: no budget.
    """

    def __init__(
        self,
        transport: Transport,
        device_id: int,
        queue_frames: int = 16,
        first_sequence: int = 0,
        clock_ns: Callable[[], int] = time.monotonic_ns,
        broken_after: int = 3,
        link_broken: threading.Event | None = None,
        shape_config: ShapeCodecConfig | None = None,
        frame_budget_bytes: int = 0,
    ) -> None:
        self.transport = transport
        self.device_id = device_id
        self.stats = SenderStats()
        self._clock_ns = clock_ns
        self._frames: collections.deque[FrameResult] = collections.deque(maxlen=queue_frames)
        self._urgent: collections.deque[Any] = collections.deque()
        self._wake = threading.Condition()
        self._stop = False
        self._in_flight = False  # a record taken from a queue and not yet sent or dropped (`wait_sent`)
        self._sequence = first_sequence & 0xFFFFFFFF
        self._broken_after = max(1, broken_after)
        self._failures_in_row = 0
        self.link_broken = link_broken if link_broken is not None else threading.Event()
        self._hint = ShapeHint()
        self._shape_config = shape_config or ShapeCodecConfig()
        self._frame_budget = frame_budget_bytes
        self._thread = threading.Thread(target=self._run, name="ropecam-sender", daemon=True)
        self._thread.start()

    def submit_frame(self, record: FrameResult) -> None:
        """Queue a frame result; drops (and counts) the oldest waiting one when the queue is full."""
        with self._wake:
            if self._stop or not self._thread.is_alive():  # closed, or its thread died: nobody would send it
                self.stats.dropped_closed += 1
                return
            if len(self._frames) == self._frames.maxlen:
                self.stats.dropped_queue_full += 1
            self._frames.append(record)
            self.stats.queued += 1
            self._wake.notify()

    def submit(self, record: Any) -> None:
        """Queue a Status, ControlAck, Log or RawFrameChunk; these go ahead of frame results and are never dropped
        here (the transport may still drop them when the line is full); after `close` they are counted and dropped."""
        with self._wake:
            if self._stop or not self._thread.is_alive():  # closed, or its thread died: nobody would send it
                self.stats.dropped_closed += 1
                return
            self._urgent.append(record)
            self._wake.notify()

    @property
    def next_sequence(self) -> int:
        """The sequence number the next message will carry (final once `close` has returned)."""
        with self._wake:
            return self._sequence

    def backlog(self) -> int:
        """Messages waiting to be sent."""
        with self._wake:
            return len(self._frames) + len(self._urgent)

    def wait_sent(self, timeout_s: float) -> bool:
        """Wait up to `timeout_s` seconds until every queued message went out (sent, or dropped by the link) and none
        is being encoded; return whether that happened. The counters in `stats` are then final for what was queued
        (a final Status made before would go ahead of the frames still queued and miss their counts)."""
        deadline = time.monotonic() + timeout_s
        while self._thread.is_alive() and not self._stop:
            with self._wake:
                if not (self._frames or self._urgent or self._in_flight):
                    return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.002)
        return False

    def close(self, drain_timeout_s: float = 2.0) -> None:
        """Send what is queued for up to `drain_timeout_s` seconds, then stop the thread.

        Returns within about `drain_timeout_s` (plus one send). What is still queued then is dropped and counted in
        ``stats.dropped_closed``; from then on no message gets a sequence number, so `next_sequence` is final.
        """
        deadline = time.monotonic() + drain_timeout_s
        while self.backlog() and time.monotonic() < deadline and self._thread.is_alive():
            time.sleep(0.005)
        with self._wake:
            self._stop = True
            self.stats.dropped_closed += len(self._frames) + len(self._urgent)
            self._frames.clear()
            self._urgent.clear()
            self._wake.notify()
        self._thread.join(timeout=max(deadline - time.monotonic(), 0.05))

    @property
    def closed(self) -> bool:
        """True once `close` has been called."""
        return self._stop

    def _next(self) -> tuple[Any, int] | None:
        """The next record and the sequence number it carries (taken under the lock, never after `close`)."""
        with self._wake:
            self._in_flight = False  # the record taken last (if any) is done with
            while not self._stop and not self._frames and not self._urgent:
                self._wake.wait(timeout=0.5)
            if self._stop:
                return None
            record = self._urgent.popleft() if self._urgent else self._frames.popleft()
            self._in_flight = True
            sequence = self._sequence
            self._sequence = (sequence + 1) & 0xFFFFFFFF
            return record, sequence

    def _give_back(self, sequence: int) -> None:
        """Return an unused sequence number (the record could not be encoded) unless another was taken since."""
        with self._wake:
            if self._sequence == (sequence + 1) & 0xFFFFFFFF:
                self._sequence = sequence

    def _encode(self, record: Any, sequence: int) -> bytes:
        if not isinstance(record, FrameResult):
            return encode_message(record, device_id=self.device_id, sequence=sequence, t_ns=self._clock_ns())
        data, cut = encode_within_budget(
            record, self._frame_budget, device_id=self.device_id, sequence=sequence, t_ns=self._clock_ns(),
            shape_config=self._shape_config, hint=self._hint,
        )  # fmt: skip
        if cut:
            self.stats.budget_cuts += 1
        return data

    def _run(self) -> None:
        while True:
            taken = self._next()
            if taken is None:
                return
            record, sequence = taken
            try:
                data = self._encode(record, sequence)
            except (ValueError, ProtocolError) as exc:
                self._give_back(sequence)
                self.stats.encode_errors += 1
                _log.warning("cannot encode %s: %s", type(record).__name__, exc)
                continue
            try:
                if self.transport.send(data):
                    self.stats.sent += 1
                    self.stats.bytes_sent += len(data)
                else:
                    self.stats.dropped_by_link += 1
                self._failures_in_row = 0
            except TransportError as exc:
                # A port that closes or a network that goes away: count it; after a few in a row the daemon reopens.
                self.stats.link_errors += 1
                self._failures_in_row += 1
                if self._failures_in_row == self._broken_after:
                    _log.error("link broken after %d failed sends: %s", self._failures_in_row, exc)
                    self.link_broken.set()
                elif self._failures_in_row < self._broken_after:
                    _log.warning("link error: %s", exc)
