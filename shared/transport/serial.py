"""Serial transport: COBS-framed messages over a UART or USB adapter, with writes that never block.

`send` frames the message and writes what the OS output buffer takes right now. If it takes only part, the rest is
kept and written first on the next call; while such a remainder is pending a new message is dropped whole (counted)
rather than waiting: the camera pipeline must not stall on a slow line, and a half-written message would only be
discarded by the receiver anyway. Hardware flow control (``rtscts=1``) makes the OS buffer fill when the receiver
holds CTS, which then shows up as drops. On FTDI adapters ``low_latency`` (default ``auto``) sets the driver's
ASYNC_LOW_LATENCY flag, which cuts the adapter's 16 ms receive latency timer to 1 ms.
"""

from __future__ import annotations

import errno
import logging
import os
import select
import threading
import time
from collections import deque
from pathlib import Path
from typing import Final

from ropecam.shared.errors import ConfigError, TransportError
from ropecam.shared.protocol.framing import Deframer, DeframerStats, frame
from ropecam.shared.transport.base import TRANSPORT_OPTIONS, Transport, Waker, parse_url

__all__ = ["SerialTransport"]

_log = logging.getLogger(__name__)
_READ_BYTES: Final = 4096


def _is_ftdi(path: str) -> bool:
    name = Path(os.path.realpath(path)).name
    driver = Path("/sys/class/tty") / name / "device" / "driver"
    try:
        return driver.resolve().name == "ftdi_sio"
    except OSError:
        return False


class SerialTransport(Transport):
    """``serial:///dev/ttyX?baud=921600[&rtscts=1][&low_latency=auto|1|0]``."""

    def __init__(self, url: str) -> None:
        super().__init__(url)
        _, path, _, options = parse_url(url, TRANSPORT_OPTIONS["serial"], path=True)
        if not path:
            raise ConfigError(f"transport URL {url!r}: a device path is required (serial:///dev/ttyUSB0)")
        baud = options.get("baud", 921600)
        if not isinstance(baud, int) or baud <= 0:
            raise ConfigError(f"transport URL {url!r}: baud must be a positive integer, got {baud!r}")
        import serial  # pyserial: imported here so loop:// and udp:// users do not pay for it

        try:
            self._port = serial.Serial(
                path, baudrate=baud, rtscts=bool(options.get("rtscts", False)), timeout=0, write_timeout=0
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            raise TransportError(f"{url}: cannot open serial port {path}: {exc}") from exc
        self._fd = self._port.fileno()
        os.set_blocking(self._fd, False)
        low_latency = options.get("low_latency", "auto")
        if low_latency is True or (low_latency == "auto" and _is_ftdi(path)):
            try:
                self._port.set_low_latency_mode(True)
            except (ValueError, AttributeError, OSError) as exc:
                if low_latency is True:
                    self._port.close()
                    raise TransportError(f"{url}: cannot set low-latency mode: {exc}") from exc
                _log.warning("%s: low-latency mode not available: %s", path, exc)
        self._pending = b""
        self._deframer = Deframer()
        self._ready: deque[bytes] = deque()
        # The daemon sends from its pipeline thread and receives control on another: the write side (pending tail,
        # send counters) and the read side (deframer, ready queue) each have a lock; close() takes both.
        self._write_lock = threading.Lock()
        self._read_lock = threading.Lock()
        self._waker = Waker()

    @property
    def deframer_stats(self) -> DeframerStats:
        """Counters of the receive side's framing (frames, bad frames, garbage runs)."""
        return self._deframer.stats

    def _write_some(self, data: bytes) -> int:
        try:
            return os.write(self._fd, data)
        except BlockingIOError:
            return 0
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EINTR):
                return 0
            raise TransportError(f"{self.url}: write failed: {exc}") from exc

    def _flush_pending(self) -> None:
        """Write what the OS takes of the pending tail; call with the write lock held."""
        if self._pending:
            written = self._write_some(self._pending)
            self.stats.bytes_sent += written
            self._pending = self._pending[written:]

    def send(self, message: bytes) -> bool:
        """Frame and write one message without blocking; False (counted) when the line is still busy."""
        data = frame(message)
        with self._write_lock:
            if self._closed:
                raise TransportError(f"{self.url}: send on a closed transport")
            self._flush_pending()
            if self._pending:
                self.stats.send_dropped += 1
                return False
            written = self._write_some(data)
            if written == 0:
                self.stats.send_dropped += 1
                return False
            self.stats.bytes_sent += written
            self._pending = data[written:]
            self.stats.sent += 1
            return True

    def drain(self, timeout_s: float = 1.0) -> bool:
        """Wait up to `timeout_s` until a partly written message has gone out; True when nothing is pending."""
        deadline = time.monotonic() + timeout_s
        while True:
            with self._write_lock:
                if self._closed:
                    raise TransportError(f"{self.url}: drain on a closed transport")
                self._flush_pending()
                if not self._pending:
                    return True
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            try:
                select.select([self._waker], [self._fd], [], remaining)
            except (OSError, ValueError) as exc:
                raise TransportError(f"{self.url}: drain failed: {exc}") from exc

    @property
    def pending_bytes(self) -> int:
        """Bytes of a partly written message still waiting for the line."""
        return len(self._pending)

    def receive(self, timeout_s: float | None = 0.0) -> bytes | None:
        """Return the next complete message (COBS-decoded), waiting up to `timeout_s`."""
        if self._closed:
            raise TransportError(f"{self.url}: receive on a closed transport")
        with self._write_lock:
            if not self._closed:
                self._flush_pending()
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        waited = False
        while True:
            with self._read_lock:
                if self._closed:
                    raise TransportError(f"{self.url}: closed while receiving")
                if self._ready:
                    self.stats.received += 1
                    return self._ready.popleft()
                try:
                    data = os.read(self._fd, _READ_BYTES)
                except BlockingIOError:
                    data = b""
                except OSError as exc:
                    raise TransportError(f"{self.url}: read failed (port lost?): {exc}") from exc
                if data:
                    waited = False
                    self._feed(data)
                    continue
            if waited:
                # A tty with VMIN = VTIME = 0 reads b"" when empty; after select said readable it means hang-up.
                raise TransportError(f"{self.url}: the serial device reports data but gives none (unplugged?)")
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                return None
            try:
                readable, _, _ = select.select([self._fd, self._waker], [], [], remaining)
            except (OSError, ValueError) as exc:  # the port was closed by another thread
                if self._closed:
                    raise TransportError(f"{self.url}: closed while receiving") from exc
                raise TransportError(f"{self.url}: waiting for data failed: {exc}") from exc
            waited = self._fd in readable

    def _feed(self, data: bytes) -> None:
        stats = self._deframer.stats
        before = stats.bad_frames + stats.overlong
        self.stats.bytes_received += len(data)
        self._ready.extend(self._deframer.feed(data))
        self.stats.bad_frames += stats.bad_frames + stats.overlong - before

    def close(self) -> None:
        """Close the port (a pending partial message is abandoned); a blocked `receive` or `drain` wakes and raises."""
        if self._closed:
            return
        super().close()
        self._waker.wake()
        with self._write_lock, self._read_lock:
            self._port.close()
