"""Offline frame sources: odd image files become grey frames or a per-frame message naming the file."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture import sources
from ropecam.device.capture.sources import open_source


def _write_gray_alpha_png(path: Path, grey: np.ndarray, alpha: np.ndarray) -> None:
    """Write an 8-bit grey + alpha PNG (colour type 4) without OpenCV, which cannot write 2 channels."""
    height, width = grey.shape
    pixels = np.stack([grey, alpha], axis=2).astype(np.uint8)
    raw = b"".join(b"\x00" + pixels[r].tobytes() for r in range(height))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", width, height, 8, 4, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    )


def test_gray_alpha_png_is_read_as_its_grey_channel(tmp_path: Path) -> None:
    grey = (np.arange(12 * 16).reshape(12, 16) % 251).astype(np.uint8)
    _write_gray_alpha_png(tmp_path / "000.png", grey, np.full_like(grey, 128))
    frames = list(open_source(tmp_path))
    assert len(frames) == 1 and frames[0].message == ""
    np.testing.assert_array_equal(frames[0].image, grey)


@pytest.mark.parametrize("channels", [1, 2])
def test_one_and_two_channel_arrays_become_grey(channels: int) -> None:
    image = np.zeros((6, 7, channels), np.uint8)
    image[..., 0] = 77
    if channels == 2:
        image[..., 1] = 255  # alpha
    grey, message = sources._gray(image)
    assert message == ""
    assert grey is not None and grey.shape == (6, 7) and grey.flags.c_contiguous
    assert np.all(grey == 77)


def test_other_channel_counts_get_a_message_naming_the_file(tmp_path: Path, monkeypatch) -> None:
    (tmp_path / "a.png").write_bytes(b"not read: imread is replaced below")
    monkeypatch.setattr(sources.cv2, "imread", lambda *args: np.zeros((5, 6, 5), np.uint8))
    frames = list(open_source(tmp_path))
    assert frames[0].image is None
    assert str(tmp_path / "a.png") in frames[0].message
    assert "5 channels" in frames[0].message and "expected 1 (grey)" in frames[0].message
