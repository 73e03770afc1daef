"""A whole frame cut into RawFrameChunk messages, shuffled, sent and reassembled."""

from __future__ import annotations

import random

import numpy as np
import pytest

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol import (
    FrameAssembler,
    PixelFormat,
    RawFrameChunk,
    decode_message,
    encode_message,
    split_frame,
)


def test_frame_survives_chunking_in_any_order() -> None:
    image = np.random.default_rng(0).integers(0, 256, (54, 102), dtype=np.uint8)
    chunks = split_frame(17, image, chunk_bytes=500)
    assert len(chunks) == 12
    random.Random(1).shuffle(chunks)
    assembler = FrameAssembler()
    results = []
    for sequence, chunk in enumerate(chunks):
        data = encode_message(chunk, device_id=1, sequence=sequence, t_ns=0)
        results.append(assembler.add(decode_message(data).record))  # type: ignore[arg-type]
    assert all(r is None for r in results[:-1])
    np.testing.assert_array_equal(results[-1], image)


def test_a_newer_frame_abandons_an_incomplete_one() -> None:
    assembler = FrameAssembler()
    first = split_frame(1, np.zeros((10, 10), np.uint8), 30)
    second = split_frame(2, np.ones((10, 10), np.uint8), 30)
    assert assembler.add(first[0]) is None and assembler.missing == len(first) - 1
    for chunk in second[:-1]:
        assert assembler.add(chunk) is None
    assert np.all(assembler.add(second[-1]) == 1)
    assert assembler.abandoned == 1


def test_bad_images_are_refused() -> None:
    with pytest.raises(ValueError, match="uint8"):
        split_frame(1, np.zeros((4, 4), np.float32))
    with pytest.raises(ValueError, match="chunk_bytes"):
        split_frame(1, np.zeros((4, 4), np.uint8), 0)


def _frame(index: int, value: int, chunk_bytes: int = 30) -> list[RawFrameChunk]:
    return split_frame(index, np.full((10, 10), value, np.uint8), chunk_bytes)


def test_a_late_chunk_of_an_older_frame_does_not_abandon_the_newer_one() -> None:
    assembler = FrameAssembler()
    first, second = _frame(1, 0), _frame(2, 1)
    for chunk in second[:-1]:
        assert assembler.add(chunk) is None
    assert assembler.add(first[1]) is None  # reordered or duplicated on the network
    image = assembler.add(second[-1])
    assert image is not None and np.all(image == 1)
    assert (assembler.abandoned, assembler.late) == (0, 1)


def test_chunks_of_a_finished_frame_are_ignored() -> None:
    assembler = FrameAssembler()
    first, second = _frame(1, 0), _frame(2, 1)
    for chunk in first[:-1]:
        assembler.add(chunk)
    assert assembler.add(first[-1]) is not None
    assert assembler.add(first[0]) is None  # a duplicate after completion starts no phantom frame
    assert assembler.missing == 0
    assert assembler.add(second[0]) is None  # the phantom would have been "abandoned" here
    assembler.add(first[2])  # late chunk of frame 1 while frame 2 is assembled
    for chunk in second[1:-1]:
        assembler.add(chunk)
    assert np.all(assembler.add(second[-1]) == 1)
    assert (assembler.abandoned, assembler.late) == (0, 2)


def test_duplicated_chunks_are_ignored_and_the_frame_completes_once() -> None:
    image = np.arange(100, dtype=np.uint8).reshape(10, 10)
    chunks = split_frame(7, image, 30)
    assembler = FrameAssembler()
    assert assembler.add(chunks[0]) is None
    assert assembler.add(chunks[0]) is None
    for chunk in chunks[1:-1]:
        assert assembler.add(chunk) is None
    np.testing.assert_array_equal(assembler.add(chunks[-1]), image)
    assert assembler.duplicates == 1


def test_chunks_reusing_an_offset_raise_instead_of_leaving_a_hole() -> None:
    data = bytes([7]) * 50
    assembler = FrameAssembler()
    assert assembler.add(RawFrameChunk(5, 10, 10, PixelFormat.GRAY8, 0, 2, 0, data)) is None
    with pytest.raises(ProtocolError, match="overlaps"):
        assembler.add(RawFrameChunk(5, 10, 10, PixelFormat.GRAY8, 1, 2, 0, data))  # should be at offset 50
    # the frame in progress is kept: the right chunk still completes it
    image = assembler.add(RawFrameChunk(5, 10, 10, PixelFormat.GRAY8, 1, 2, 50, bytes([9]) * 50))
    assert image is not None and image.sum() == 50 * 7 + 50 * 9


def test_a_chunk_index_with_other_bytes_and_short_frames_raise() -> None:
    assembler = FrameAssembler()
    assembler.add(RawFrameChunk(5, 10, 10, PixelFormat.GRAY8, 0, 2, 0, bytes(50)))
    with pytest.raises(ProtocolError, match="twice"):
        assembler.add(RawFrameChunk(5, 10, 10, PixelFormat.GRAY8, 0, 2, 50, bytes(50)))
    with pytest.raises(ProtocolError, match="cover only 90 of 100"):
        assembler.add(RawFrameChunk(5, 10, 10, PixelFormat.GRAY8, 1, 2, 60, bytes(40)))
    with pytest.raises(ProtocolError, match="earlier chunks said 10 x 10"):
        assembler.add(RawFrameChunk(6, 10, 10, PixelFormat.GRAY8, 0, 2, 0, bytes(50)))
        assembler.add(RawFrameChunk(6, 20, 5, PixelFormat.GRAY8, 1, 2, 50, bytes(50)))


def test_a_huge_claim_is_refused_before_allocating() -> None:
    assembler = FrameAssembler()
    with pytest.raises(ProtocolError, match="4294836225 bytes"):
        assembler.add(RawFrameChunk(1, 65535, 65535, PixelFormat.GRAY8, 0, 65535, 0, bytes(1000)))
    assert len(assembler._buffer) == 0
    small = FrameAssembler(max_frame_bytes=99)
    with pytest.raises(ProtocolError, match="more than the 99 bytes"):
        small.add(_frame(1, 0)[0])


def test_a_restarted_sender_is_followed_after_a_frame_of_late_chunks() -> None:
    assembler = FrameAssembler()
    assembler.add(_frame(5000, 0)[0])  # frame 5000 never completes: the device restarted
    restarted = _frame(3, 2)  # 4 chunks of an "older" frame
    results = [assembler.add(chunk) for chunk in restarted + restarted]
    assert assembler.abandoned == 1
    assert any(r is not None and np.all(r == 2) for r in results)
    assembler.reset()
    assert np.all([assembler.add(c) for c in _frame(5000, 4)][-1] == 4)  # reset forgets the finished frames


def test_shuffled_duplicated_chunks_of_interleaved_frames() -> None:
    rng = random.Random(3)
    images = {k: np.random.default_rng(k).integers(0, 256, (20, 30), dtype=np.uint8) for k in (10, 11)}
    chunks = {k: split_frame(k, images[k], 64) for k in images}
    first = chunks[10] + rng.sample(chunks[10], 3)
    rng.shuffle(first)
    second = chunks[11] + rng.sample(chunks[10], 4) + rng.sample(chunks[11], 3)
    rng.shuffle(second)
    assembler = FrameAssembler()
    done = [image for image in (assembler.add(c) for c in first + second) if image is not None]
    assert len(done) == 2
    np.testing.assert_array_equal(done[0], images[10])
    np.testing.assert_array_equal(done[1], images[11])
    assert assembler.abandoned == 0
