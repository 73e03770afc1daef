"""The camera's processing after the sensor: gamma curve, unsharp-mask sharpening and the JPEG/MJPEG round trip.

Applied by `ropecam.host.sim.scene.Sensor` in a camera's order: noise on the linear light, then `encode_gamma`,
`unsharp_mask`, rounding and clipping to 8 bits, then `jpeg_round_trip`. Motion blur, the lens PSF, vignetting and
flicker all act on linear light, before any of these.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["encode_gamma", "jpeg_round_trip", "unsharp_mask"]

FULL_SCALE_DN = 255.0
"""Linear light of this many DN encodes to code 255 whatever the gamma."""


def encode_gamma(light: NDArray[np.float32], gamma: float) -> NDArray[np.float32]:
    """Return ``255 (max(light, 0) / 255)^(1 / gamma)`` (float32, same shape), the camera's output curve.

    Parameters
    ----------
    light
        (H, W) linear light in DN (noise included).
    gamma
        Exponent (>= 1); 1 returns `light` clipped at 0.
    """
    scaled = np.maximum(light, 0.0, dtype=np.float32) / np.float32(FULL_SCALE_DN)
    if gamma != 1.0:
        np.power(scaled, np.float32(1.0 / gamma), out=scaled)
    scaled *= np.float32(FULL_SCALE_DN)
    return scaled


def unsharp_mask(code: NDArray[np.float32], amount: float, sigma_px: float) -> NDArray[np.float32]:
    """Return ``code + amount * (code - GaussianBlur(code, sigma_px))`` (float32), the camera's sharpening.

    Parameters
    ----------
    code
        (H, W) float32 image (DN).
    amount
        Unsharp-mask gain (>= 0).
    sigma_px
        Gaussian standard deviation, pixels (> 0); the border is reflected.
    """
    blurred = cv2.GaussianBlur(code, (0, 0), sigmaX=sigma_px, borderType=cv2.BORDER_REFLECT)
    out = code - blurred
    out *= np.float32(amount)
    out += code
    return out


def jpeg_round_trip(frame: NDArray[np.uint8], quality: int) -> NDArray[np.uint8]:
    """Return `frame` (H, W) uint8 encoded as baseline JPEG at `quality` (1-100) by OpenCV and decoded again.

    Each MJPEG frame is such a JPEG image, so this is also an MJPEG camera's round trip.

    Raises
    ------
    ValueError
        `quality` is outside 1-100 or OpenCV fails to encode.
    """
    if not 1 <= quality <= 100:
        raise ValueError(f"quality must be in [1, 100], got {quality!r}")
    ok, data = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f"OpenCV could not JPEG-encode a {frame.shape} {frame.dtype} frame")
    return cv2.imdecode(data, cv2.IMREAD_GRAYSCALE)
