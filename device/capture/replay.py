"""Replay a recorded frame set as a camera: paced at its frame rate (or a given one) or as fast as possible.

Paced replay behaves like a camera that started streaming at `start`: frame k becomes available at
``start_ns + offset_k``, where ``offset_k`` is the frame's index time minus the first frame's (scaled when another
frame rate is asked for, continued across loops), and a slow consumer gets the newest available frame while the
ones it missed count as skipped, exactly as with the camera.

A frame's ``t_ns`` (start of its exposure) keeps the recording's time base: ``start_ns`` plus the frame's unscaled
index offset (one set length more per loop). The exposure times are measurement data: the rope moved between two
frames as much as the recorded interval says, so a replay at another rate (slow motion) must not rewrite them, or
everything downstream (time order of the two shapes, velocities, the model's time axis) would be wrong. At the
set's own rate the two clocks coincide. Unpaced replay uses the index's own ``t_ns`` (plus one set length per loop).

Frames are decoded once and kept in one read-only array when they fit in `max_preload_bytes`, so a read costs a few
microseconds; larger sets are decoded from disk on each read.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ropecam.device.capture.frameset import FrameSet
from ropecam.device.capture.source import CameraSource, CapturedFrame
from ropecam.shared.errors import CaptureError, DataError

__all__ = ["DEFAULT_MAX_PRELOAD_BYTES", "FrameSetSource"]

log = logging.getLogger(__name__)

DEFAULT_MAX_PRELOAD_BYTES = 512 * 2**20


class FrameSetSource(CameraSource):
    """A `CameraSource` over a recorded frame set (`ropecam.device.capture.frameset`).

    Parameters
    ----------
    frames
        The frame set, or its folder.
    fps
        Replay rate in frames per second; None replays at the set's own rate (its index times).
    paced
        True: frames become available in real time (newest-frame policy applies). False: as fast as the consumer
        reads, every frame in order.
    loop
        Start again after the last frame (sequence numbers and times continue); otherwise `finished` becomes True.
    max_preload_bytes
        Decode all frames into memory at `start` when they need at most this many bytes.
    clock, sleep
        Monotonic clock in ns and sleep in s; replaceable for tests.

    Raises
    ------
    DataError
        The set cannot be read or is empty.
    ValueError
        `fps` or `max_preload_bytes` is not positive.
    """

    def __init__(
        self,
        frames: FrameSet | str | Path,
        fps: float | None = None,
        paced: bool = True,
        loop: bool = False,
        max_preload_bytes: int = DEFAULT_MAX_PRELOAD_BYTES,
        clock: Callable[[], int] = time.monotonic_ns,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.frameset = frames if isinstance(frames, FrameSet) else FrameSet(frames)
        super().__init__(f"frames:{self.frameset.root}")
        if len(self.frameset) == 0:
            raise DataError(f"{self.frameset.root}: frame set has no frames")
        if fps is not None and not (np.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be > 0, got {fps!r}")
        if max_preload_bytes < 0:
            raise ValueError(f"max_preload_bytes must be >= 0, got {max_preload_bytes!r}")
        self._fps = float(fps) if fps is not None else self.frameset.fps
        self.paced = bool(paced)
        self.loop = bool(loop)
        self.max_preload_bytes = int(max_preload_bytes)
        self._clock = clock
        self._sleep = sleep
        records = self.frameset.records
        for before, after in itertools.pairwise(records):
            if after.t_ns <= before.t_ns or after.frame <= before.frame:
                raise DataError(
                    f"{self.frameset.root}: index goes back at frame {after.frame} (t_ns {after.t_ns} after "
                    f"{before.t_ns}, frame {after.frame} after {before.frame}); times and numbers must increase"
                )
        scale = self.frameset.fps / self._fps
        t0 = records[0].t_ns
        # Offsets of each frame from the first, at the replay rate; one loop lasts the set plus one frame period.
        self._offsets_ns = np.array([round((r.t_ns - t0) * scale) for r in records], dtype=np.int64)
        self._loop_ns = int(self._offsets_ns[-1]) + round(1e9 / self._fps)
        self._index_t_ns = np.array([r.t_ns for r in records], dtype=np.int64)
        self._loop_index_ns = int(self._index_t_ns[-1] - t0) + round(1e9 / self.frameset.fps)
        self._frame_numbers = [r.frame for r in records]
        self._loop_frames = records[-1].frame - records[0].frame + 1
        self._exposures = [r.exposure_us for r in records]
        self._preloaded: NDArray[np.uint8] | None = None
        self._decoded = 0  # preloaded frames decoded so far (the preload thread decodes them in order)
        self._preload_error: CaptureError | None = None
        self._preload_ready = threading.Condition()
        self._next = 0  # frames (counting across loops) handed over or skipped so far
        self._last_position = 0  # index position of the frame delivered last
        self._start_ns = 0

    # -- properties ----------------------------------------------------------------------------------------------
    @property
    def image_size(self) -> tuple[int, int]:
        return self.frameset.image_size

    @property
    def fps(self) -> float:
        return self._fps

    @property
    def exposure_us(self) -> int:
        """Exposure time of the frame delivered last (of the first frame before any)."""
        return self._exposures[self._last_position]

    @property
    def pixel_format(self) -> str:
        return "frames"

    @property
    def preloaded(self) -> bool:
        """True when the frames are held in memory (decided at `start`)."""
        return self._preloaded is not None

    @property
    def finished(self) -> bool:
        return self._started and not self.loop and self._next >= len(self.frameset)

    # -- lifecycle -----------------------------------------------------------------------------------------------
    def _open(self) -> None:
        width, height = self.frameset.image_size
        needed = len(self.frameset) * width * height
        if needed <= self.max_preload_bytes and self._preloaded is None:
            # The first frame now, the others in the background (a camera's first frame does not wait for the
            # whole recording to be decoded: 0.5 s for 60 rig frames); a read of a frame not yet decoded waits.
            missing = next((r for r in self.frameset.records if not Path(r.path).is_file()), None)
            if missing is not None:  # refused at start, as a whole-set preload would be; a corrupt file is found
                raise CaptureError(  # when its frame is read
                    f"{self.name}: {Path(missing.path).name}: missing or unreadable image (frame {missing.frame})"
                )
            frames = np.empty((len(self.frameset), height, width), dtype=np.uint8)
            frames[0] = self._decode(0)
            view = frames.view()
            view.flags.writeable = False
            self._preloaded = view
            self._decoded = 1
            self._preload_error = None
            if len(frames) > 1:
                thread = threading.Thread(target=self._preload, args=(frames,), name="frameset-preload", daemon=True)
                thread.start()
        elif self._preloaded is None:
            log.info("%s: %.1f MB exceed the preload limit; decoding frames on read", self.name, needed / 1e6)
        self._next = 0
        self._last_position = 0
        self._start_ns = self._clock()

    def _preload(self, frames: NDArray[np.uint8]) -> None:
        """Decode frames 1.. into `frames` (the preload thread), announcing each one."""
        started = time.perf_counter()
        for position in range(1, len(frames)):
            try:
                frames[position] = self._decode(position)
            except CaptureError as exc:
                with self._preload_ready:
                    self._preload_error = exc
                    self._preload_ready.notify_all()
                return
            with self._preload_ready:
                self._decoded = position + 1
                self._preload_ready.notify_all()
        log.info("%s: preloaded %d frames (%.1f MB) in %.2f s", self.name, len(frames), frames.nbytes / 1e6,
                 time.perf_counter() - started)  # fmt: skip

    def _preloaded_frame(self, position: int) -> NDArray[np.uint8]:
        """The preloaded frame at `position`, once the preload thread has decoded it."""
        assert self._preloaded is not None
        if self._decoded <= position:
            with self._preload_ready:
                while self._decoded <= position and self._preload_error is None:
                    self._preload_ready.wait(1.0)
            if self._decoded <= position and self._preload_error is not None:
                raise self._preload_error
        return self._preloaded[position]

    def _close(self) -> None:
        """Keep the preloaded frames: a restarted replay does not decode again."""

    def _decode(self, position: int) -> NDArray[np.uint8]:
        try:
            return self.frameset.read(position)
        except DataError as exc:
            raise CaptureError(f"{self.name}: {exc}") from exc

    # -- frames --------------------------------------------------------------------------------------------------
    def _schedule_ns(self, k: int) -> int:
        loops, position = divmod(k, len(self.frameset))
        return self._start_ns + loops * self._loop_ns + int(self._offsets_ns[position])

    def _last_available(self, now_ns: int) -> int:
        """Return the largest frame count k whose frame is available at `now_ns` (-1 when none yet)."""
        n = len(self.frameset)
        elapsed = now_ns - self._start_ns
        if elapsed < 0:
            return -1
        loops, rest = divmod(elapsed, self._loop_ns)
        position = int(np.searchsorted(self._offsets_ns, rest, side="right")) - 1
        return loops * n + position

    def _read(self, timeout_s: float) -> CapturedFrame | None:
        n = len(self.frameset)
        if not self.loop and self._next >= n:
            return None
        if not self.paced:
            k = self._next
        else:
            deadline_ns = self._clock() + round(timeout_s * 1e9)
            while True:
                now_ns = self._clock()
                newest = self._last_available(now_ns)
                if not self.loop:
                    newest = min(newest, n - 1)
                if newest >= self._next:
                    break
                due_ns = self._schedule_ns(self._next)
                if due_ns > deadline_ns:
                    wait_ns = deadline_ns - now_ns
                    if wait_ns > 0:
                        self._sleep(wait_ns / 1e9)
                    return None
                self._sleep(max(due_ns - now_ns, 0) / 1e9)
            k = newest
            self.counters.skipped += k - self._next
        loops, position = divmod(k, n)
        sequence = self._sequence(k)
        # Frames the pacing overtook are `skipped`; only the recording's own gaps (frame numbers missing from the
        # index) count as dropped, those before the first frame handed over too (a slow start overtook a gap).
        last = self._frame_numbers[0] - 1 if self._last_sequence is None else self._last_sequence
        self.counters.dropped += (sequence - last - 1) - (k - self._next)
        self._last_sequence = sequence
        self._next = k + 1
        self._last_position = position
        # The recording's exposure times: moved onto this clock when paced, as in the index otherwise (see above).
        recorded_ns = int(self._index_t_ns[position] - self._index_t_ns[0]) + loops * self._loop_index_ns
        t_ns = self._start_ns + recorded_ns if self.paced else int(self._index_t_ns[0]) + recorded_ns
        if self._preloaded is not None:
            image = self._preloaded_frame(position)
        else:
            image = self._decode(position)
            image.flags.writeable = False
        return CapturedFrame(image, sequence, t_ns, self._exposures[position])

    def _sequence(self, k: int) -> int:
        loops, position = divmod(k, len(self.frameset))
        return self._frame_numbers[position] + loops * self._loop_frames
