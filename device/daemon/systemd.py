"""systemd's notify protocol (Type=notify): READY, WATCHDOG pings, STATUS text, over the NOTIFY_SOCKET datagram."""

from __future__ import annotations

import logging
import socket

__all__ = ["Notifier"]

_log = logging.getLogger(__name__)


class Notifier:
    """Send notifications to systemd; a no-op when not started by systemd (no socket given).

    Parameters
    ----------
    socket_path
        The value of ``NOTIFY_SOCKET`` (read by the application, not here); a leading ``@`` is the abstract
        namespace. None or empty: notifications are dropped silently.
    watchdog_usec
        The value of ``WATCHDOG_USEC``: when set, `watchdog_due` tells when the next ping is due (half the period).
    """

    def __init__(self, socket_path: str | None = None, watchdog_usec: int | None = None) -> None:
        self._address: str | bytes | None = None
        if socket_path:
            self._address = b"\0" + socket_path[1:].encode() if socket_path.startswith("@") else socket_path
        self.watchdog_period_s = watchdog_usec / 2e6 if watchdog_usec else None
        self.sent: list[str] = []
        self.failed = 0
        """Notifications that could not be sent (no reader, or its queue full)."""

    @property
    def enabled(self) -> bool:
        """True when running under systemd with a notify socket."""
        return self._address is not None

    def notify(self, text: str) -> None:
        """Send one notification such as ``READY=1`` or ``STATUS=...``; failures are logged, never raised."""
        if self._address is None:
            return
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
                # Never block the measuring loop: a notify socket whose queue is full (its reader stalled) drops
                # the message instead (a blocking send waited until the reader came back).
                sock.setblocking(False)
                sock.sendto(text.encode(), self._address)
            self.sent.append(text)
        except OSError as exc:
            self.failed += 1
            if self.failed & (self.failed - 1) == 0:  # 1st, 2nd, 4th, 8th ...: a stalled reader does not flood the log
                _log.warning("systemd notification %r failed (%d so far): %s", text, self.failed, exc)

    def ready(self, status: str = "") -> None:
        """Tell systemd the service is up (after the pipeline has warmed up)."""
        self.notify("READY=1" + (f"\nSTATUS={status}" if status else ""))

    def watchdog(self) -> None:
        """Ping the watchdog: the main loop is alive."""
        self.notify("WATCHDOG=1")

    def status(self, text: str) -> None:
        """Show a one-line status in `systemctl status`."""
        self.notify(f"STATUS={text}")

    def stopping(self) -> None:
        """Tell systemd the service is shutting down."""
        self.notify("STOPPING=1")
