"""The 8-column vector steps of the Canny passes (`canny_simd`) against float32 NumPy references, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from ropecam.device.pipeline import _kernels as K

pytestmark = pytest.mark.kernel

F = np.float32


def _reference(image: np.ndarray, weights: np.ndarray, low: float, high: float):
    """Smoothing, Sobel and non-maximum suppression labels of the whole image in float32, each expression in the
    order the scalar kernels evaluate it (border replicated)."""
    w0, w1, w2 = (F(w) for w in weights[:3])
    f = np.pad(image.astype(F), 2, mode="edge")
    tmp = w0 * (f[:, :-4] + f[:, 4:]) + w1 * (f[:, 1:-3] + f[:, 3:-1])
    tmp = tmp + w2 * f[:, 2:-2]
    t = tmp[:, :]
    smooth = w0 * (t[:-4] + t[4:]) + w1 * (t[1:-3] + t[3:-1]) + w2 * t[2:-2]
    s = np.pad(smooth, 1, mode="edge")
    two = F(2.0)
    gx = (s[:-2, 2:] + two * s[1:-1, 2:] + s[2:, 2:]) - (s[:-2, :-2] + two * s[1:-1, :-2] + s[2:, :-2])
    gy = (s[2:, :-2] + two * s[2:, 1:-1] + s[2:, 2:]) - (s[:-2, :-2] + two * s[:-2, 1:-1] + s[:-2, 2:])
    mag = np.sqrt(gx * gx + gy * gy)
    m = np.pad(mag, 1)
    ax, ay = np.abs(gx), np.abs(gy)
    horizontal = ay < ax * K.TAN_22_5
    vertical = ay > ax * F(K.TAN_22_5 + K.TWO)
    falling = gx * gy < 0
    centre = m[1:-1, 1:-1]
    a = np.where(horizontal, m[1:-1, :-2], np.where(vertical, m[:-2, 1:-1], np.where(falling, m[:-2, 2:], m[:-2, :-2])))
    b = np.where(horizontal, m[1:-1, 2:], np.where(vertical, m[2:, 1:-1], np.where(falling, m[2:, :-2], m[2:, 2:])))
    straight = horizontal | vertical
    keep = (centre > F(low)) & (centre > a) & ((centre > b) | ((centre == b) & straight))
    labels = np.where(keep, np.where(centre > F(high), 2, 1), 0)
    return smooth, gx, gy, mag, labels


def _hysteresis(labels: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Edge pixels: the weak or strong pixels inside the spans 8-connected (inside the spans) to a strong one."""
    components, _ = ndimage.label((labels > 0) & inside, np.ones((3, 3), bool))
    seeded = np.unique(components[(labels == 2) & inside])
    return np.isin(components, seeded[seeded > 0])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_vector_steps_equal_float32_reference(seed) -> None:
    rng = np.random.default_rng(seed)
    height, width = 48, 96
    # A blurred bright bar on noise: edges, weak and strong pixels, every gradient sector.
    yy, xx = np.mgrid[0:height, 0:width]
    bar = 120 * np.exp(-(((xx - 40 - 0.4 * yy) / 5.0) ** 2)) + 40 * np.exp(-(((yy - 20) / 3.0) ** 2))
    image = np.clip(bar + rng.normal(30, 8, (height, width)), 0, 255).astype(np.uint8)
    lo = np.full(height, 1, np.int32)
    hi = np.zeros(height, np.int32)
    rows = np.arange(6, height - 6)
    lo[rows] = rng.integers(12, 30, rows.size)  # off the image border: the 8-column steps run
    hi[rows] = lo[rows] + rng.integers(0, 50, rows.size)
    lo[20], hi[20] = 1, 0  # an empty row inside the band
    weights = np.array([0.054, 0.242, 0.408, 0.242, 0.054], np.float32)
    work = np.zeros((4, height), np.int32)
    planes = [rng.normal(0, 50, (height, width)).astype(np.float32) for _ in range(5)]  # stale content
    edges = np.full((height, width), 7, np.uint8)
    stack = np.zeros(height * width, np.int32)
    count = K.detect_edges(image, weights, lo, hi, F(20), F(50), work, *planes, edges, stack)
    smooth, gx, gy, mag, labels = _reference(image, weights, 20.0, 50.0)
    inside = np.zeros((height, width), bool)
    sob = np.zeros((height, width), bool)
    gau = np.zeros((height, width), bool)
    for r in range(height):
        inside[r, lo[r] : hi[r] + 1] = hi[r] >= lo[r]
        sob[r, work[0, r] : work[1, r] + 1] = work[1, r] >= work[0, r] and 5 <= r <= height - 6
        gau[r, work[2, r] : work[3, r] + 1] = work[3, r] >= work[2, r] and 4 <= r <= height - 5
    np.testing.assert_array_equal(planes[1][gau], smooth[gau])
    for got, want in zip(planes[2:], (gx, gy, mag), strict=True):
        np.testing.assert_array_equal(got[sob], want[sob])
    want_edges = _hysteresis(labels, inside)
    assert want_edges.sum() > 20 and ((labels == 1) & inside & ~want_edges).any()  # weak pixels left out too
    np.testing.assert_array_equal(edges[inside], want_edges[inside].astype(np.uint8))
    assert (edges[sob & ~inside] == 0).all()
    assert count == want_edges.sum()
    np.testing.assert_array_equal(np.sort(stack[:count]), np.flatnonzero(want_edges))
    strong = np.flatnonzero((labels == 2) & inside)  # the hysteresis seeds come first, in raster order
    np.testing.assert_array_equal(stack[: strong.size], strong)
