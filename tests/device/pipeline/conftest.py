"""Fixtures of the pipeline tests: small synthetic motion-blurred rope frames and kernel buffers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticFrame, SyntheticRope


@pytest.fixture(scope="session")
def rope() -> SyntheticRope:
    """A 320x240 rope, 180 px long, 4 px thick, swinging fast enough for several pixels of tip blur at 8 ms."""
    return SyntheticRope(exposure_us=8000, amplitude_rad=0.7, period_s=0.9)


@pytest.fixture(scope="session")
def blurred_frames(rope: SyntheticRope) -> list[SyntheticFrame]:
    """Eight consecutive blurred frames of `rope`."""
    return list(rope.frames(8, start=2))


@pytest.fixture(scope="session")
def static_frame(rope: SyntheticRope) -> SyntheticFrame:
    """A frame with a (nearly) motionless rope: 50 us exposure at a turning point of the swing."""
    return replace(rope, exposure_us=50, phase_rad=0.0).render(0)


@pytest.fixture(scope="session")
def fast_rope() -> SyntheticRope:
    """A rope blurred over ~10 px at the tip (12 ms exposure)."""
    return SyntheticRope(exposure_us=12000, amplitude_rad=0.7, period_s=0.9, diameter_px=3.0, phase_rad=1.2)


@pytest.fixture(scope="session")
def fast_frames(fast_rope: SyntheticRope) -> list[SyntheticFrame]:
    """Six consecutive frames of `fast_rope`."""
    return list(fast_rope.frames(6))


@pytest.fixture(scope="session")
def swinging_rope() -> SyntheticRope:
    """A rope swinging over a plain plate with little noise (the tip's end stands out from the learned plate)."""
    return SyntheticRope(
        width=240, height=200, fixed_uv=(120.3, 20.6), length_px=120.0, amplitude_rad=0.5, noise_dn=1.0
    )


@pytest.fixture(scope="session")
def dusty_frames(swinging_rope: SyntheticRope) -> list[tuple[SyntheticFrame, np.ndarray]]:
    """32 frames of `swinging_rope`, each with its image on a dusty plate: specks (2x2 px, 40 DN brighter, every
    6 px) that the rope hides. The static mask learns the dust, so every free tip ends within reach of it."""
    rope = swinging_rope
    out = []
    for frame in rope.frames(32):
        image = frame.image.astype(np.float64)
        cover = np.clip((image - rope.background) / (rope.rope_level - rope.background), 0.0, 1.0)
        specks = np.zeros(image.shape, bool)
        for dr in range(2):
            for dc in range(2):
                specks[3 + dr :: 6, 2 + dc :: 6] = True
        image[specks] += 40.0 * (1.0 - cover[specks])
        out.append((frame, np.clip(np.rint(image), 0, 255).astype(np.uint8)))
    return out


def distance_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Each point's distance (px) to the polyline `poly` (both (n, 2), the same axis order), segment by segment."""
    a, d = poly[:-1][None], np.diff(poly, axis=0)[None]
    p = points[:, None]
    t = np.clip(((p - a) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-12), 0.0, 1.0)
    return np.min(np.hypot(*(p - a - t[..., None] * d).transpose(2, 0, 1)), axis=1)


def resample(poly: np.ndarray, count: int) -> np.ndarray:
    """`count` points evenly spaced by arc length along the polyline `poly` (n, 2)."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poly, axis=0).T))])
    target = np.linspace(0.0, s[-1], count)
    return np.stack([np.interp(target, s, poly[:, 0]), np.interp(target, s, poly[:, 1])], axis=1)


def curve_error(true: np.ndarray, ours: np.ndarray) -> float:
    """A shape's centreline error (px): the mean distance from 100 points evenly spaced along the true curve to our
    polyline (both (n, 2), the same axis order), as the matrix measures it."""
    return float(distance_to_polyline(resample(true, 100), ours).mean())


def full_spans(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Return row spans covering the whole image."""
    return np.zeros(height, np.int32), np.full(height, width - 1, np.int32)


@pytest.fixture
def spans_full():
    """The `full_spans` helper as a fixture."""
    return full_spans
