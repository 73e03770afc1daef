"""Receiver-side accounting of sequence numbers: losses, duplicates, reordering and restarts, per device id.

Sequence numbers are uint32 and wrap; comparisons use serial-number arithmetic. A message more than `window` behind
the newest one cannot be told from a very old duplicate and is counted as stale. A device restart (its numbers start
again near 0) is recognised

* at its first message, when the receiver passes the header's t_ns and the message was made after the newest one
  (the device's clock kept running) or carries another t_ns than the message first seen with its number;
* by a jump back of more than 4 windows;
* by 2 increasing numbers in a row more than a window behind (only the first is lost), or 16 within the window.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from enum import Enum
from typing import Final

__all__ = ["Arrival", "SequenceStats", "SequenceTracker"]

_MODULUS: Final = 1 << 32
_HALF: Final = 1 << 31
_RESTART_RUN: Final = 16
"""Increasing numbers in a row within the window (duplicates to a receiver without t_ns) that mean a restart."""
_STALE_RESTART_RUN: Final = 2
"""Increasing numbers in a row behind the newest, the first more than a window behind, that mean a restart."""


class Arrival(Enum):
    """What one message's sequence number says."""

    FIRST = "first"
    NEW = "new"
    """Next in order, or ahead (the gap is counted lost until it arrives)."""
    LATE = "late"
    """Arrived after a later message (reordered); it fills a gap, so it is not lost after all."""
    DUPLICATE = "duplicate"
    STALE = "stale"
    """Too old to tell (more than `window` behind)."""
    RESTART = "restart"
    """The sender started over; counting continues from here."""

    @property
    def accept(self) -> bool:
        """True when the message should be used (not a duplicate or stale)."""
        return self in (Arrival.FIRST, Arrival.NEW, Arrival.LATE, Arrival.RESTART)


@dataclass(slots=True)
class SequenceStats:
    """Counts for one device."""

    received: int = 0
    lost: int = 0
    """Messages never received (gaps, minus the late arrivals that filled them)."""
    duplicates: int = 0
    reordered: int = 0
    stale: int = 0
    restarts: int = 0
    newest: int = 0
    _missing: set[int] = field(default_factory=set, repr=False)
    _missing_order: deque[int] = field(default_factory=deque, repr=False)
    _back_run: int = field(default=0, repr=False)
    _run_last: int = field(default=-1, repr=False)
    _run_stale: int = field(default=0, repr=False)
    _t_ns: dict[int, int] = field(default_factory=dict, repr=False)
    _t_ns_order: deque[int] = field(default_factory=deque, repr=False)
    _newest_t_ns: int | None = field(default=None, repr=False)


