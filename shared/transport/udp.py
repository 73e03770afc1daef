"""UDP transport: one message per datagram, non-blocking sends."""

from __future__ import annotations

import errno
import select
import socket
from typing import Final

from ropecam.shared.errors import ConfigError, TransportError
from ropecam.shared.protocol.wire import MAX_MESSAGE_BYTES
from ropecam.shared.transport.base import TRANSPORT_OPTIONS, Transport, Waker, parse_url

__all__ = ["UdpTransport"]

_RECEIVE_BUFFER_BYTES: Final = 1 << 20
_DROPPABLE: Final = {errno.EAGAIN, errno.EWOULDBLOCK, errno.ENOBUFS, errno.ECONNREFUSED, errno.EHOSTUNREACH}


class UdpTransport(Transport):
    """``udp://HOST:PORT`` sends to HOST:PORT (and receives the replies on its own port);
    ``udp://:PORT`` or ``udp://HOST:PORT?listen=1`` binds and receives, replying to the last sender.
    Port 0 when listening picks a free port (see `local_address`).
    """

    def __init__(self, url: str) -> None:
        super().__init__(url)
        _, host, port, options = parse_url(url, TRANSPORT_OPTIONS["udp"])
        if port is None:
            raise ConfigError(f"transport URL {url!r}: a UDP port is required (udp://host:port)")
        listen = options.get("listen") is True or not host
        self._waker = Waker()
        sock: socket.socket | None = None
        try:
            infos = socket.getaddrinfo(host or "0.0.0.0", port, type=socket.SOCK_DGRAM)
            family, _, _, _, address = infos[0]
            sock = socket.socket(family, socket.SOCK_DGRAM)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, _RECEIVE_BUFFER_BYTES)
            if listen:
                sock.bind(address)
                self._peer: tuple | None = None
            else:
                sock.connect(address)
                self._peer = address
            sock.setblocking(False)
        except OSError as exc:
            if sock is not None:
                sock.close()
            raise TransportError(f"{url}: cannot open UDP socket: {exc}") from exc
        self._socket = sock
        self._listen = listen

    @property
    def local_address(self) -> tuple[str, int]:
        """The (host, port) this end is bound to."""
        return self._socket.getsockname()[:2]

    def send(self, message: bytes) -> bool:
        """Send one datagram; False (counted) when the socket buffer is full or no peer is known yet."""
        if self._closed:
            raise TransportError(f"{self.url}: send on a closed transport")
        try:
            if self._listen:
                if self._peer is None:
                    self.stats.send_dropped += 1
                    return False
                self._socket.sendto(message, self._peer)
            else:
                self._socket.send(message)
        except OSError as exc:
            if exc.errno in _DROPPABLE:
                self.stats.send_dropped += 1
                return False
            raise TransportError(f"{self.url}: send failed: {exc}") from exc
        self.stats.sent += 1
        self.stats.bytes_sent += len(message)
        return True

    def receive(self, timeout_s: float | None = 0.0) -> bytes | None:
        """Return the next datagram, waiting up to `timeout_s`; oversized ones are counted in bad_frames."""
        if self._closed:
            raise TransportError(f"{self.url}: receive on a closed transport")
        while True:
            try:
                data, address = self._socket.recvfrom(MAX_MESSAGE_BYTES + 1)
            except (BlockingIOError, InterruptedError):
                if timeout_s == 0.0:
                    return None
                try:
                    readable, _, _ = select.select([self._socket, self._waker], [], [], timeout_s)
                except (OSError, ValueError) as exc:  # ValueError: the socket was closed by another thread
                    self._raise_if_closed()
                    raise TransportError(f"{self.url}: receive failed: {exc}") from exc
                self._raise_if_closed()
                if not readable:
                    return None
                timeout_s = 0.0  # one wait only; the datagram is there now
                continue
            except ConnectionRefusedError:
                continue  # ICMP "port unreachable" for an earlier send: the peer is not up yet
            except OSError as exc:
                self._raise_if_closed()
                raise TransportError(f"{self.url}: receive failed: {exc}") from exc
            self.stats.bytes_received += len(data)
            if len(data) > MAX_MESSAGE_BYTES:
                self.stats.bad_frames += 1
                continue
            if self._listen:
                self._peer = address
            self.stats.received += 1
            return data

    def _raise_if_closed(self) -> None:
        if self._closed:
            raise TransportError(f"{self.url}: closed while receiving")

    def close(self) -> None:
        """Close the socket; a thread blocked in `receive` wakes up and raises TransportError."""
        if not self._closed:
            super().close()
            self._waker.wake()
            self._socket.close()
