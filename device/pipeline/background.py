"""A static background's texture divided out of each frame before its edges (a flat field).

A rope in front of a textured sheet or table (paper grain, weave, smudges) sees the texture's gradients as noise:
on the simulated `lab-dark` preset (a white sheet, tuning seed, 60 frames, in linear light at the 1 px smoothing)
the median gradient magnitude of a frame is 19.2, of the per-pixel median background 18.0 and of a frame divided
by that background 5.0: three quarters of what the thresholds must stand above is the sheet, which does not move.
The thresholds measured from the noise are then 49 / 79 and the far end of a blurred band (about 9 DN over the
rope's width) falls below them; at lower thresholds the texture floods the edges.

The texture is multiplicative (a reflectance times the light), so it is removed by a gain per pixel: the
background's local level (a Gaussian of `LEVEL_SIGMA_PX` over its plain pixels) over the background itself,
applied in linear light. Slow variation (vignetting, uneven light) is kept; the rope's contrast against its
surroundings is kept. The background is learned from frames of the swinging rope (`learn_background`: per pixel,
the median of the frames, each divided by its mean so that lamp flicker cancels) by ``ropecam-device setup``,
which writes it as a 16-bit PNG of linear light x 256 (`ropecam.device.capture.background_file`) and names it in
``[pipeline] background_png``. Structures darker or brighter than `MAX_GAIN` times their surroundings (a clamp,
a rod, the rope's part near the fixed end that stays in most frames) keep the gain 1: they are neither divided
out nor ringed by a halo.

`BackgroundFlattening` takes the tone curve's place (`Stages.tone`): the gamma table, then the gain, in two flat
passes over the frame (`K.flatten_frame`). Without ``background_png`` the pipeline does not make one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K

__all__ = [
    "COARSE_BLOCK_PX",
    "GAIN_BITS",
    "LEVEL_SIGMA_PX",
    "MAX_GAIN",
    "BackgroundFlattening",
    "coarse_level",
    "flat_gain",
    "learn_background",
]

LEVEL_SIGMA_PX = 8.0
"""Gaussian sigma (px) of the background's local level: above the texture's grain, below the light's variation."""
MAX_GAIN = 1.5
"""Largest gain (and 1 / smallest) of a pixel: a clamp, rod or the still rope in the background is not divided
out."""
COARSE_BLOCK_PX = 64
"""Side (px) of the squares whose medians are the sheet's coarse level (`coarse_level`), less than the light's
variation. A dark structure covering less than half of a square does not move its median (`lab-dark`'s 40x24 px
clamp covers at most 23 % of one, its 12 px rod 19 %); a larger one (a clamp over ~64x64 px) sets its squares' level
to its own and the sheet round it is divided by too little."""
GAIN_BITS = K.GAIN_BITS
"""Fixed-point bits of the gain (4096 = 1; `K.flatten_frame` reads the gain in it)."""
QUANTILE = 0.5
"""Per-pixel quantile of the normalised frames taken as the background: a rope (of either polarity) covering a
pixel in fewer than half of the frames does not change it."""
MAX_SAMPLES = 48
"""Frames `learn_background` reads at most (evenly spread)."""


def linear_table(gamma: float) -> NDArray[np.uint8]:
    """Code -> linear light (0-255, rounded) of a camera with output curve `gamma` (as `ToneCurve.table`)."""
    codes = np.arange(256, dtype=np.float64) / 255.0
    return np.round(255.0 * codes**gamma).astype(np.uint8)


def learn_background(images: Sequence[NDArray[np.uint8]], gamma: float = 1.0) -> NDArray[np.float32]:
    """Return the static background of `images` (camera codes) in linear light (float32, 0-255).

    Each frame (up to `MAX_SAMPLES`, evenly spread) is linearised and divided by its mean (lamp flicker); per
    pixel the `QUANTILE` of them times the mean level is the background. The rope must move over the frames.
    """
    if len(images) < 2:
        raise ValueError(f"learn_background needs at least 2 frames, got {len(images)}")
    table = linear_table(gamma).astype(np.float32)
    picks = np.unique(np.linspace(0, len(images) - 1, min(MAX_SAMPLES, len(images))).round().astype(int))
    height, width = images[0].shape
    stack = np.empty((len(picks), height, width), np.float32)
    for k, position in enumerate(picks):
        stack[k] = table[images[position]]
        stack[k] /= max(float(stack[k].mean()), 1e-3)
    level = float(np.mean([table[images[p]].mean() for p in picks]))
    index = round(QUANTILE * (len(picks) - 1))
    background = np.partition(stack, index, axis=0)[index]
    return (background * level).astype(np.float32)


