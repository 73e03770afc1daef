"""The transport contract: non-blocking `send` of one message, `receive` of one message, counters, URL factory."""

from __future__ import annotations

import contextlib
import math
import socket
import weakref
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from types import TracebackType
from typing import Final
from urllib.parse import parse_qsl, unquote, urlsplit

from ropecam.shared.errors import ConfigError

__all__ = [
    "BOOL_OR_AUTO",
    "TRANSPORT_OPTIONS",
    "Transport",
    "TransportStats",
    "Waker",
    "check_transport_url",
    "open_transport",
    "parse_url",
]


@dataclass(slots=True)
class TransportStats:
    """Counters every transport keeps.

    Attributes
    ----------
    sent, send_dropped
        Messages handed to the line, and messages dropped whole because it was full.
    received
        Complete messages returned by `receive`.
    bytes_sent, bytes_received
        Bytes on the line (including framing).
    bad_frames
        Framing damage seen by the receiver (invalid COBS, runs of garbage); UDP: datagrams over the size limit.
    """

    sent: int = 0
    send_dropped: int = 0
    received: int = 0
    bytes_sent: int = 0
    bytes_received: int = 0
    bad_frames: int = 0


class Transport(ABC):
    """One end of a message link. Messages are the complete bytes of `encode_message`; the transport never parses them.

    `send` never blocks: when the line cannot take a message now, the whole message is dropped, counted in
    ``stats.send_dropped`` and `send` returns False. `receive` waits up to `timeout_s` for one message.
    """

    url: str

    def __init__(self, url: str) -> None:
        self.url = url
        self.stats = TransportStats()
        self._closed = False

    @abstractmethod
    def send(self, message: bytes) -> bool:
        """Queue one message without blocking; return False (and count it) if it was dropped."""

    @abstractmethod
    def receive(self, timeout_s: float | None = 0.0) -> bytes | None:
        """Return the next message, waiting up to `timeout_s` (None: forever); None when none arrived.

        Raises TransportError when the transport is closed, also when `close` is called by another thread while
        this one waits.
        """

    def drain(self, timeout_s: float = 1.0) -> bool:
        """Wait up to `timeout_s` until everything accepted by `send` has left this end; True when it has."""
        return True

    def close(self) -> None:
        """Release the line; further calls fail with TransportError.

        Safe to call from another thread: a `receive` blocked in that thread wakes up and raises TransportError.
        Calling it again does nothing.
        """
        self._closed = True

    @property
    def closed(self) -> bool:
        """True after `close`."""
        return self._closed

    def __enter__(self) -> Transport:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.url!r})"


class Waker:
    """A socket pair to wake a thread blocked in ``select``: select on `fileno()`, call `wake()` from another thread.

    The pair stays open until the waker is garbage-collected, so a thread that enters select just after a close
    never waits on a closed (or reused) descriptor.
    """

    def __init__(self) -> None:
        self._read, self._write = socket.socketpair()
        self._read.setblocking(False)
        self._write.setblocking(False)
        weakref.finalize(self, _close_all, self._read, self._write)

    def fileno(self) -> int:
        """The descriptor that becomes readable on `wake`."""
        return self._read.fileno()

    def wake(self) -> None:
        """Make `fileno()` readable (for good: nothing clears it)."""
        with contextlib.suppress(OSError):  # only when its buffer is full: then it is readable already
            self._write.send(b"\x00")


def _close_all(*sockets: socket.socket) -> None:
    for item in sockets:
        item.close()


BOOL_OR_AUTO: Final = "bool-or-auto"
"""Type marker for `parse_url`: the option is a boolean or the word ``auto`` (returned as the string "auto")."""
_TRUE: Final = frozenset({"1", "true", "yes", "on"})
_FALSE: Final = frozenset({"0", "false", "no", "off"})
_EXPECTED: Final = {
    int: "an integer",
    float: "a finite number",
    bool: "a boolean (1/0, true/false, yes/no, on/off)",
    BOOL_OR_AUTO: "a boolean (1/0, true/false, yes/no, on/off) or auto",
    str: "text",
}


def _option_value(raw: str, kind: object) -> object:
    """Convert one query value; ValueError when it is not of `kind`."""
    if kind is bool or kind == BOOL_OR_AUTO:
        word = raw.strip().lower()
        if word == "auto" and kind == BOOL_OR_AUTO:
            return "auto"
        if word in _TRUE or word in _FALSE:
            return word in _TRUE
        raise ValueError(raw)
    if kind is int:
        return int(raw)
    if kind is float:
        value = float(raw)
        if not math.isfinite(value):
            raise ValueError(raw)
        return value
    if kind is str:
        return raw
    raise TypeError(f"unsupported option type {kind!r}")


