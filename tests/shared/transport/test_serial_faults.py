"""Acceptance 3: serial over a real pty pair with 1 % byte corruption, insertions and drops.

0 corrupted messages accepted; every intact message decoded (resynchronisation within one message); the receiver's
loss count equals exactly the messages that did not arrive (line damage plus whole-message drops at the sender).
"""

from __future__ import annotations

import bisect
import os

import numpy as np
import pytest

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol import Log, decode_message, encode_message, frame
from ropecam.shared.transport import SequenceTracker

MESSAGES = int(os.environ.get("ROPECAM_SERIAL_FAULT_MESSAGES", "100000"))
BATCH = 20


@pytest.mark.slow
@pytest.mark.parametrize("pty_link", [{"fault_rate": 0.01, "seed": 7}], indirect=True)
def test_acceptance_one_percent_faults_on_a_pty_pair(pty_link) -> None:
    device, host, relay = pty_link
    rng = np.random.default_rng(1)
    texts = ["m" * int(n) for n in rng.integers(4, 60, 64)]
    sent: dict[int, bytes] = {}
    received: dict[int, bytes] = {}
    tracker = SequenceTracker()
    corrupted_accepted = bad_messages = 0

    def pump(timeout_s: float) -> None:
        nonlocal corrupted_accepted, bad_messages
        while (data := host.receive(timeout_s)) is not None:
            try:
                message = decode_message(data)
            except ProtocolError:
                bad_messages += 1
                continue
            sequence = message.header.sequence
            if tracker.observe(message.header.device_id, sequence).accept:
                received[sequence] = data
                if sent.get(sequence) != data:
                    corrupted_accepted += 1
            timeout_s = 0.0

    # The first and the last messages go through clean: losses before the first and after the last received
    # message are invisible to any receiver.
    fault_rate, relay.fault_rate = relay.fault_rate, 0.0
    first = encode_message(Log(20, "first"), device_id=9, sequence=0, t_ns=0)
    assert device.send(first)
    sent[0] = first
    pump(2.0)
    assert 0 in received
    relay.fault_rate = fault_rate
    clean_tail = 20
    sequence = 1
    while len(sent) < MESSAGES:
        if len(sent) >= MESSAGES - clean_tail:
            relay.fault_rate = 0.0
        for _ in range(BATCH):
            data = encode_message(Log(20, texts[sequence % 64]), device_id=9, sequence=sequence, t_ns=sequence)
            if device.send(data):
                sent[sequence] = data
            sequence += 1
        pump(0.001)
    # The last message must reach the line: a sender's drop of the very last one would be invisible to the
    # receiver, and the loss count below could not be exact. Reading meanwhile lets the line drain.
    last = encode_message(Log(20, "last"), device_id=9, sequence=sequence, t_ns=sequence)
    last_refused = 0  # the sender's count of drops includes the refused tries of the last message
    while not device.send(last):
        last_refused += 1
        assert last_refused < 1000, "the line stayed busy for 10 s: the last message could not be sent"
        pump(0.01)
    sent[sequence] = last
    attempts = sequence + 1
    # Read until the line has been quiet for a second: what was sent has arrived or was lost on the line.
    while True:
        heard = len(received) + bad_messages + host.stats.bad_frames
        pump(1.0)
        if len(received) + bad_messages + host.stats.bad_frames == heard:
            break

    # Which sent messages were touched by a fault? Their spans in the clean stream are known exactly.
    order = sorted(sent)
    starts = np.cumsum([0] + [len(frame(sent[s])) for s in order])
    damaged = set()
    for fault in relay.faults:
        index = bisect.bisect_right(starts, fault.offset) - 1
        if index >= len(order):
            continue
        last_byte = starts[index + 1] - 1
        if fault.kind == "insert" and fault.offset == last_byte:
            continue  # inserted between two messages: garbage of its own, no message touched
        damaged.add(order[index])
    intact = set(order) - damaged
    stats = tracker.stats(9)

    print(  # shown with -s: the figures behind the acceptance
        f"attempts {attempts}, sent {len(sent)}, sender drops {device.stats.send_dropped}, faults {len(relay.faults)}"
        f" in {relay.forwarded} bytes, damaged {len(damaged)}, intact {len(intact)}, received {len(received)}, "
        f"lost {stats.lost}, corrupted accepted {corrupted_accepted}"
    )
    assert len(relay.faults) > 0.009 * relay.forwarded  # the fault rate was really applied
    assert len(sent) >= MESSAGES
    assert corrupted_accepted == 0
    assert intact <= set(received), f"{len(intact - set(received))} intact messages were not decoded"
    assert set(received) <= set(sent)
    assert stats.lost == attempts - len(received)  # exact: sender drops + line damage
    assert device.stats.send_dropped == attempts - len(sent) + last_refused
    assert stats.duplicates == stats.reordered == 0
    assert bad_messages + host.stats.bad_frames > 0
