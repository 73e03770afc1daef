"""SequenceTracker: wrap-around, gaps filled late, duplicates, stale numbers, restarts, several devices."""

from __future__ import annotations

import pytest

from ropecam.shared.transport import Arrival, SequenceTracker


def _feed(tracker: SequenceTracker, sequences: list[int], device: int = 1) -> list[Arrival]:
    return [tracker.observe(device, s) for s in sequences]


def test_in_order_gap_late_and_duplicate() -> None:
    tracker = SequenceTracker()
    verdicts = _feed(tracker, [10, 11, 14, 12, 12, 15])
    assert verdicts == [Arrival.FIRST, Arrival.NEW, Arrival.NEW, Arrival.LATE, Arrival.DUPLICATE, Arrival.NEW]
    stats = tracker.stats(1)
    assert (stats.lost, stats.reordered, stats.duplicates, stats.received) == (1, 1, 1, 6)


def test_wrap_around_is_not_a_loss() -> None:
    tracker = SequenceTracker()
    _feed(tracker, [2**32 - 2, 2**32 - 1, 0, 1, 3])
    assert tracker.stats(1).lost == 1
    assert tracker.observe(1, 2) is Arrival.LATE
    assert tracker.stats(1).lost == 0


def test_stale_and_restart_by_large_jump() -> None:
    tracker = SequenceTracker(window=100)
    _feed(tracker, list(range(1000, 1300)))
    assert tracker.observe(1, 1000) is Arrival.STALE  # 299 behind: more than the window, less than 4 windows
    assert tracker.observe(1, 5) is Arrival.RESTART  # far behind: the device started over
    assert tracker.observe(1, 6) is Arrival.NEW
    stats = tracker.stats(1)
    assert (stats.stale, stats.restarts, stats.lost) == (1, 1, 0)


def test_restart_detected_from_a_run_of_increasing_duplicates() -> None:
    tracker = SequenceTracker(window=4096)
    _feed(tracker, list(range(0, 500)))
    verdicts = _feed(tracker, list(range(0, 20)))  # a device restarted 4 s after the previous start
    assert verdicts[:15] == [Arrival.DUPLICATE] * 15
    assert verdicts[15] is Arrival.RESTART and verdicts[16:] == [Arrival.NEW] * 4
    stats = tracker.stats(1)
    assert (stats.duplicates, stats.restarts, stats.lost) == (0, 1, 0)


def test_gap_longer_than_the_window_still_counts_every_loss() -> None:
    tracker = SequenceTracker(window=16)
    _feed(tracker, [0, 1000])
    assert tracker.stats(1).lost == 999
    assert tracker.observe(1, 990) is Arrival.LATE
    assert tracker.observe(1, 960) is Arrival.STALE  # 40 behind: beyond the window of 16
    assert tracker.stats(1).lost == 998


def test_devices_are_independent_and_input_checked() -> None:
    tracker = SequenceTracker()
    _feed(tracker, [0, 2], device=1)
    _feed(tracker, [0, 1], device=2)
    assert tracker.devices() == [1, 2]
    assert (tracker.stats(1).lost, tracker.stats(2).lost) == (1, 0)
    with pytest.raises(ValueError, match="uint32"):
        tracker.observe(1, -1)
