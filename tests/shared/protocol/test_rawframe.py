"""A whole frame cut into RawFrameChunk messages, shuffled, sent and reassembled."""

from __future__ import annotations

import random

import numpy as np
import pytest

from ropecam.shared.protocol import FrameAssembler, decode_message, encode_message, split_frame


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
