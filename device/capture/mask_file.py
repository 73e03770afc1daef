"""Read a mask image for the pipeline's static mask (``[pipeline] static_mask_png``)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import ConfigError

__all__ = ["read_mask_png"]


def read_mask_png(path: str | Path, shape: tuple[int, int], key: str = "static_mask_png") -> NDArray[np.bool_]:
    """Read a mask image (PNG, any bit depth, grey or colour): True where a pixel is non-zero.

    Parameters
    ----------
    path
        The image file.
    shape
        (height, width) the mask must have: the frames'.
    key
        The config key that named the file (for the error messages).

    Raises
    ------
    ConfigError
        The file is missing, not an image, or not of the frames' size (the message names the key and the file).
    """
    file = Path(path)
    if not file.is_file():
        raise ConfigError(f"{key}: mask file {file} does not exist")
    image = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ConfigError(f"{key}: {file} is not a readable image (expected a PNG mask)")
    if image.ndim == 3:
        image = image.max(axis=2)
    if image.shape != shape:
        raise ConfigError(
            f"{key}: mask {file} is {image.shape[1]}x{image.shape[0]} px, the frames are {shape[1]}x{shape[0]} px"
        )
    return np.asarray(image != 0)
