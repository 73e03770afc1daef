"""The picture `ropecam-device setup` leaves for the user to check by eye, and the PNG files it writes.

PNG is written here with zlib (8-bit grey or RGB, no filtering): the device install reads image files through
OpenCV in `capture/` only, and these two images need nothing more.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import DataError

__all__ = ["COLOURS", "draw_overlay", "write_png"]

COLOURS = {
    "mask": (230, 40, 40),
    "begin": (40, 220, 40),
    "end": (60, 140, 255),
    "segmentation": (255, 0, 255),
    "fixed_end": (255, 220, 0),
}
"""RGB of each element of the overlay (the command prints the legend)."""


def write_png(path: str | Path, image: NDArray[np.uint8]) -> None:
    """Write an (h, w) grey or (h, w, 3) RGB uint8 image as PNG; raises `DataError` when it cannot be written."""
    if image.dtype != np.uint8 or image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] != 3):
        raise ValueError(f"image must be uint8 (h, w) or (h, w, 3), got {image.dtype} {image.shape}")
    height, width = image.shape[:2]
    colour_type = 0 if image.ndim == 2 else 2
    rows = np.ascontiguousarray(image).reshape(height, -1)
    raw = np.concatenate([np.zeros((height, 1), np.uint8), rows], axis=1).tobytes()  # filter 0 on every row

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    try:
        Path(path).write_bytes(data)
    except OSError as exc:
        raise DataError(f"{path}: cannot write the image: {exc.strerror}") from exc


def _paint_line(rgb: NDArray[np.uint8], line: NDArray[np.float32], colour: tuple[int, int, int]) -> None:
    """Paint a (row, col) polyline one pixel wide, sampled at 0.5 px."""
    if len(line) == 0:
        return
    points = [line[:1].astype(np.float64)]
    for a, b in zip(line[:-1].astype(np.float64), line[1:].astype(np.float64), strict=True):
        n = max(1, int(np.ceil(2 * np.hypot(*(b - a)))))
        points.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
    dense = np.round(np.concatenate(points)).astype(int)
    ok = (dense[:, 0] >= 0) & (dense[:, 0] < rgb.shape[0]) & (dense[:, 1] >= 0) & (dense[:, 1] < rgb.shape[1])
    rgb[dense[ok, 0], dense[ok, 1]] = colour


def _paint_ring(rgb: NDArray[np.uint8], row: float, col: float, radius: float, colour: tuple[int, int, int]) -> None:
    angles = np.linspace(0.0, 2 * np.pi, max(16, int(8 * radius)), endpoint=False)
    ring = np.stack([row + radius * np.sin(angles), col + radius * np.cos(angles)], axis=1).astype(np.float32)
    _paint_line(rgb, np.concatenate([ring, ring[:1]]), colour)


def draw_overlay(
    image: NDArray[np.uint8],
    mask: NDArray[np.bool_] | None,
    begin: NDArray[np.float32] | None,
    end: NDArray[np.float32] | None,
    segmentation: NDArray[np.float32] | None,
    fixed_uv: tuple[float, float] | None,
) -> NDArray[np.uint8]:
    """Return an RGB picture of `image` with the static mask (tinted), one blur split (the begin and end centrelines
    and the segmentation points) and the fixed end (two rings) drawn over it; points are (row, col)."""
    grey = image.astype(np.float32)
    rgb = np.repeat((0.8 * grey)[:, :, None], 3, axis=2)
    if mask is not None:
        tint = np.asarray(COLOURS["mask"], np.float32)
        rgb[mask] = 0.35 * rgb[mask] + 0.65 * tint
    out = np.clip(rgb, 0, 255).astype(np.uint8)
    for line, name in ((begin, "begin"), (end, "end")):
        if line is not None:
            _paint_line(out, line, COLOURS[name])
    if segmentation is not None:
        for row, col in segmentation:
            _paint_ring(out, float(row), float(col), 3.0, COLOURS["segmentation"])
    if fixed_uv is not None:
        for radius in (4.0, 8.0):
            _paint_ring(out, fixed_uv[1], fixed_uv[0], radius, COLOURS["fixed_end"])
    return out
