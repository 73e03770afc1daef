"""Acceptance 4: UDP on 127.0.0.1 with injected loss, reordering and duplicates: the counts are exact."""

from __future__ import annotations

import random

from ropecam.shared.protocol import Log, decode_message, encode_message
from ropecam.shared.transport import Arrival, SequenceTracker, open_transport


def test_acceptance_udp_loss_reorder_duplicates_counted_exactly() -> None:
    host = open_transport("udp://127.0.0.1:0?listen=1")
    device = open_transport(f"udp://127.0.0.1:{host.local_address[1]}")  # type: ignore[attr-defined]
    rng = random.Random(42)
    count = 6000
    messages = [encode_message(Log(20, f"m{i}"), device_id=4, sequence=i, t_ns=i) for i in range(count)]
    # The injector between the pipeline and the socket: drop, duplicate, hold back (reorder) with known counts.
    lost = {i for i in range(1, count - 1) if rng.random() < 0.05}
    duplicated = {i for i in range(count) if i not in lost and rng.random() < 0.03}
    held = {i for i in range(1, count - 10) if i not in lost and i not in duplicated and rng.random() < 0.04}
    schedule: list[int] = []
    late: list[tuple[int, int]] = []  # (release position, sequence)
    for i in range(count):
        if i in lost:
            continue
        if i in held:
            late.append((i + rng.randint(2, 8), i))
            continue
        schedule.append(i)
        if i in duplicated:
            schedule.append(i)
        for release, sequence in [x for x in late if x[0] <= i]:
            schedule.append(sequence)
            late.remove((release, sequence))
    schedule += [sequence for _, sequence in late]
    tracker = SequenceTracker()
    verdicts: dict[Arrival, int] = {}
    try:
        for start in range(0, len(schedule), 64):  # bursts the receiver keeps up with: the kernel drops nothing
            for sequence in schedule[start : start + 64]:
                assert device.send(messages[sequence])
            for _ in schedule[start : start + 64]:
                data = host.receive(2.0)
                assert data is not None
                message = decode_message(data)
                verdict = tracker.observe(message.header.device_id, message.header.sequence)
                verdicts[verdict] = verdicts.get(verdict, 0) + 1
    finally:
        device.close()
        host.close()
    stats = tracker.stats(4)
    assert stats.lost == len(lost)
    assert stats.duplicates == len(duplicated) == verdicts[Arrival.DUPLICATE]
    assert stats.reordered == len(held) == verdicts[Arrival.LATE]  # each held one arrives after a later one
    assert stats.received == len(schedule)
    assert stats.stale == stats.restarts == 0
