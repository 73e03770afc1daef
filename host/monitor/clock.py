"""Device clock -> host clock: the offset of each device's clock, from the messages' send and receive times.

A message stamped ``t_ns`` by the device (its clock, usually monotonic since boot) and received at ``receive_t_ns``
(host wall clock) gives ``receive_t_ns - t_ns = offset + transit delay``. The smallest such difference over the
last `window_s` is the offset up to the shortest transit delay (tens of microseconds on a LAN or serial link), and
follows a slow drift of the two clocks. A difference far below the current offset (the device clock jumped
forward) is taken at once; one far above it (the device rebooted and its clock restarted) resets the estimate.
"""

from __future__ import annotations

from collections import deque
from typing import Final

__all__ = ["ClockMap"]

RESET_NS: Final = 1_000_000_000
"""A transit delay above this is not believed: the device clock restarted."""


class ClockMap:
    """Per-device offset between the device clock and the host clock.

    Parameters
    ----------
    window_s
        The offset is the smallest (receive - send) difference of this long a span of receive times.
    """

    def __init__(self, window_s: float = 10.0) -> None:
        if not window_s > 0:
            raise ValueError(f"window_s must be > 0, got {window_s}")
        self._window_ns = int(window_s * 1e9)
        self._bucket_ns = max(1, self._window_ns // 10)
        self._minima: dict[int, deque[tuple[int, int]]] = {}  # device -> (bucket start, smallest difference)

    def observe(self, device_id: int, device_t_ns: int, receive_t_ns: int) -> None:
        """Account for one message the device stamped `device_t_ns` and the host received at `receive_t_ns`."""
        difference = receive_t_ns - device_t_ns
        minima = self._minima.setdefault(device_id, deque())
        if minima and difference - min(m for _, m in minima) > RESET_NS:
            minima.clear()
        bucket = receive_t_ns - receive_t_ns % self._bucket_ns
        if minima and minima[-1][0] == bucket:
            minima[-1] = (bucket, min(minima[-1][1], difference))
        else:
            minima.append((bucket, difference))
        while minima and minima[0][0] < bucket - self._window_ns:
            minima.popleft()

    def offset_ns(self, device_id: int) -> int | None:
        """Return host time minus device time for `device_id` (None before its first message)."""
        minima = self._minima.get(device_id)
        return min(m for _, m in minima) if minima else None

    def to_host(self, device_id: int, device_t_ns: int, fallback_ns: int) -> int:
        """Return `device_t_ns` on the host clock, or `fallback_ns` before the device's first message."""
        offset = self.offset_ns(device_id)
        return fallback_ns if offset is None else device_t_ns + offset
