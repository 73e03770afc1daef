"""Read and write the static background of ``[pipeline] background_png`` (`ropecam.device.pipeline.background`):
a 16-bit grey PNG of linear light x 256."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import ConfigError, DataError

__all__ = ["read_background_png", "write_background_png"]


def write_background_png(path: str | Path, background: NDArray[np.floating]) -> None:
    """Write `background` (linear light, 0-255) as a 16-bit grey PNG of linear light x 256; raises `DataError`
    when it cannot be written."""
    data = np.clip(np.round(np.asarray(background, np.float64) * 256.0), 0, 65535).astype(np.uint16)
    try:
        ok = cv2.imwrite(str(path), data)
    except cv2.error as exc:
        raise DataError(f"cannot write the background image {path}: {exc}") from exc
    if not ok:
        raise DataError(f"cannot write the background image {path}")


def read_background_png(path: str | Path, shape: tuple[int, int], key: str = "background_png") -> NDArray[np.float32]:
    """Read a background written by `write_background_png`: linear light (float32, 0-255) of `shape`.

    Raises
    ------
    ConfigError
        The file is missing, not a 16-bit grey image, or not of the frames' size (the message names `key`).
    """
    file = Path(path)
    if not file.is_file():
        raise ConfigError(f"{key}: background image {file} does not exist")
    image = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
    if image is None or image.ndim != 2 or image.dtype != np.uint16:
        what = "unreadable" if image is None else f"{image.dtype} with shape {image.shape}"
        raise ConfigError(
            f"{key}: {file} is {what}; expected a 16-bit grey PNG of linear light x 256 (ropecam-device setup)"
        )
    if image.shape != shape:
        raise ConfigError(
            f"{key}: background {file} is {image.shape[1]}x{image.shape[0]} px, the frames are {shape[1]}x{shape[0]} px"
        )
    return image.astype(np.float32) / 256.0
