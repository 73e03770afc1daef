"""The result sender: one numbering without overlap across a close, a drain that keeps its timeout, no queue growth
after close, and the link-broken event after failed sends in a row."""

from __future__ import annotations

import threading
import time

import pytest

from ropecam.device.senders.stream import ResultSender
from ropecam.shared.errors import TransportError
from ropecam.shared.protocol import FrameResult, Log, MessageType, budget, decode_message
from ropecam.shared.protocol.examples import example_records
from ropecam.shared.transport.base import Transport


class SlowLine(Transport):
    """A line whose every send waits until the test lets it go (`gate`), or fails while `failing` is set."""

    def __init__(self) -> None:
        super().__init__("test://slow")
        self.gate = threading.Semaphore(0)
        self.failing = False
        self.sequences: list[int] = []

    def send(self, message: bytes) -> bool:
        if self.failing:
            raise TransportError("write failed: [Errno 5] Input/output error")
        self.gate.acquire(timeout=5.0)
        self.sequences.append(decode_message(message).header.sequence)
        return True

    def receive(self, timeout_s: float | None = 0.0) -> bytes | None:
        return None


def test_close_keeps_its_drain_timeout_and_numbers_nothing_afterwards() -> None:
    line = SlowLine()
    sender = ResultSender(line, device_id=1, first_sequence=7)
    for i in range(50):
        sender.submit(Log(level=20, text=f"message {i}"))
    for _ in range(3):
        line.gate.release()  # three messages get through, then the line hangs
    sender.close(drain_timeout_s=0.1)
    final = sender.next_sequence
    line.gate.release(100)  # the line comes back: the sender thread must not number anything more
    sender._thread.join(5.0)
    assert not sender._thread.is_alive()
    assert sender.next_sequence == final
    assert line.sequences == list(range(7, final))
    assert sender.stats.sent + sender.stats.dropped_closed == 50
    # A sender that continues the numbering starts exactly where this one stopped: no overlap, no gap.
    follower = ResultSender(SlowLine(), device_id=1, first_sequence=sender.next_sequence)
    assert follower.next_sequence == line.sequences[-1] + 1
    follower.close(0.0)


def test_submit_after_close_is_counted_not_queued() -> None:
    sender = ResultSender(SlowLine(), device_id=1)
    sender.close(0.0)
    sender.submit(Log(level=20, text="late"))
    sender.submit_frame(object())  # type: ignore[arg-type]  # never encoded: refused before
    assert sender.backlog() == 0 and sender.stats.dropped_closed == 2


class Unpackable:
    """A record whose payload cannot be packed (as a value outside what the wire can carry)."""

    TYPE = MessageType.LOG

    def pack(self, *args: object, **kwargs: object) -> bytes:
        raise ValueError("cannot be packed")


def test_encode_error_does_not_use_up_a_sequence_number() -> None:
    line = SlowLine()
    line.gate.release(10)
    sender = ResultSender(line, device_id=1)
    sender.submit(Unpackable())
    sender.submit(Log(level=20, text="fine"))
    sender.close(2.0)
    assert sender.stats.encode_errors == 1 and line.sequences == [0]


def test_a_frame_the_budget_cannot_hold_is_an_encode_error_and_the_sender_goes_on(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A frame result that fits the byte budget in no form (not reachable with a budget >= MIN_BUDGET_BYTES: made
    here by a size bound that no message meets) is counted and skipped like any frame that cannot be encoded; the
    sender thread keeps sending (it ended on the budget's AssertionError, and every later message was lost)."""
    monkeypatch.setattr(budget, "framed_bytes_bound", lambda message_bytes: 10**9)
    line = SlowLine()
    line.gate.release(10)
    sender = ResultSender(line, device_id=1, frame_budget_bytes=774)
    record = example_records()[MessageType.FRAME_RESULT]
    assert isinstance(record, FrameResult)
    sender.submit_frame(record)
    until = time.monotonic() + 5.0
    while sender.backlog() and time.monotonic() < until:  # the frame taken first (logs go ahead of frames)
        time.sleep(0.01)
    sender.submit(Log(level=20, text="after the frame"))
    sender.close(2.0)
    assert sender.stats.encode_errors == 1 and line.sequences == [0]


def test_three_failed_sends_in_a_row_set_link_broken() -> None:
    line = SlowLine()
    line.gate.release(100)
    sender = ResultSender(line, device_id=1, broken_after=3)
    line.failing = True
    for text in ("a", "b"):
        sender.submit(Log(level=20, text=text))
    _wait_tried(sender, 2)
    assert not sender.link_broken.is_set()  # two errors are not yet a broken link
    line.failing = False
    sender.submit(Log(level=20, text="ok"))  # a success resets the count
    _wait_tried(sender, 3)
    line.failing = True
    for text in ("c", "d"):
        sender.submit(Log(level=20, text=text))
    _wait_tried(sender, 5)
    assert not sender.link_broken.is_set()
    sender.submit(Log(level=20, text="last straw"))
    assert sender.link_broken.wait(5.0)
    assert sender.stats.link_errors == 5 and sender.stats.sent == 1
    sender.close(0.5)


def _wait_tried(sender: ResultSender, attempts: int) -> None:
    """Wait until `attempts` messages have been tried (sent or failed)."""
    event = threading.Event()
    for _ in range(500):
        if sender.stats.sent + sender.stats.link_errors >= attempts:
            return
        event.wait(0.01)
    raise AssertionError(f"only {sender.stats.sent + sender.stats.link_errors} of {attempts} sends tried")


def test_wait_sent_returns_once_the_queue_and_the_record_in_hand_are_sent() -> None:
    """A final Status is made after `wait_sent`: the frames queued before it are out and counted, including the one
    the sender thread had taken but not yet sent; a line that hangs makes it give up after its timeout."""
    line = SlowLine()
    sender = ResultSender(line, device_id=1)
    for i in range(3):
        sender.submit(Log(level=20, text=f"message {i}"))
    assert not sender.wait_sent(0.05)  # the line hangs on the first message: nothing went out
    line.gate.release(2)
    deadline = time.monotonic() + 5.0
    while len(line.sequences) < 2 and time.monotonic() < deadline:
        time.sleep(0.001)
    assert len(line.sequences) == 2
    assert not sender.wait_sent(0.05)  # the third is taken from the queue (or about to be), not sent
    line.gate.release(1)
    assert sender.wait_sent(5.0) and sender.stats.sent == 3 and sender.backlog() == 0
    sender.close(0.0)
    assert not sender.wait_sent(0.0)  # closed: nothing will be sent any more
