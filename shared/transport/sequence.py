"""Receiver-side accounting of sequence numbers: losses, duplicates, reordering and restarts, per device id.

Sequence numbers are uint32 and wrap; comparisons use serial-number arithmetic. A message more than `window` behind
the newest one cannot be told from a very old duplicate and is counted as stale. A device restart (its numbers start
again near 0) is recognised by a large backward jump, or by a run of consecutive "duplicates" that keep increasing.
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
    _duplicate_run: int = field(default=0, repr=False)
    _run_last: int = field(default=-1, repr=False)


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

    def observe(self, device_id: int, sequence: int) -> Arrival:
        """Account for one message and say what it was."""
        if not 0 <= sequence < _MODULUS:
            raise ValueError(f"sequence must be a uint32, got {sequence}")
        state = self._devices.get(device_id)
        if state is None:
            state = self._devices[device_id] = SequenceStats(received=1, newest=sequence)
            return Arrival.FIRST
        state.received += 1
        ahead = (sequence - state.newest) % _MODULUS
        if 0 < ahead < _HALF:
            state._duplicate_run = 0
            state.lost += ahead - 1
            end = state.newest + ahead  # unwrapped; the gap is newest+1 .. end-1
            for missing in range(max(state.newest + 1, end - self.window), end):
                state._missing.add(missing % _MODULUS)
                state._missing_order.append(missing % _MODULUS)
            state.newest = sequence
            self._evict(state)
            return Arrival.NEW
        behind = (state.newest - sequence) % _MODULUS
        if behind > self.window:
            if behind > 4 * self.window:
                return self._restart(state, sequence)
            state.stale += 1
            return Arrival.STALE
        if sequence in state._missing:
            state._missing.discard(sequence)
            state.lost -= 1
            state.reordered += 1
            state._duplicate_run = 0
            return Arrival.LATE
        state.duplicates += 1
        # A restarted sender replays numbers we have seen, in increasing order: after a run of them, start over.
        increasing = state._run_last >= 0 and (sequence - state._run_last) % _MODULUS == 1
        state._duplicate_run = state._duplicate_run + 1 if increasing else 1
        state._run_last = sequence
        if state._duplicate_run >= _RESTART_RUN:
            state.duplicates -= _RESTART_RUN  # they were the restarted sender's first messages, not duplicates
            return self._restart(state, sequence)
        return Arrival.DUPLICATE

    def _restart(self, state: SequenceStats, sequence: int) -> Arrival:
        state.restarts += 1
        state.newest = sequence
        state._missing.clear()
        state._missing_order.clear()
        state._duplicate_run = 0
        state._run_last = -1
        return Arrival.RESTART

    def _evict(self, state: SequenceStats) -> None:
        while state._missing_order:
            value = state._missing_order[0]
            if (state.newest - value) % _MODULUS <= self.window:
                break
            state._missing_order.popleft()
            state._missing.discard(value)
