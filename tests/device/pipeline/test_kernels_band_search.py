"""`search_band_line` (the band tracker's search without a track) against a slow reference: the line bent joint by
joint in numpy, scored with scipy's `map_coordinates`."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter, map_coordinates

from ropecam.device.pipeline._kernels import sample_or_zero, search_band_line

JOINTS, SKIP, TURN_DEG = 8, 0.12, 45.0


def _chained(shape: np.ndarray, angles: np.ndarray) -> np.ndarray:
    out = shape.copy()
    for k, angle in enumerate(angles):
        joint = k * len(shape) // len(angles)
        c, s = math.cos(angle), math.sin(angle)
        d = out[joint:] - out[joint]
        out[joint:] = out[joint] + np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=1)
    return out


def _score(evidence: np.ndarray, line: np.ndarray) -> float:
    return float(map_coordinates(evidence, [line[:, 1], line[:, 0]], order=1, mode="constant", cval=0.0).mean())


def _reference_search(evidence: np.ndarray, shape: np.ndarray) -> tuple[np.ndarray, float]:
    """Every candidate line built whole and scored (the tool's search before it became a kernel)."""
    count = len(shape)
    skip = int(SKIP * count)
    angles = np.zeros(JOINTS)
    for joint in range(JOINTS):
        lo, hi = max(joint * count // JOINTS, skip), min((joint + 2) * count // JOINTS, count)
        reach = 2.0 * TURN_DEG if joint == 0 else TURN_DEG
        best, chosen = -math.inf, angles
        for offset in np.radians(np.arange(-reach, reach + 1e-9, 0.5)):
            trial = angles.copy()
            trial[joint] += offset
            score = _score(evidence, _chained(shape, trial)[lo:hi])
            if score > best:
                best, chosen = score, trial
        angles = chosen
    best = _score(evidence, _chained(shape, angles)[skip:])
    for joint in range(JOINTS):
        base = angles[joint]
        for offset in np.radians(np.arange(-2.0, 2.01, 0.25)):
            trial = angles.copy()
            trial[joint] = base + offset
            score = _score(evidence, _chained(shape, trial)[skip:])
            if score > best:
                best, angles = score, trial
    return _chained(shape, angles), best


def _straight(points: int = 61, length: float = 150.0) -> np.ndarray:
    s = np.linspace(0.0, length, points)
    return np.stack([20.0 + s, 30.0 + 0.0 * s], axis=1)


def test_sample_or_zero_is_scipys_constant_bilinear() -> None:
    image = np.random.default_rng(1).normal(size=(7, 9))
    rows = np.array([0.0, 3.25, 6.0, 6.0001, -1e-9, 2.5, 5.9, 0.3])
    cols = np.array([0.0, 4.5, 8.0, 2.0, 3.0, 8.2, 7.99, -0.5])
    expected = map_coordinates(image, [rows, cols], order=1, mode="constant", cval=0.0)
    got = [sample_or_zero(image, r, c) for r, c in zip(rows, cols, strict=True)]
    assert got == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(("turn_deg", "bend_deg"), [(7.0, -5.0), (30.0, -12.0), (0.0, 0.0)])
def test_search_band_line_matches_the_reference(turn_deg: float, bend_deg: float) -> None:
    shape = _straight()
    truth = _chained(shape, np.radians([turn_deg, 0.0, 0.0, bend_deg, 0.0, 0.0, 0.0, 0.0]))
    rows, cols = np.mgrid[0:200, 0:200].astype(np.float64)
    distance = np.min(np.hypot(cols[..., None] - truth[:, 0], rows[..., None] - truth[:, 1]), axis=-1)
    noise = np.random.default_rng(4).normal(0.0, 0.3, distance.shape)
    evidence = gaussian_filter(np.where(distance < 2.0, 1.0, 0.0) + noise, 2.0)
    expected, expected_score = _reference_search(evidence, shape)
    found = np.empty_like(shape)
    score = search_band_line(evidence, shape, JOINTS, SKIP, TURN_DEG, 0.5, 2.0, 0.25, found)
    assert score == pytest.approx(expected_score, abs=1e-9)
    np.testing.assert_allclose(found, expected, atol=1e-9)
    assert np.hypot(*(found - truth).T).max() < 1.5  # and it found the band


def test_search_band_line_refuses_what_it_cannot_bend() -> None:
    evidence = np.zeros((20, 20))
    line = _straight(points=10, length=10.0)
    out = np.empty_like(line)
    assert math.isnan(search_band_line(evidence, line[:1], JOINTS, SKIP, TURN_DEG, 0.5, 2.0, 0.25, out))
    assert math.isnan(search_band_line(evidence, line, 10, SKIP, TURN_DEG, 0.5, 2.0, 0.25, out))
    assert math.isnan(search_band_line(evidence, line, JOINTS, SKIP, TURN_DEG, 0.5, 2.0, 0.25, out[:5]))
