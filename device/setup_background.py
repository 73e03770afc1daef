"""Setup's decision on a textured background: learn it, and divide it out when its texture is most of the noise.

`ropecam.device.pipeline.background` describes the flat field. Setup learns the background from its frames
(the rope swinging), and measures the median gradient magnitude of a few frames in linear light with and without
the texture divided out; when the texture is at least `TEXTURE_RATIO` times what is left (shot and read noise),
every candidate runs with it and the table names it (``background_png``, written beside OUT as OUT_background.png).
A plain background (a black plate in read noise, a lit wall) gains nothing and is left alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline.background import BackgroundFlattening, learn_background, linear_table
from ropecam.device.pipeline.edges import EdgeDetector

__all__ = ["TEXTURE_RATIO", "background_path", "choose_background", "median_gradient"]

TEXTURE_RATIO = 1.5
"""Median gradient of the linearised frames over that of the flattened ones above which the background is used."""
_PROBES = 5
"""Frames (evenly spread) whose gradients are compared."""


def median_gradient(images: Sequence[NDArray[np.uint8]], smooth_sigma_px: float) -> float:
    """The median over `images` (linear light) of each one's median gradient magnitude on a 4-px grid, as the
    pipeline's edge stage computes it (`EdgeThresholds` measures the noise so)."""
    height, width = images[0].shape
    detector = EdgeDetector(height, width, smooth_sigma_px, 1e9, 1e9)  # no edge passes: the gradient only
    lo, hi = np.zeros(height, np.int32), np.full(height, width - 1, np.int32)
    medians = []
    for image in images:
        detector.detect(np.ascontiguousarray(image), lo, hi)
        medians.append(float(np.median(detector.mag[::4, ::4])))
    return float(np.median(medians))


def background_path(out: Path) -> Path:
    """Where setup writes the background of `out` (a device.toml): OUT_background.png beside it."""
    return out.resolve().with_name(out.stem + "_background.png")


def choose_background(
    images: Sequence[NDArray[np.uint8]], gamma: float, smooth_sigma_px: float
) -> tuple[NDArray[np.float32] | None, str]:
    """Learn the background of `images` (camera codes) and decide whether to divide it out.

    Returns
    -------
    background, why
        The background in linear light (None: not used) and one line saying what was measured.
    """
    if len(images) < 5:
        return None, f"background: not learned ({len(images)} frames, 5 needed)"
    background = learn_background(images, gamma)
    flat = BackgroundFlattening(background, gamma)
    table = linear_table(gamma)
    picks = np.unique(np.linspace(0, len(images) - 1, min(_PROBES, len(images))).round().astype(int))
    raw = median_gradient([table[images[p]] for p in picks], smooth_sigma_px)
    flattened = median_gradient([flat.apply(images[p]).copy() for p in picks], smooth_sigma_px)
    ratio = raw / max(flattened, 1e-6)
    measured = f"median gradient {raw:.1f} as the camera gives it, {flattened:.1f} with the background divided out"
    if ratio < TEXTURE_RATIO:
        return None, f"background: plain ({measured}): not divided out"
    return background, f"background: textured ({measured}): divided out of each frame"
