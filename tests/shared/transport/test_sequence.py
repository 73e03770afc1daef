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


@pytest.mark.parametrize("newest", [4097, 10_000, 16_384])
def test_restart_between_one_and_four_windows_back_loses_one_message(newest: int) -> None:
    tracker = SequenceTracker(window=4096)
    _feed(tracker, list(range(newest + 1)))
    verdicts = _feed(tracker, list(range(0, 50)))  # restarted: numbers 4097..16384 behind the newest
    assert verdicts[0] is Arrival.STALE
    assert verdicts[1] is Arrival.RESTART and verdicts[2:] == [Arrival.NEW] * 48
    stats = tracker.stats(1)
    assert (stats.stale, stats.duplicates, stats.restarts, stats.lost, stats.newest) == (0, 0, 1, 0, 49)


def test_a_single_stale_message_is_not_a_restart() -> None:
    tracker = SequenceTracker(window=100)
    _feed(tracker, list(range(1000, 1300)))
    assert _feed(tracker, [1000, 1300, 1001, 1301]) == [Arrival.STALE, Arrival.NEW, Arrival.STALE, Arrival.NEW]
    assert (tracker.stats(1).stale, tracker.stats(1).restarts) == (2, 0)


def _feed_timed(tracker: SequenceTracker, pairs: list[tuple[int, int]]) -> list[Arrival]:
    return [tracker.observe(1, sequence, t_ns) for sequence, t_ns in pairs]


@pytest.mark.parametrize("newest", [20, 500, 10_000, 100_000])
def test_with_t_ns_a_restart_loses_nothing(newest: int) -> None:
    tracker = SequenceTracker(window=4096)
    _feed_timed(tracker, [(s, 1_000_000 * s) for s in range(newest + 1)])
    restart_t_ns = 1_000_000 * (newest + 5000)  # daemon restarted: the device clock kept running
    verdicts = _feed_timed(tracker, [(s, restart_t_ns + 1_000_000 * s) for s in range(30)])
    assert verdicts == [Arrival.RESTART] + [Arrival.NEW] * 29
    assert (tracker.stats(1).duplicates, tracker.stats(1).stale, tracker.stats(1).restarts) == (0, 0, 1)


def test_with_t_ns_a_rebooted_sender_in_the_window_is_seen_at_once() -> None:
    tracker = SequenceTracker(window=4096)
    _feed_timed(tracker, [(s, 10_000_000_000 + s) for s in range(500)])
    # rebooted: CLOCK_MONOTONIC started over too, so only the t_ns that differs for a known number tells
    verdicts = _feed_timed(tracker, [(s, 2_000_000_000 + s) for s in range(5)])
    assert verdicts == [Arrival.RESTART] + [Arrival.NEW] * 4


def test_with_t_ns_runs_of_true_duplicates_stay_duplicates() -> None:
    tracker = SequenceTracker(window=4096)
    pairs = [(s, 1000 + s) for s in range(100)]
    _feed_timed(tracker, pairs)
    verdicts = _feed_timed(tracker, pairs[50:90])  # a network replaying 40 messages in order
    assert verdicts == [Arrival.DUPLICATE] * 40
    assert _feed_timed(tracker, [(100, 1100)]) == [Arrival.NEW]
    stats = tracker.stats(1)
    assert (stats.duplicates, stats.restarts, stats.lost) == (40, 0, 0)


def test_with_t_ns_late_and_stale_messages_are_not_restarts() -> None:
    tracker = SequenceTracker(window=100)
    _feed_timed(tracker, [(s, 10 * s) for s in range(1000) if s != 950])
    assert _feed_timed(tracker, [(950, 9500), (800, 8000), (850, 8500)]) == [
        Arrival.LATE,
        Arrival.STALE,
        Arrival.STALE,  # not increasing by one: no run
    ]
    assert tracker.stats(1).restarts == 0
