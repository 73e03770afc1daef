"""What a lab's rig adds to the plate: a clamp with its rod, the plate's edge, scratches, dust and a second cable.

All are static and drawn once per frame set from their own seeded generators (the draws of `build_scene`'s older
options are untouched, so scenes without these parts are the same as before). Edges are blurred like the rope's
(the optics' edge sigma). Scratches and dust are of the rope's polarity (bright on a dark plate, dark on a light
one: light catching a scratch, grime on a white sheet), at a few per cent of the rope's contrast.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

from ropecam.host.sim import _kernels

__all__ = ["ClampParts", "add_plate_details", "clamp_with_rod"]

SHADOW_OFFSET_PX = (4, 6)
"""Where the clamp's shadow falls on the plate relative to the clamp (right, down), pixels."""
SHADOW_BLUR_PX = 2.5
"""Softness of that shadow (Gaussian sigma), pixels."""
SHADOW_DEPTH = 0.6
"""Fraction of the plate's light the shadow takes away."""
WALL_TILT_RAD = math.radians(2.0)
"""The plate's edge leans by this much from the image's vertical (a plate is never quite aligned)."""


@dataclass(frozen=True)
class ClampParts:
    """The clamp block and its rod: coverage, brightness where covered, outlines in pixels, and the factor their
    shadow multiplies the plate's brightness by."""

    cover: NDArray[np.float64]
    level: NDArray[np.float64]
    box_px: tuple[float, float, float, float]
    rod_px: tuple[float, float, float, float] | None
    shadow: NDArray[np.float64]


def clamp_with_rod(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    fixed_end_px: tuple[float, float],
    width_px: float,
    rod_width_px: float,
    level_dn: float,
    sigma_px: float,
) -> ClampParts:
    """Draw a shaded clamp block centred on the fixed end and a round rod from its top to the image's top border.

    Parameters
    ----------
    u, v
        (1, W) and (H, 1) pixel coordinates.
    fixed_end_px
        Centre of the clamp (the rope's fixed end), pixels.
    width_px
        Width of the block (its height is 0.6 of it), pixels.
    rod_width_px
        Diameter of the rod (0: none), pixels.
    level_dn
        Mean brightness of the metal, DN.
    sigma_px
        Edge blur, pixels.
    """
    fu, fv = fixed_end_px
    half_u, half_v = 0.5 * width_px, 0.3 * width_px
    box = (fu - half_u, fv - half_v, fu + half_u, fv + half_v)
    block = ndtr(np.minimum(u - box[0], box[2] - u) / sigma_px) * ndtr(np.minimum(v - box[1], box[3] - v) / sigma_px)
    # Anodised metal lit from the upper left: a bright chamfer along the top and left edges, the face darkening
    # downwards, two dark bolt heads beside the rope's entry, each with a small specular glint.
    face = 0.75 - 0.25 * np.clip((v - box[1]) / (2 * half_v), 0, 1) + 0 * u
    chamfer = np.maximum(
        np.exp(-0.5 * ((v - box[1] - 1.0) / 1.0) ** 2), 0.6 * np.exp(-0.5 * ((u - box[0] - 1.0) / 1.0) ** 2)
    )
    level = level_dn * (face + 0.9 * chamfer)
    head = 0.35 * half_v + 1.0
    for side in (-1.0, 1.0):
        bu = fu + side * 0.55 * half_u
        bolt = ndtr((head - np.hypot(u - bu, v - fv)) / sigma_px)
        glint = np.exp(-0.5 * np.hypot(u - bu + 0.35 * head, v - fv + 0.35 * head) ** 2 / 0.8**2)
        level = level * (1.0 - 0.35 * bolt) + level_dn * 0.5 * glint * bolt
    cover = block
    rod = None
    if rod_width_px > 0:
        radius = 0.5 * rod_width_px
        across = (u - fu) / radius
        rod_end = box[1] + 2.0  # the rod goes into the block's top
        rod_cover = ndtr((radius - np.abs(u - fu)) / sigma_px) * ndtr((rod_end - v) / sigma_px)
        # A cylinder lit from the left: a highlight left of its axis, darker towards its sides.
        rod_level = level_dn * (0.35 + 0.8 * np.exp(-(((across + 0.3) / 0.35) ** 2))) + 0 * v
        level = np.where(rod_cover > block, rod_level, level)
        cover = np.maximum(block, rod_cover)
        rod = (fu - radius, 0.0, fu + radius, rod_end)
    # Their soft shadow on the plate, down and to the right (the plate is a few centimetres behind them).
    shadow = 1.0 - SHADOW_DEPTH * cv2.GaussianBlur(
        _shifted(np.ascontiguousarray(cover, dtype=np.float32), SHADOW_OFFSET_PX), (0, 0), SHADOW_BLUR_PX
    )
    return ClampParts(cover=cover, level=level, box_px=box, rod_px=rod, shadow=shadow.astype(np.float64))


def _shifted(image: NDArray[np.float32], offset: tuple[int, int]) -> NDArray[np.float32]:
    """`image` moved by (du, dv) >= 0 pixels, zeros shifted in."""
    du, dv = offset
    out = np.zeros_like(image)
    out[dv:, du:] = image[: image.shape[0] - dv, : image.shape[1] - du]
    return out


def _local(u: NDArray[np.float64], v: NDArray[np.float64], centre: tuple[float, float], reach: float) -> tuple:
    """Slices of the window of half-size `reach` around `centre`, clipped to the image, and its coordinates."""
    width, height = u.shape[1], v.shape[0]
    c0, c1 = max(0, int(centre[0] - reach)), min(width, int(centre[0] + reach) + 2)
    r0, r1 = max(0, int(centre[1] - reach)), min(height, int(centre[1] + reach) + 2)
    return (slice(r0, r1), slice(c0, c1)), u[:, c0:c1], v[r0:r1, :]