def parse_url(
    url: str, allowed: Mapping[str, object], *, path: bool | None = None, what: str = "transport URL"
) -> tuple[str, str, int | None, dict[str, object]]:
    """Split a URL into (scheme, host-or-path, port, options) with typed, checked query options.

    One parser for every URL ropecam takes (transports, capture sources), so they agree on spellings.

    Parameters
    ----------
    url
        ``scheme://host:port?key=value`` or ``scheme:///path?key=value`` (also ``scheme:path?...``).
    allowed
        Query keys the scheme accepts and their types: int, float (finite), bool (1/0, true/false, yes/no, on/off,
        any case), `BOOL_OR_AUTO` (a bool or ``auto``) or str.
    path
        True: the location is a path (netloc and path joined, percent-decoded; no port). False: a host name and
        port. None (default): a path for ``serial``, a host otherwise.
    what
        How error messages name the URL ("transport URL", "source URL", ...).

    Raises
    ------
    ConfigError
        Malformed URL, unknown option (the message lists the allowed ones), an option given twice, or a value of
        the wrong type (the message says what was expected).
    """
    parts = urlsplit(url)
    as_path = parts.scheme == "serial" if path is None else path
    port = None
    if not as_path:
        try:
            port = parts.port
        except ValueError as exc:
            raise ConfigError(f"{what} {url!r}: bad port ({exc})") from exc
    options: dict[str, object] = {}
    for key, raw in parse_qsl(parts.query, keep_blank_values=True, strict_parsing=False):
        if key not in allowed:
            names = ", ".join(sorted(allowed)) or "none"
            raise ConfigError(f"{what} {url!r}: unknown option {key!r} (allowed: {names})")
        if key in options:
            raise ConfigError(f"{what} {url!r}: option {key!r} given twice")
        kind = allowed[key]
        try:
            options[key] = _option_value(raw, kind)
        except ValueError as exc:
            expected = _EXPECTED.get(kind, str(kind))  # type: ignore[call-overload]
            raise ConfigError(f"{what} {url!r}: option {key}={raw!r} is not {expected}") from exc
    where = unquote(parts.netloc + parts.path) if as_path else (parts.hostname or "")
    return parts.scheme, where, port, options


TRANSPORT_OPTIONS: Final[Mapping[str, Mapping[str, object]]] = {
    "loop": {"capacity": int},
    "udp": {"listen": bool},
    "serial": {"baud": int, "rtscts": bool, "low_latency": BOOL_OR_AUTO},
}
"""Query options each transport scheme accepts, and their types (for `parse_url`)."""


def check_transport_url(url: str) -> None:
    """Check a transport URL without opening anything: scheme, host and port (udp), path (serial), options.

    Raises
    ------
    ConfigError
        Unknown scheme, missing UDP port or serial device path, port out of range, unknown or mistyped option.
    """
    if not isinstance(url, str):
        raise ConfigError(f"transport URL must be text, got {url!r}")
    scheme = urlsplit(url).scheme
    if scheme not in TRANSPORT_OPTIONS:
        raise ConfigError(f"transport URL {url!r}: unknown scheme {scheme!r} (use udp://HOST:PORT, serial:///dev/X)")
    _, where, port, options = parse_url(url, TRANSPORT_OPTIONS[scheme])
    if scheme == "udp" and port is None:
        raise ConfigError(f"transport URL {url!r}: a UDP port is required (udp://HOST:PORT)")
    if scheme == "serial":
        if not where:
            raise ConfigError(f"transport URL {url!r}: a device path is required (serial:///dev/ttyUSB0)")
        baud = options.get("baud", 921600)
        if not isinstance(baud, int) or baud <= 0:
            raise ConfigError(f"transport URL {url!r}: baud must be a positive integer, got {baud!r}")


def open_transport(url: str) -> Transport:
    """Open the transport a URL names.

    ``loop://`` (in-process, what is sent comes back), ``loop://NAME`` (the first and second opener of NAME are
    connected to each other), ``udp://HOST:PORT`` (send to HOST:PORT, receive its replies),
    ``udp://:PORT`` or ``udp://HOST:PORT?listen=1`` (bind and receive; reply to the last sender),
    ``serial:///dev/ttyX?baud=921600&rtscts=1&low_latency=auto``.

    Raises
    ------
    ConfigError
        Unknown scheme or malformed URL.
    TransportError
        The port or socket cannot be opened.
    """
    scheme = urlsplit(url).scheme
    if scheme == "loop":
        from ropecam.shared.transport.loop import open_loop

        return open_loop(url)
    if scheme == "udp":
        from ropecam.shared.transport.udp import UdpTransport

        return UdpTransport(url)
    if scheme == "serial":
        from ropecam.shared.transport.serial import SerialTransport

        return SerialTransport(url)
    raise ConfigError(f"transport URL {url!r}: unknown scheme {scheme!r} (use loop://, udp:// or serial://)")
