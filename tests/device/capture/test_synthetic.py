"""The synthetic rope's anti-aliased coverage against the plain computation over the whole bounding box."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope


def _distance_everywhere(rope: SyntheticRope, line_uv: np.ndarray) -> np.ndarray:
    """The distance of every pixel of the image to the polyline (every segment over the whole image)."""
    vv, uu = np.mgrid[0 : rope.height, 0 : rope.width].astype(np.float64)
    dist = np.full(uu.shape, np.inf)
    for a, b in itertools.pairwise(line_uv):
        d = b - a
        t = np.clip(((uu - a[0]) * d[0] + (vv - a[1]) * d[1]) / max(float(d @ d), 1e-12), 0.0, 1.0)
        np.minimum(dist, np.hypot(uu - a[0] - t * d[0], vv - a[1] - t * d[1]), out=dist)
    return dist


@pytest.mark.parametrize("seed", range(4))
def test_coverage_equals_the_distance_to_every_segment(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rope = replace(SyntheticRope(width=64, height=48, diameter_px=float(rng.uniform(1.5, 7.0))), rope_end="round")
    # A curled polyline, partly outside the image, with a zero-length segment.
    angles = np.cumsum(rng.uniform(-0.8, 0.8, 24))
    steps = np.stack([np.cos(angles), np.sin(angles)], axis=1) * rng.uniform(1.0, 6.0, (24, 1))
    line = np.cumsum(np.vstack([[rng.uniform(-5, 40), rng.uniform(-5, 30)], steps]), axis=0)
    line[5] = line[4]
    want = np.clip(0.5 * rope.diameter_px + 0.5 - _distance_everywhere(rope, line), 0.0, 1.0)
    np.testing.assert_array_equal(rope.coverage(line), want)  # the same numbers, not only close ones