def _static_cable(points_px: NDArray[np.float64], radius_px: float, sigma_px: float, shape: tuple[int, int]):
    """Coverage (H, W) of a static rope along `points_px`, drawn by the rope renderer's kernels."""
    dist = np.full(shape, _kernels.FAR, dtype=np.float32)
    scratch = [np.zeros(shape, dtype=np.float32) for _ in range(3)]
    box = np.array([shape[1], shape[0], -1, -1], dtype=np.int32)
    cover = np.zeros(shape, dtype=np.float32)
    signal = np.zeros(shape, dtype=np.float32)
    flat = np.ones((1, 1), dtype=np.float32)
    n = len(points_px)
    _kernels.stamp_centreline(np.ascontiguousarray(points_px), np.full(n, radius_px), np.ones(n), sigma_px, flat,
                              0.0, 0, shape[0] - 1, dist, *scratch, box)  # fmt: skip
    _kernels.accumulate_cover(dist, *scratch, box, sigma_px, np.ones(shape[0]), cover, signal)
    return cover.astype(np.float64)


def add_plate_details(
    background: NDArray[np.float64],
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    *,
    rope_level: float,
    background_level: float,
    rope_width_px: float,
    sigma_px: float,
    plate_edge: float,
    scratches: int,
    dust: int,
    distractor: bool,
    seed: int,
) -> tuple[NDArray[np.float64], dict[str, object]]:
    """Return the background with the plate's edge, scratches, dust and a distractor cable, and where they are.

    Parameters
    ----------
    background
        (H, W) plate brightness, DN.
    u, v
        (1, W) and (H, 1) pixel coordinates.
    rope_level, background_level
        Mean rope and plate brightness, DN (they set the parts' polarity and contrast).
    rope_width_px, sigma_px
        Rope width (the distractor's) and edge blur, pixels.
    plate_edge, scratches, dust, distractor
        The `SceneSpec` options.
    seed
        Seed; each part has its own generator.

    Returns
    -------
    background, where
        The new background and a JSON-able description for the metadata (``plate_edge_px``: the edge's u at the
        top and the bottom row; ``distractor_px``: its centreline, every 8th point).
    """
    height, width = background.shape
    contrast = rope_level - background_level
    where: dict[str, object] = {}
    out = np.array(background, dtype=np.float64, copy=True)
    if plate_edge > 0:
        rng = np.random.default_rng([seed, 3])
        top = plate_edge * (width - 1)
        slope = math.tan(WALL_TILT_RAD) * (1 if rng.uniform() < 0.5 else -1)
        edge_u = top + slope * v
        beyond = ndtr((u - edge_u) / sigma_px)
        wall = (background_level + 0.12 * contrast) * (1.0 + 0.3 * (v / (height - 1) - 0.5))
        out = out * (1.0 - beyond) + wall * beyond
        # The plate's cut edge catches the light: a thin bright line along it.
        bevel = np.exp(-0.5 * ((u - edge_u + 1.0) / max(sigma_px, 0.7)) ** 2)
        out += 0.35 * abs(contrast) * bevel
        where["plate_edge_px"] = [float(top), float(top + slope * (height - 1))]
    if scratches:
        rng = np.random.default_rng([seed, 4])
        for _ in range(scratches):
            centre = (rng.uniform(0, width), rng.uniform(0, height))
            half = rng.uniform(8, 50)
            angle = rng.uniform(0, math.pi)
            amplitude = rng.uniform(0.03, 0.1) * contrast
            half_width = rng.uniform(0.2, 0.4)
            window, uu, vv = _local(u, v, centre, half + 4)
            du, dv = half * math.cos(angle), half * math.sin(angle)
            t = np.clip(((uu - centre[0] + du) * 2 * du + (vv - centre[1] + dv) * 2 * dv) / (4 * half * half), 0, 1)
            dist = np.hypot(uu - centre[0] + du - t * 2 * du, vv - centre[1] + dv - t * 2 * dv)
            out[window] += amplitude * (ndtr((half_width - dist) / sigma_px) - ndtr((-half_width - dist) / sigma_px))
    if dust:
        rng = np.random.default_rng([seed, 5])
        for _ in range(dust):
            centre = (rng.uniform(0, width), rng.uniform(0, height))
            # Mostly faint specks; a few larger, out-of-focus ones (blurred by their distance from the plate).
            radius = rng.uniform(0.4, 1.2) if rng.uniform() < 0.85 else rng.uniform(1.5, 3.0)
            amplitude = rng.uniform(0.02, 0.12) * contrast * (0.4 if radius > 1.4 else 1.0)
            window, uu, vv = _local(u, v, centre, radius + 4)
            out[window] += amplitude * ndtr((radius - np.hypot(uu - centre[0], vv - centre[1])) / sigma_px)
    if distractor:
        rng = np.random.default_rng([seed, 6])
        # A cable hanging from the top border to the bottom one, beside the swing, sagging sideways a little.
        u0 = width * rng.uniform(0.06, 0.16)
        u1 = u0 + width * rng.uniform(-0.04, 0.08)
        sag = width * rng.uniform(0.01, 0.04)
        t = np.linspace(0.0, 1.0, 2 * (height + 20))
        points = np.stack([u0 + (u1 - u0) * t + sag * np.sin(math.pi * t), -10 + (height + 20) * t], axis=-1)
        cover = _static_cable(points, 0.5 * rope_width_px, sigma_px, (height, width))
        level = rope_level * (0.85 + 0.1 * np.sin(v / 37.0))
        out = out * (1.0 - cover) + level * cover
        where["distractor_px"] = points[::8].tolist()
    return out, where
