"""Recorded frame sets as a camera: unpaced order, loops, paced newest-frame reads on a fake clock, recorded gaps."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSetWriter
from ropecam.device.capture.replay import FrameSetSource
from ropecam.shared.errors import CaptureError, DataError

FPS = 100.0
PERIOD_NS = 10_000_000
T0_NS = 1_000_000


class FakeClock:
    """A monotonic clock that only moves when told to (or when the source sleeps)."""

    def __init__(self, now_ns: int = 50_000_000_000) -> None:
        self.now_ns = now_ns
        self.sleeps: list[float] = []

    def __call__(self) -> int:
        return self.now_ns

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now_ns += round(seconds * 1e9)


def _write(root: Path, frames: int = 5) -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    images = [rng.integers(0, 256, (12, 16), dtype=np.uint8) for _ in range(frames)]
    with FrameSetWriter(root, (16, 12), FPS) as writer:
        for i, image in enumerate(images):
            writer.add(image, t_ns=T0_NS + i * PERIOD_NS, exposure_us=1500 + i)
    return images


def test_unpaced_replays_every_frame_in_order_then_finishes(tmp_path: Path) -> None:
    images = _write(tmp_path / "set")
    source = FrameSetSource(tmp_path / "set", paced=False)
    with source:
        assert source.preloaded and source.image_size == (16, 12) and source.fps == FPS
        frames = [source.read(0) for _ in range(5)]
        assert source.finished
        assert source.read(0) is None
    for i, frame in enumerate(frames):
        assert frame is not None
        np.testing.assert_array_equal(frame.image, images[i])
        assert (frame.sequence, frame.t_ns, frame.exposure_us) == (i, T0_NS + i * PERIOD_NS, 1500 + i)
        assert not frame.image.flags.writeable and frame.image.flags.c_contiguous
    assert source.counters.as_dict() == {"delivered": 5, "skipped": 0, "dropped": 0, "timeouts": 0}


def test_loop_continues_sequence_numbers_and_times(tmp_path: Path) -> None:
    images = _write(tmp_path / "set")
    with FrameSetSource(tmp_path / "set", paced=False, loop=True) as source:
        frames = [source.read(0) for _ in range(12)]
        assert not source.finished
    assert [f.sequence for f in frames if f] == list(range(12))
    assert [f.t_ns for f in frames if f] == [T0_NS + k * PERIOD_NS for k in range(12)]
    np.testing.assert_array_equal(frames[11].image, images[1])  # type: ignore[union-attr]


def test_paced_replay_hands_over_the_newest_frame_on_the_clock(tmp_path: Path) -> None:
    images = _write(tmp_path / "set")
    clock = FakeClock()
    start = clock.now_ns
    with FrameSetSource(tmp_path / "set", clock=clock, sleep=clock.sleep) as source:
        first = source.read(0)
        assert first is not None and (first.sequence, first.t_ns) == (0, start)
        clock.now_ns += 3 * PERIOD_NS + PERIOD_NS // 2  # a slow consumer: frames 1 and 2 are overtaken
        newest = source.read(0)
        assert newest is not None and (newest.sequence, newest.t_ns) == (3, start + 3 * PERIOD_NS)
        np.testing.assert_array_equal(newest.image, images[3])
        assert source.read(0.001) is None  # frame 4 is due in 5 ms
        assert clock.sleeps[-1] == pytest.approx(0.001)
        waited = source.read(1.0)  # sleeps until it is due
        assert waited is not None and (waited.sequence, waited.t_ns) == (4, start + 4 * PERIOD_NS)
        assert clock.now_ns == start + 4 * PERIOD_NS
        assert source.read(1.0) is None and source.finished
    assert source.counters.as_dict() == {"delivered": 3, "skipped": 2, "dropped": 0, "timeouts": 1}


def test_paced_at_another_rate_and_looping(tmp_path: Path) -> None:
    _write(tmp_path / "set")
    clock = FakeClock()
    start = clock.now_ns
    with FrameSetSource(tmp_path / "set", fps=50.0, loop=True, clock=clock, sleep=clock.sleep) as source:
        times = []
        for _ in range(7):
            frame = source.read(1.0)
            assert frame is not None
            times.append(frame.t_ns - start)
        paced_until = clock.now_ns - start
    # Half the rate: frames are handed over at twice the period (slow motion), across the loop...
    assert paced_until == 6 * 2 * PERIOD_NS
    # ...but their exposure times keep the recording's period: they are measurement data.
    assert times == [k * PERIOD_NS for k in range(7)]


def test_recorded_gaps_count_as_drops_and_large_sets_are_decoded_on_read(tmp_path: Path) -> None:
    images = _write(tmp_path / "set")
    index = tmp_path / "set" / "index.csv"
    lines = index.read_text().splitlines()
    index.write_text("\n".join(lines[:3] + lines[4:]) + "\n")  # frame 2 was never recorded
    with FrameSetSource(tmp_path / "set", paced=False, max_preload_bytes=0) as source:
        assert not source.preloaded
        frames = [source.read(0) for _ in range(4)]
    assert [f.sequence for f in frames if f] == [0, 1, 3, 4]
    np.testing.assert_array_equal(frames[2].image, images[3])  # type: ignore[union-attr]
    assert source.counters.dropped == 1 and source.counters.delivered == 4


def test_a_gap_overtaken_before_the_first_frame_still_counts_as_dropped(tmp_path: Path) -> None:
    # The consumer's first read comes late, after the recording's gap (frame 2 was never recorded): every frame of
    # the span is accounted for (CI at load 16: a daemon started late counted 10 of 12 frames).
    _write(tmp_path / "set")
    index = tmp_path / "set" / "index.csv"
    lines = index.read_text().splitlines()
    index.write_text("\n".join(lines[:3] + lines[4:]) + "\n")
    clock = FakeClock()
    with FrameSetSource(tmp_path / "set", clock=clock, sleep=clock.sleep) as source:
        clock.now_ns += 3 * PERIOD_NS + PERIOD_NS // 2  # frames 0, 1 and 3 are due: 3 is the newest
        first = source.read(0)
        assert first is not None and first.sequence == 3
        rest = [source.read(1.0) for _ in range(2)]
    assert [f.sequence for f in rest if f] == [4]
    assert source.counters.as_dict() == {"delivered": 2, "skipped": 2, "dropped": 1, "timeouts": 0}


def test_bad_sets_are_refused(tmp_path: Path) -> None:
    _write(tmp_path / "set")
    (tmp_path / "set" / "frames" / "000003.png").unlink()
    with pytest.raises(CaptureError, match=r"000003.png: missing or unreadable image \(frame 3\)"):
        FrameSetSource(tmp_path / "set").start()
    _write(tmp_path / "corrupt")
    (tmp_path / "corrupt" / "frames" / "000003.png").write_bytes(b"not a png")
    with FrameSetSource(tmp_path / "corrupt", paced=False) as preloading:  # decoded in the background
        for _ in range(3):
            assert preloading.read(0) is not None
        with pytest.raises(CaptureError, match=r"000003\.png"):
            preloading.read(0)
    streaming = FrameSetSource(tmp_path / "set", paced=False, max_preload_bytes=0)
    with streaming:
        for _ in range(3):
            assert streaming.read(0) is not None
        with pytest.raises(CaptureError, match=r"000003\.png"):
            streaming.read(0)
    with FrameSetWriter(tmp_path / "backwards", (16, 12), FPS) as writer:
        for t_ns in (0, PERIOD_NS, PERIOD_NS):
            writer.add(np.zeros((12, 16), np.uint8), t_ns=t_ns, exposure_us=100)
    with pytest.raises(DataError, match="index goes back at frame 2"):
        FrameSetSource(tmp_path / "backwards")
    FrameSetWriter(tmp_path / "empty", (16, 12), FPS).close()
    with pytest.raises(DataError, match="has no frames"):
        FrameSetSource(tmp_path / "empty")
    with pytest.raises(DataError, match="not a frame set"):
        FrameSetSource(tmp_path / "nowhere")
    with pytest.raises(ValueError, match="fps must be > 0"):
        FrameSetSource(tmp_path / "set", fps=0.0)


def test_a_recording_has_no_exposure_or_gain_to_set(tmp_path: Path) -> None:
    _write(tmp_path / "set")
    with FrameSetSource(tmp_path / "set", paced=False) as source:
        with pytest.raises(ValueError, match="cannot change the exposure"):
            source.set_exposure_us(1000)
        with pytest.raises(ValueError, match="no gain control"):
            source.set_gain(2)
        assert source.read(0) is not None


def test_zero_or_nan_rate_in_the_set_is_a_clear_error(tmp_path: Path) -> None:
    _write(tmp_path / "set")
    meta_path = tmp_path / "set" / "frameset.json"
    for fps in ("0", "NaN", "-1"):
        meta_path.write_text(re.sub(r'"fps": [^,]+', f'"fps": {fps}', meta_path.read_text()))
        with pytest.raises(DataError, match=r"frameset\.json: fps must be a finite number > 0"):
            FrameSetSource(tmp_path / "set")


@pytest.mark.parametrize("paced", [False, True])
def test_exposure_is_the_last_delivered_frames(tmp_path: Path, paced: bool) -> None:
    _write(tmp_path / "set")
    clock = FakeClock()
    source = FrameSetSource(tmp_path / "set", paced=paced, clock=clock, sleep=clock.sleep)
    assert source.exposure_us == 1500  # before any read: the first frame's
    with source:
        assert source.exposure_us == 1500
        if paced:
            clock.now_ns += 2 * PERIOD_NS  # frames 0..2 are available; the newest (2) is delivered
        frame = source.read(0)
        assert frame is not None and source.exposure_us == frame.exposure_us == (1502 if paced else 1500)
        while not source.finished:
            clock.now_ns += PERIOD_NS
            frame = source.read(1.0) or frame
        assert frame.sequence == 4 and source.exposure_us == 1504