class SequenceTracker:
    """Feed it (device id, sequence) for every decoded message; read `stats(device_id)`.

    Parameters
    ----------
    window
        How many sequence numbers behind the newest are remembered for duplicate and reorder detection.
    """

    def __init__(self, window: int = 4096) -> None:
        if window < 1:
            raise ValueError(f"window must be >= 1, got {window}")
        self.window = window
        self._devices: dict[int, SequenceStats] = {}

    def devices(self) -> list[int]:
        """Device ids seen so far."""
        return sorted(self._devices)

    def stats(self, device_id: int) -> SequenceStats:
        """Counts for `device_id` (zeros if never seen)."""
        return self._devices.get(device_id, SequenceStats())

    def observe(self, device_id: int, sequence: int, t_ns: int | None = None) -> Arrival:
        """Account for one message and say what it was.

        Parameters
        ----------
        device_id, sequence
            From the message header.
        t_ns
            The header's t_ns (the sender's clock when it made the message), or None. With it a restarted sender is
            recognised at its first message whenever its clock kept running (daemon restart: a number seen before,
            made later) or the number is in the window with another t_ns (a true duplicate has the same t_ns).
            The sender's clock must not go backwards while it runs (CLOCK_MONOTONIC).
        """
        if not 0 <= sequence < _MODULUS:
            raise ValueError(f"sequence must be a uint32, got {sequence}")
        state = self._devices.get(device_id)
        if state is None:
            state = self._devices[device_id] = SequenceStats(received=1, newest=sequence)
            self._remember(state, sequence, t_ns)
            return Arrival.FIRST
        state.received += 1
        ahead = (sequence - state.newest) % _MODULUS
        if 0 < ahead < _HALF:
            state._back_run = state._run_stale = 0
            state.lost += ahead - 1
            end = state.newest + ahead  # unwrapped; the gap is newest+1 .. end-1
            for missing in range(max(state.newest + 1, end - self.window), end):
                state._missing.add(missing % _MODULUS)
                state._missing_order.append(missing % _MODULUS)
            state.newest = sequence
            self._remember(state, sequence, t_ns)
            self._evict(state)
            return Arrival.NEW
        behind = (state.newest - sequence) % _MODULUS
        if t_ns is not None and self._made_after_restart(state, sequence, t_ns, behind):
            return self._restart(state, sequence, t_ns)
        if t_ns is not None and behind <= self.window and sequence in state._t_ns:
            state.duplicates += 1  # same number, same t_ns: certainly a copy, whatever runs it makes
            return Arrival.DUPLICATE
        # A restarted sender sends numbers behind the newest, in increasing order: after a run of them, start over.
        increasing = state._run_last >= 0 and (sequence - state._run_last) % _MODULUS == 1
        state._back_run = state._back_run + 1 if increasing else 1
        state._run_stale = state._run_stale if increasing else 0
        state._run_last = sequence
        # Increasing numbers in a row, at least one of them more than a window late: not something a network does.
        stale_run = state._run_stale > 0 or behind > self.window
        if behind > 4 * self.window or (stale_run and state._back_run >= _STALE_RESTART_RUN):
            self._uncount_run(state)
            return self._restart(state, sequence, t_ns)
        if behind > self.window:
            state.stale += 1
            state._run_stale += 1
            return Arrival.STALE
        if sequence in state._missing:
            state._missing.discard(sequence)
            state.lost -= 1
            state.reordered += 1
            state._back_run = state._run_stale = 0
            state._run_last = -1
            return Arrival.LATE
        if state._back_run >= _RESTART_RUN:
            self._uncount_run(state)
            return self._restart(state, sequence, t_ns)
        state.duplicates += 1
        return Arrival.DUPLICATE

    @staticmethod
    def _uncount_run(state: SequenceStats) -> None:
        """The run's earlier members were the restarted sender's first messages, not stale or duplicates."""
        state.stale -= state._run_stale
        state.duplicates -= state._back_run - 1 - state._run_stale

    def _made_after_restart(self, state: SequenceStats, sequence: int, t_ns: int, behind: int) -> bool:
        """True when a number at or behind the newest cannot be a duplicate or a late message, judging by its t_ns."""
        if state._newest_t_ns is not None and t_ns > state._newest_t_ns:
            return True  # made after the newest message, numbered before it
        if behind <= self.window and sequence in state._t_ns:
            return state._t_ns[sequence] != t_ns  # a true duplicate carries the original's t_ns
        return False

    def _remember(self, state: SequenceStats, sequence: int, t_ns: int | None) -> None:
        if t_ns is None:
            return
        state._newest_t_ns = t_ns
        if sequence not in state._t_ns:
            state._t_ns_order.append(sequence)
        state._t_ns[sequence] = t_ns

    def _restart(self, state: SequenceStats, sequence: int, t_ns: int | None) -> Arrival:
        state.restarts += 1
        state.newest = sequence
        state._missing.clear()
        state._missing_order.clear()
        state._t_ns.clear()
        state._t_ns_order.clear()
        state._newest_t_ns = None
        state._back_run = state._run_stale = 0
        state._run_last = -1
        self._remember(state, sequence, t_ns)
        return Arrival.RESTART

    def _evict(self, state: SequenceStats) -> None:
        while state._missing_order:
            value = state._missing_order[0]
            if (state.newest - value) % _MODULUS <= self.window:
                break
            state._missing_order.popleft()
            state._missing.discard(value)
        while state._t_ns_order and (state.newest - state._t_ns_order[0]) % _MODULUS > self.window:
            state._t_ns.pop(state._t_ns_order.popleft(), None)
