"""Send a whole camera frame as RawFrameChunk messages and put it back together on the host."""

from __future__ import annotations

from collections import deque
from typing import Final

import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.records import MAX_CHUNK_BYTES, PixelFormat, RawFrameChunk

__all__ = ["MAX_FRAME_BYTES", "FrameAssembler", "split_frame"]

MAX_FRAME_BYTES: Final = 16 << 20
"""Largest raw frame a `FrameAssembler` accepts by default (4096 x 4096 grey)."""
_FINISHED_MEMORY: Final = 16
_FRAME_MODULUS: Final = 1 << 32


def split_frame(frame_index: int, image: NDArray[np.uint8], chunk_bytes: int = 1024) -> list[RawFrameChunk]:
    """Cut a grey image (height, width) uint8 into chunks of at most `chunk_bytes` bytes.

    Raises
    ------
    ValueError
        `image` is not a 2-D uint8 array of at most 65535 x 65535, or `chunk_bytes` is out of 1..MAX_CHUNK_BYTES.
    """
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 2 or image.size == 0:
        raise ValueError(f"image must be a non-empty 2-D uint8 array, got {getattr(image, 'shape', image)!r}")
    if not 1 <= chunk_bytes <= MAX_CHUNK_BYTES:
        raise ValueError(f"chunk_bytes must be in [1, {MAX_CHUNK_BYTES}], got {chunk_bytes}")
    height, width = image.shape
    data = np.ascontiguousarray(image).tobytes()
    count = -(-len(data) // chunk_bytes)
    if count > 0xFFFF:
        raise ValueError(f"{count} chunks of {chunk_bytes} bytes exceed 65535: raise chunk_bytes")
    return [
        RawFrameChunk(frame_index, width, height, PixelFormat.GRAY8, i, count, i * chunk_bytes,
                      data[i * chunk_bytes : (i + 1) * chunk_bytes])
        for i in range(count)
    ]  # fmt: skip


class FrameAssembler:
    """Join the chunks of one frame at a time, as they come off UDP: reordered, duplicated, partly lost.

    A chunk of a newer frame starts it (an incomplete frame in progress is abandoned and counted). Chunks of a frame
    already finished (completed or abandoned) and chunks of an older frame while a newer one is being assembled are
    late: ignored and counted in `late`, so they never abandon the newer frame. A duplicated chunk is ignored.
    Only after more late chunks in a row than the frame in progress has chunks (its sender restarted and counts
    frames from 0 again) does the assembler give up on the frame in progress and follow the sender.

    Parameters
    ----------
    max_frame_bytes
        Largest frame accepted (default 16 MiB, 4096 x 4096 grey); a chunk claiming more raises `ProtocolError`
        before anything is allocated.
    """

    def __init__(self, max_frame_bytes: int = MAX_FRAME_BYTES) -> None:
        if not 1 <= max_frame_bytes <= 0xFFFF * 0xFFFF:
            raise ValueError(f"max_frame_bytes must be in [1, {0xFFFF * 0xFFFF}], got {max_frame_bytes!r}")
        self.max_frame_bytes = max_frame_bytes
        self._key: tuple[int, int, int, int] | None = None
        self._buffer = bytearray()
        self._covered = bytearray()
        self._have: dict[int, tuple[int, bytes]] = {}
        self._finished: deque[int] = deque(maxlen=_FINISHED_MEMORY)
        self._late_run = 0
        self.abandoned = 0
        """Frames given up incomplete because a newer one started."""
        self.late = 0
        """Chunks ignored because their frame was finished or older than the one in progress."""
        self.duplicates = 0
        """Chunks received twice (ignored)."""

    @property
    def missing(self) -> int:
        """Chunks still missing of the frame being assembled (0 when none is)."""
        return 0 if self._key is None else self._key[3] - len(self._have)

    def reset(self) -> None:
        """Forget the frame in progress and the finished ones (call it when the sender restarted)."""
        if self._key is not None:
            self.abandoned += 1
        self._key = None
        self._have = {}
        self._finished.clear()
        self._late_run = 0

    def _is_late(self, frame_index: int) -> bool:
        if frame_index in self._finished:
            return True
        if self._key is None:
            return False
        behind = (self._key[0] - frame_index) % _FRAME_MODULUS
        if not 0 < behind < _FRAME_MODULUS // 2:
            return False
        self._late_run += 1
        return self._late_run <= self._key[3]

    def add(self, chunk: RawFrameChunk) -> NDArray[np.uint8] | None:
        """Add a chunk; return the whole image (height, width) once its last chunk arrived, else None.

        Raises
        ------
        ProtocolError
            The chunk claims a frame larger than `max_frame_bytes`, disagrees with the other chunks of its frame
            (size or count), reuses a chunk index with other bytes, or overlaps another chunk's bytes. The chunk is
            ignored; the frame in progress is kept. Also when the last chunk arrived but the chunks leave bytes
            uncovered (the frame is dropped).
        """
        if chunk.frame_bytes > self.max_frame_bytes:
            raise ProtocolError(
                f"raw frame {chunk.frame_index}: {chunk.width} x {chunk.height} = {chunk.frame_bytes} bytes is more "
                f"than the {self.max_frame_bytes} bytes accepted"
            )
        key = (chunk.frame_index, chunk.width, chunk.height, chunk.chunk_count)
        if self._key is None or chunk.frame_index != self._key[0]:
            if self._is_late(chunk.frame_index):
                self.late += 1
                return None
            self._start(key)
        elif key != self._key:
            raise ProtocolError(
                f"raw frame {chunk.frame_index}: chunk {chunk.chunk_index} says {chunk.width} x {chunk.height} in "
                f"{chunk.chunk_count} chunks, earlier chunks said {self._key[1]} x {self._key[2]} in {self._key[3]}"
            )
        self._late_run = 0
        end = chunk.offset + len(chunk.data)
        seen = self._have.get(chunk.chunk_index)
        if seen is not None:
            if seen == (chunk.offset, chunk.data):
                self.duplicates += 1
                return None
            raise ProtocolError(
                f"raw frame {chunk.frame_index}: chunk {chunk.chunk_index} received twice with other offset or bytes"
            )
        if self._covered.find(1, chunk.offset, end) >= 0:
            raise ProtocolError(
                f"raw frame {chunk.frame_index}: chunk {chunk.chunk_index} (bytes {chunk.offset}..{end - 1}) overlaps "
                "bytes of another chunk"
            )
        self._buffer[chunk.offset : end] = chunk.data
        self._covered[chunk.offset : end] = b"\x01" * len(chunk.data)
        self._have[chunk.chunk_index] = (chunk.offset, chunk.data)
        if len(self._have) < chunk.chunk_count:
            return None
        self._finish()
        covered = self._covered.count(1)
        if covered != chunk.frame_bytes:
            raise ProtocolError(
                f"raw frame {chunk.frame_index}: all {chunk.chunk_count} chunks arrived but cover only "
                f"{covered} of {chunk.frame_bytes} bytes"
            )
        return np.frombuffer(bytes(self._buffer), dtype=np.uint8).reshape(chunk.height, chunk.width)

    def _start(self, key: tuple[int, int, int, int]) -> None:
        if self._key is not None:
            self.abandoned += 1
            self._finished.append(self._key[0])
        self._key = key
        frame_bytes = key[1] * key[2]
        self._buffer = bytearray(frame_bytes)
        self._covered = bytearray(frame_bytes)
        self._have = {}
        self._late_run = 0

    def _finish(self) -> None:
        if self._key is not None:
            self._finished.append(self._key[0])
        self._key = None
        self._have = {}
