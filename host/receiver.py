"""The host's receiving end: one transport URL in, checked packets with their receive time out.

Every datagram (or deframed serial message) becomes a `Packet` holding the exact bytes (for the raw recording), the
host receive time and, when the envelope is sound, the checked header. The header and CRC check and the quick
`FrameSummary` (frame index, times, status, method, confidence, pipeline time) cost a few microseconds, so they run
for every packet; the full decode (shapes: ~1 ms in Python) is a separate step the caller may skip under load.
Bad packets are returned with their error text, never raised: the caller counts and skips them.
"""

from __future__ import annotations

import struct
import time
import zlib
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Final

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.frame_result import FrameSummary, peek_frame_summary
from ropecam.shared.protocol.wire import CRC_BYTES, HEADER_BYTES, Header, MessageType, peek_header
from ropecam.shared.transport.base import Transport

__all__ = ["FrameSummary", "Packet", "Receiver", "check_packet", "summarize_frame"]

_CRC: Final = struct.Struct("<I")


@dataclass(frozen=True, slots=True)
class Packet:
    """One received message.

    Attributes
    ----------
    data
        The exact bytes received (what the raw channel records and replay feeds back).
    receive_t_ns
        Host wall clock (``time.time_ns()``) when the packet was taken from the transport.
    header
        The checked header, or None when the envelope is broken.
    error
        Why the packet is unusable (bad magic, CRC mismatch, ...), or None.
    crc_error
        True when the header parsed but the CRC did not match (the device id is then probably right).
    """

    data: bytes
    receive_t_ns: int
    header: Header | None
    error: str | None = None
    crc_error: bool = False

    @property
    def ok(self) -> bool:
        """True when header and CRC are sound (the payload may still be refused by the full decode)."""
        return self.error is None


def check_packet(data: bytes, receive_t_ns: int) -> Packet:
    """Check the envelope (header fields, length, CRC) of `data` and wrap it in a `Packet`; never raises."""
    try:
        header = peek_header(data)
    except ProtocolError as exc:
        return Packet(data, receive_t_ns, None, str(exc))
    (crc,) = _CRC.unpack_from(data, len(data) - CRC_BYTES)
    actual = zlib.crc32(memoryview(data)[: len(data) - CRC_BYTES])
    if crc != actual:
        error = f"CRC mismatch: message says 0x{crc:08x}, bytes give 0x{actual:08x}"
        return Packet(data, receive_t_ns, header, error, crc_error=True)
    return Packet(data, receive_t_ns, header)


def summarize_frame(packet: Packet) -> FrameSummary | None:
    """Read the leading FrameResult fields of a sound FrameResult packet; None for other packets or bad payloads."""
    header = packet.header
    if header is None or not packet.ok or header.type != MessageType.FRAME_RESULT:
        return None
    try:
        return peek_frame_summary(memoryview(packet.data)[HEADER_BYTES : HEADER_BYTES + header.payload_length],
                                  header.t_ns)  # fmt: skip
    except ProtocolError:
        return None


class Receiver:
    """Take packets from one transport, timestamping each as it leaves the transport.

    `poll` first drains everything the transport has ready into an internal queue (so receive times stay accurate
    and the socket buffer never fills while the caller works), then returns the oldest packet. `backlog` tells the
    caller how far behind it is, so it can skip optional work (the full decode) under load.

    Parameters
    ----------
    transport
        An open transport (`ropecam.shared.transport.open_transport`).
    clock_ns
        Host clock for receive times (default ``time.time_ns``; tests may inject one).
    max_backlog
        Packets held at most; beyond it the oldest is dropped and counted in `overflow` (host far too slow).
    """

    def __init__(
        self, transport: Transport, clock_ns: Callable[[], int] = time.time_ns, max_backlog: int = 200_000
    ) -> None:
        if max_backlog < 1:
            raise ValueError(f"max_backlog must be >= 1, got {max_backlog}")
        self.transport = transport
        self._clock_ns = clock_ns
        self._queue: deque[tuple[bytes, int]] = deque()
        self._max_backlog = max_backlog
        self.overflow = 0

    @property
    def backlog(self) -> int:
        """Packets received but not yet returned by `poll`."""
        return len(self._queue)

    def _drain(self) -> None:
        receive, clock, queue = self.transport.receive, self._clock_ns, self._queue
        while (data := receive(0.0)) is not None:
            if len(queue) >= self._max_backlog:
                queue.popleft()
                self.overflow += 1
            queue.append((data, clock()))

    def remaining(self) -> Iterator[Packet]:
        """Yield what the transport holds now and what is queued (at shutdown: nothing received is left behind)."""
        self._drain()
        while self._queue:
            data, receive_t_ns = self._queue.popleft()
            yield check_packet(data, receive_t_ns)

    def poll(self, timeout_s: float) -> Packet | None:
        """Return the next packet, waiting up to `timeout_s` when none is queued; None when nothing came."""
        self._drain()
        if not self._queue:
            data = self.transport.receive(timeout_s)
            if data is None:
                return None
            self._queue.append((data, self._clock_ns()))
        data, receive_t_ns = self._queue.popleft()
        return check_packet(data, receive_t_ns)
