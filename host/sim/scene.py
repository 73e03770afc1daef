"""The static scene behind and in front of the rope, and the sensor that turns light into 8-bit frames.

Built once per frame set from a seeded generator: the background (level, smooth non-uniformity, optional texture
and bright scratch), the vignetting, the optional clamp over the fixed end, and the rope's brightness along its arc
length. `Sensor.expose` composes one frame::

    light = vignette * ((background * (1 - C) + A) * (1 - clamp) + clamp_level * clamp)
    frame = clip(round(light + noise), 0, 255),  noise ~ N(0, read_noise^2 + gain * light)

with C and A the rope's time-averaged coverage and coverage x brightness (`ropecam.host.sim.render`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

from ropecam.host.sim.config import SceneSpec, SensorSpec
from ropecam.host.sim.processing import encode_gamma, jpeg_round_trip, unsharp_mask
from ropecam.host.sim.rig_parts import add_plate_details, clamp_with_rod
from ropecam.host.sim.rope_photo import load_plate_texture

__all__ = ["SceneLayers", "Sensor", "build_scene", "rope_levels"]

CLAMP_LEVEL_DN = 120.0
"""Brightness of the clamp block (a grey metal part, visible against either background)."""
SCRATCH_CONTRAST_DN = 90.0
"""How much brighter than the background the scratch is."""


@dataclass(frozen=True)
class SceneLayers:
    """Static images of one frame set, each (H, W) float32.

    Attributes
    ----------
    background
        Background brightness (DN) before vignetting, with non-uniformity, texture and scratch.
    vignette
        Multiplicative illumination fall-off in (0, 1].
    clamp
        Clamp coverage in [0, 1] (zeros without a clamp).
    clamp_box_px
        (u_min, v_min, u_max, v_max) of the clamp in pixels, or None.
    scratch_px
        (u0, v0, u1, v1) end points of the scratch in pixels, or None.
    clamp_level
        (H, W) brightness of the clamp and its rod where they cover (DN), or None for the plain block
        (`CLAMP_LEVEL_DN`).
    parts
        Where the rig's parts are, for the metadata (``rod_px``, ``plate_edge_px``, ``distractor_px``).
    """

    background: NDArray[np.float32]
    vignette: NDArray[np.float32]
    clamp: NDArray[np.float32]
    clamp_box_px: tuple[float, float, float, float] | None
    scratch_px: tuple[float, float, float, float] | None
    clamp_level: NDArray[np.float32] | None = None
    parts: dict[str, object] = field(default_factory=dict)


def _scene_rng(seed: int) -> np.random.Generator:
    return np.random.default_rng([seed, 0])


def build_scene(
    scene: SceneSpec,
    image_size: tuple[int, int],
    fixed_end_px: tuple[float, float],
    rope_length_px: float,
    rope_width_px: float,
    edge_sigma_px: float,
    seed: int,
) -> SceneLayers:
    """Build the static layers of a frame set.

    Parameters
    ----------
    scene
        Levels and options.
    image_size
        (width, height) in pixels.
    fixed_end_px
        (u, v) of the rope's fixed end (the clamp is centred there; the scratch is placed in the swing region).
    rope_length_px
        Approximate length of the rope in the image, pixels (sizes the scratch and its distance from the fixed end).
    rope_width_px
        Apparent rope width, pixels (sizes the clamp).
    edge_sigma_px
        Edge blur of the optics, pixels (the clamp and the scratch are blurred like the rope).
    seed
        Seed; the same seed gives the same layers.
    """
    width, height = image_size
    rng = _scene_rng(seed)
    u = np.arange(width, dtype=np.float64)[None, :]
    v = np.arange(height, dtype=np.float64)[:, None]
    xn = (u - (width - 1) / 2) / ((width - 1) / 2)
    yn = (v - (height - 1) / 2) / ((height - 1) / 2)

    # Smooth non-uniformity: a gradient in a random direction plus a broad bump, together within [-1, 1].
    angle = rng.uniform(0, 2 * math.pi)
    gradient = (math.cos(angle) * xn + math.sin(angle) * yn) / math.sqrt(2)
    bx, by = rng.uniform(-0.6, 0.6, size=2)
    bump = np.exp(-((xn - bx) ** 2 + (yn - by) ** 2) / (2 * 0.5**2))
    field = 0.5 * gradient + (bump - 0.5)
    background = scene.background_level * (1.0 + scene.background_variation * field)

    texture_noise = rng.standard_normal((height, width)).astype(np.float32)
    if scene.texture > 0:
        grain = cv2.GaussianBlur(texture_noise, (0, 0), sigmaX=1.0)
        grain /= max(float(grain.std()), 1e-12)
        background = background * (1.0 + scene.texture * grain)

    plate = scene.plate_photo_path
    surface = None
    if plate is not None:
        surface = scene.plate_photo_contrast * load_plate_texture(plate, (width, height))
        background = background * (1.0 + surface)

    scratch_params = rng.uniform(size=5)
    scratch_px = None
    if scene.scratch:
        # A thin straight scratch in the region the rope sweeps (below the fixed end), so the rope crosses it.
        direction = math.radians(20 + 140 * scratch_params[0])
        distance = rope_length_px * (0.35 + 0.45 * scratch_params[1])
        centre_u = fixed_end_px[0] + distance * math.cos(direction)
        centre_v = fixed_end_px[1] + distance * math.sin(direction)
        orientation = math.pi * scratch_params[2]
        half_length = rope_length_px * (0.08 + 0.08 * scratch_params[3])
        du, dv = half_length * math.cos(orientation), half_length * math.sin(orientation)
        scratch_px = (centre_u - du, centre_v - dv, centre_u + du, centre_v + dv)
        mask = _segment_cover(u, v, scratch_px, half_width_px=0.4, sigma_px=edge_sigma_px)
        background = background + SCRATCH_CONTRAST_DN * mask

    background, parts = add_plate_details(
        np.broadcast_to(background, (height, width)), u, v, rope_level=scene.rope_level,
        background_level=scene.background_level, rope_width_px=rope_width_px, sigma_px=edge_sigma_px,
        plate_edge=scene.plate_edge, scratches=scene.scratches, dust=scene.dust, distractor=scene.distractor,
        seed=seed,
    ) if _has_plate_details(scene) else (background, {})  # fmt: skip

    corner2 = ((width - 1) / 2) ** 2 + ((height - 1) / 2) ** 2
    radius2 = ((u - (width - 1) / 2) ** 2 + (v - (height - 1) / 2) ** 2) / corner2
    vignette = 1.0 - scene.vignetting * radius2

    clamp = np.zeros((height, width))
    clamp_box = None
    clamp_level = None
    if scene.clamp and (scene.clamp_width_px > 0 or scene.rod_width_px > 0):
        width_px = scene.clamp_width_px or max(12.0, 8.0 * rope_width_px)
        metal = clamp_with_rod(u, v, fixed_end_px, width_px, scene.rod_width_px, CLAMP_LEVEL_DN, edge_sigma_px)
        clamp, clamp_box = metal.cover, metal.box_px
        background = background * metal.shadow
        if surface is not None:  # the metal's own grain: the surface texture, shifted and fainter
            metal_level = metal.level * (1.0 + 0.5 * np.roll(surface, (97, 211), axis=(0, 1)))
        else:
            metal_level = metal.level
        clamp_level = np.ascontiguousarray(metal_level, dtype=np.float32)
        if metal.rod_px is not None:
            parts["rod_px"] = list(metal.rod_px)
    elif scene.clamp:
        half_u = max(6.0, 4.0 * rope_width_px)
        half_v = 0.6 * half_u
        fu, fv = fixed_end_px
        clamp_box = (fu - half_u, fv - half_v, fu + half_u, fv + half_v)
        inside_u = np.minimum(u - clamp_box[0], clamp_box[2] - u)
        inside_v = np.minimum(v - clamp_box[1], clamp_box[3] - v)
        clamp = ndtr(inside_u / edge_sigma_px) * ndtr(inside_v / edge_sigma_px)

    return SceneLayers(
        background=np.ascontiguousarray(np.broadcast_to(background, (height, width)), dtype=np.float32),
        vignette=np.ascontiguousarray(np.broadcast_to(vignette, (height, width)), dtype=np.float32),
        clamp=np.ascontiguousarray(clamp, dtype=np.float32),
        clamp_box_px=clamp_box,
        scratch_px=scratch_px,
        clamp_level=clamp_level,
        parts=parts,
    )


def _has_plate_details(scene: SceneSpec) -> bool:
    return bool(scene.plate_edge or scene.scratches or scene.dust or scene.distractor)


def _segment_cover(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    segment: tuple[float, float, float, float],
    half_width_px: float,
    sigma_px: float,
) -> NDArray[np.float64]:
    """Blurred coverage of a thin straight band between two points (round ends)."""
    u0, v0, u1, v1 = segment
    du, dv = u1 - u0, v1 - v0
    t = np.clip(((u - u0) * du + (v - v0) * dv) / (du * du + dv * dv), 0.0, 1.0)
    dist = np.hypot(u - u0 - t * du, v - v0 - t * dv)
    return ndtr((half_width_px - dist) / sigma_px) - ndtr((-half_width_px - dist) / sigma_px)


def rope_levels(scene: SceneSpec, s_m: NDArray[np.float64], seed: int) -> NDArray[np.float64]:
    """Return the rope's brightness (DN) at arc lengths `s_m`: uniform, or uneven along the material.

    The unevenness is a sum of three sinusoids in arc length (wavelengths 3-20 cm, random phases), scaled so its
    extreme is ``scene.rope_unevenness`` of the level.
    """
    rng = np.random.default_rng([seed, 2])
    wavelengths_m = rng.uniform(0.03, 0.2, size=3)
    phases = rng.uniform(0, 2 * math.pi, size=3)
    wave = sum(np.sin(2 * math.pi * s_m / w + p) for w, p in zip(wavelengths_m, phases, strict=True)) / 3.0
    return scene.rope_level * (1.0 + scene.rope_unevenness * np.asarray(wave, dtype=np.float64))


class Sensor:
    """Compose frames from the scene and a rendered exposure, with noise drawn from a per-frame seeded generator.

    Parameters
    ----------
    layers
        The static scene.
    sensor
        Noise parameters.
    seed
        Seed; frame k's noise comes from ``default_rng([seed, 1, k])`` so any frame can be regenerated alone.
    """

    def __init__(self, layers: SceneLayers, sensor: SensorSpec, seed: int) -> None:
        self.layers = layers
        self.spec = sensor
        self.seed = int(seed)
        self._light = np.empty_like(layers.background)

    def light(
        self, cover: NDArray[np.float32], signal: NDArray[np.float32], illumination: NDArray[np.float32] | None = None
    ) -> NDArray[np.float32]:
        """Return the noise-free light (DN, float32) for a rendered exposure; a view into this sensor's buffer.

        `illumination`, (H, 1) or (H, W), multiplies the whole scene (the lamps' flicker, `shutter.flicker_gain`).
        """
        layers = self.layers
        light = self._light
        np.subtract(1.0, cover, out=light)
        light *= layers.background
        light += signal
        if layers.clamp_box_px is not None:
            light *= 1.0 - layers.clamp
            if layers.clamp_level is None:
                light += CLAMP_LEVEL_DN * layers.clamp
            else:
                light += layers.clamp_level * layers.clamp
        if illumination is not None:
            light *= illumination
        light *= layers.vignette
        return light

    def expose(
        self,
        cover: NDArray[np.float32],
        signal: NDArray[np.float32],
        frame: int,
        illumination: NDArray[np.float32] | None = None,
    ) -> NDArray[np.uint8]:
        """Return the 8-bit frame number `frame` for a rendered exposure.

        Noise on the linear light, then the camera's processing (`ropecam.host.sim.processing`): gamma curve,
        sharpening, rounding and clipping to 8 bits, JPEG round trip.
        """
        light = self.light(cover, signal, illumination)
        if self.spec.read_noise_dn > 0 or self.spec.gain_dn_per_electron > 0:
            rng = np.random.default_rng([self.seed, 1, frame])
            variance = np.maximum(light, 0.0) * np.float32(self.spec.gain_dn_per_electron)
            variance += np.float32(self.spec.read_noise_dn**2)
            noise = rng.standard_normal(light.shape, dtype=np.float32)
            noise *= np.sqrt(variance)
            light = light + noise
        spec = self.spec
        if spec.gamma != 1.0 or spec.sharpen > 0:
            light = encode_gamma(light, spec.gamma)
            if spec.sharpen > 0:
                light = unsharp_mask(light, spec.sharpen, spec.sharpen_sigma_px)
        image = np.clip(np.rint(light), 0, 255).astype(np.uint8)
        if spec.jpeg_quality:
            image = jpeg_round_trip(image, spec.jpeg_quality)
        return image