def flat_gain(background: NDArray[np.floating]) -> NDArray[np.uint16]:
    """Return the fixed-point gain (`GAIN_BITS`) that divides `background`'s texture out: its local level over
    itself, within [1 / `MAX_GAIN`, `MAX_GAIN`].

    The level is a Gaussian (`LEVEL_SIGMA_PX`) of the plain background only: pixels further than `MAX_GAIN` from the
    sheet's coarse level (`coarse_level`: a clamp, rod, the rope's still part) are left out of the average and keep
    the gain 1, so a dark structure neither rings with a halo nor is divided out. The test was once against a
    Gaussian of `LEVEL_SIGMA_PX` of the background itself, which a clamp wider than it (40 px on `lab-dark`) makes
    dark: the clamp's inside passed for plain, its dark level was averaged into the sheet's around it, and a ring
    of darkened sheet 5-15 px wide stood round the clamp, whose gradients passed the edge thresholds measured on
    the flattened frames (13.3 / 21.2) as fragments that join the rope's outline where it leaves the clamp (the
    band's edge broken: `LOST_TRACK`).
    """
    bg = np.asarray(background, np.float32)

    def blur(image: NDArray[np.float32]) -> NDArray[np.float32]:
        return _gaussian(image, LEVEL_SIGMA_PX)

    rough = coarse_level(bg)
    plain = ((bg * MAX_GAIN > rough) & (bg < rough * MAX_GAIN) & (bg > 0.5)).astype(np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        level = blur(bg * plain) / blur(plain)
        gain = np.where(plain > 0, level / bg, 1.0)
    gain = np.clip(np.nan_to_num(gain, nan=1.0), 1.0 / MAX_GAIN, MAX_GAIN)
    return np.round(gain * (1 << GAIN_BITS)).astype(np.uint16)


def coarse_level(background: NDArray[np.float32], block_px: int = COARSE_BLOCK_PX) -> NDArray[np.float32]:
    """The sheet's slow level under `background`: the median of each `block_px` square (a structure covering less
    than half of one does not move it), interpolated bilinearly between the squares' centres."""
    bg = np.asarray(background, np.float32)
    height, width = bg.shape
    rows, cols = -(-height // block_px), -(-width // block_px)
    padded = np.pad(bg, ((0, rows * block_px - height), (0, cols * block_px - width)), mode="symmetric")
    blocks = padded.reshape(rows, block_px, cols, block_px).transpose(0, 2, 1, 3).reshape(rows, cols, -1)
    medians = np.median(blocks, axis=2).astype(np.float64)

    def between(size: int, count: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
        """Each pixel's two nearest squares' indices and the second one's weight (the border held)."""
        position = np.clip((np.arange(size) + 0.5) / block_px - 0.5, 0.0, count - 1.0)
        first = np.floor(position).astype(np.intp)
        return first, np.minimum(first + 1, count - 1), position - first

    r0, r1, fr = between(height, rows)
    c0, c1, fc = between(width, cols)
    across = medians[:, c0] * (1.0 - fc) + medians[:, c1] * fc
    return (across[r0] * (1.0 - fr[:, None]) + across[r1] * fr[:, None]).astype(np.float32)


def _gaussian(image: NDArray[np.float32], sigma_px: float) -> NDArray[np.float32]:
    """`image` blurred by a Gaussian of `sigma_px` (separable, radius 4 sigma, edges mirrored)."""
    radius = max(1, math.ceil(4.0 * sigma_px))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    weights = np.exp(-0.5 * (x / sigma_px) ** 2)
    weights = (weights / weights.sum()).astype(np.float32)
    out = np.asarray(image, np.float32)
    for axis in (0, 1):
        pad = [(0, 0), (0, 0)]
        pad[axis] = (radius, radius)
        padded = np.pad(out, pad, mode="symmetric")
        size = out.shape[axis]
        acc = np.zeros_like(out)
        for k, w in enumerate(weights):
            acc += w * (padded[k : k + size] if axis == 0 else padded[:, k : k + size])
        out = acc
    return out


class BackgroundFlattening:
    """The camera's gamma undone and a static background's texture divided out, in two flat passes per frame.

    Parameters
    ----------
    background
        The background in linear light (`learn_background`, `read_background_png`), of the frames' shape.
    gamma
        The camera's output curve (`PipelineConfig.gamma`; 1: linear).
    """

    __slots__ = ("_linear", "_out", "gain", "table")

    def __init__(self, background: NDArray[np.floating], gamma: float) -> None:
        self.table = linear_table(gamma)
        self.gain = flat_gain(background)
        """Fixed-point gain per pixel (`GAIN_BITS`)."""
        self.gain.flags.writeable = False
        self._out = np.zeros(self.gain.shape, np.uint8)
        self._linear = np.zeros(self.gain.shape, np.uint8)

    @classmethod
    def from_png(cls, path: str, shape: tuple[int, int], gamma: float) -> BackgroundFlattening:
        """Read ``background_png`` (`ropecam.device.capture.background_file.read_background_png`) for frames of
        `shape`."""
        from ropecam.device.capture.background_file import read_background_png

        return cls(read_background_png(path, shape), gamma)

    def take(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8] | None:
        """Return `apply(frame)` when `frame` is a C-contiguous array of the background's shape; None for any other
        frame (nothing done), as `ToneCurve.take` (the pipeline's first step on every frame)."""
        if frame.shape != self._out.shape or not frame.flags.c_contiguous:
            return None
        return self.apply(frame)

    def apply(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """Return `frame` (camera codes) in linear light with the texture divided out: this stage's buffer, valid
        until the next call."""
        if K.flatten_frame(frame, self.table, self.gain, self._linear, self._out) != 0:
            raise ValueError(f"frame of shape {frame.shape} for a background of shape {self._out.shape}")
        return self._out
