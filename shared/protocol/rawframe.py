"""Send a whole camera frame as RawFrameChunk messages and put it back together on the host."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.records import MAX_CHUNK_BYTES, PixelFormat, RawFrameChunk

__all__ = ["FrameAssembler", "split_frame"]


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
    """Collect the chunks of one frame at a time; a chunk of a newer frame starts over (the old one is abandoned)."""

    def __init__(self) -> None:
        self._key: tuple[int, int, int, int] | None = None
        self._buffer = bytearray()
        self._have: set[int] = set()
        self.abandoned = 0

    @property
    def missing(self) -> int:
        """Chunks still missing of the frame being assembled (0 when none is)."""
        return 0 if self._key is None else self._key[3] - len(self._have)

    def add(self, chunk: RawFrameChunk) -> NDArray[np.uint8] | None:
        """Add a chunk; return the whole image (height, width) once its last chunk arrived, else None.

        Raises
        ------
        ProtocolError
            A chunk disagrees with the others of its frame (size, count or offset).
        """
        key = (chunk.frame_index, chunk.width, chunk.height, chunk.chunk_count)
        if key != self._key:
            if self._key is not None and self.missing:
                self.abandoned += 1
            self._key = key
            self._buffer = bytearray(chunk.frame_bytes)
            self._have = set()
        self._buffer[chunk.offset : chunk.offset + len(chunk.data)] = chunk.data
        self._have.add(chunk.chunk_index)
        if len(self._have) < chunk.chunk_count:
            return None
        image = np.frombuffer(bytes(self._buffer), dtype=np.uint8).reshape(chunk.height, chunk.width)
        self._key = None
        if image.size != chunk.frame_bytes:
            raise ProtocolError("raw frame size mismatch")
        return image
