"""The rasteriser kernels against a slow, obvious reference: the band drawn on a fine grid, blurred numerically."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from ropecam.host.sim import _kernels

pytestmark = pytest.mark.kernel

SIGMA_PX = 0.5


FLAT = np.ones((1, 1), dtype=np.float32)
"""A plain rope's texture (not read by the kernel)."""


def _arc(points: int = 60) -> np.ndarray:
    """A quarter circle of radius 25 px: a curved centreline with distinct ends."""
    angle = np.linspace(0.2, 1.8, points)
    return np.ascontiguousarray(np.stack([10 + 25 * np.cos(angle), 8 + 25 * np.sin(angle)], axis=-1))


def _kernel_cover(points: np.ndarray, radius: float, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, int]:
    dist = np.full(shape, _kernels.FAR, dtype=np.float32)
    scratch = [np.zeros(shape, dtype=np.float32) for _ in range(3)]
    box = np.array([shape[1], shape[0], -1, -1], dtype=np.int32)
    cover = np.zeros(shape, dtype=np.float32)
    signal = np.zeros(shape, dtype=np.float32)
    level = np.linspace(100.0, 200.0, len(points))
    radii = np.full(len(points), radius)
    stamped = _kernels.stamp_centreline(points, radii, level, SIGMA_PX, FLAT, 0.0, 0, 10**6, dist, *scratch, box)
    assert stamped == len(points) - 1
    count = _kernels.accumulate_cover(dist, *scratch, box, SIGMA_PX, np.ones(shape[0]), cover, signal)
    assert count > 0
    assert np.all(dist == _kernels.FAR) and all(np.all(s == 0) for s in scratch), "scratch buffers not cleared"
    assert list(box) == [shape[1], shape[0], -1, -1]
    return cover, signal, count


def _reference_cover(points: np.ndarray, radius: float, shape: tuple[int, int], fine: int = 16) -> np.ndarray:
    """Indicator of the flat-ended band on a grid `fine` times finer, Gaussian-blurred, sampled at pixel centres."""
    height, width = shape
    margin = 8
    u = (np.arange((width + 2 * margin) * fine) + 0.5) / fine - 0.5 - margin
    v = (np.arange((height + 2 * margin) * fine) + 0.5) / fine - 0.5 - margin
    uu, vv = np.meshgrid(u, v)
    inside = np.zeros(uu.shape, dtype=bool)
    start_dir = (points[1] - points[0]) / np.linalg.norm(points[1] - points[0])
    end_dir = (points[-1] - points[-2]) / np.linalg.norm(points[-1] - points[-2])
    beyond_start = (uu - points[0, 0]) * start_dir[0] + (vv - points[0, 1]) * start_dir[1] < 0
    beyond_end = (uu - points[-1, 0]) * end_dir[0] + (vv - points[-1, 1]) * end_dir[1] > 0
    for a, b in itertools.pairwise(points):
        # Only the fine cells within reach of this segment (keeps the reference fast).
        c0, c1 = (np.array([min(a[0], b[0]), max(a[0], b[0])]) + margin + 0.5 + [-radius - 1, radius + 1]) * fine
        r0, r1 = (np.array([min(a[1], b[1]), max(a[1], b[1])]) + margin + 0.5 + [-radius - 1, radius + 1]) * fine
        window = (slice(max(int(r0), 0), int(r1) + 1), slice(max(int(c0), 0), int(c1) + 1))
        wu, wv = uu[window], vv[window]
        d = b - a
        t = np.clip(((wu - a[0]) * d[0] + (wv - a[1]) * d[1]) / (d @ d), 0, 1)
        inside[window] |= np.hypot(wu - a[0] - t * d[0], wv - a[1] - t * d[1]) <= radius
    # The ends are flat: cut at the planes through the end points, but keep the end segments' straight sides.
    inside &= ~beyond_start & ~beyond_end
    blurred = gaussian_filter(inside.astype(np.float64), SIGMA_PX * fine, mode="constant")
    centres = margin * fine + fine // 2 + fine * np.arange(height), margin * fine + fine // 2 + fine * np.arange(width)
    # Sample between the two fine cells around each pixel centre (fine is even).
    rows = centres[0][:, None]
    cols = centres[1][None, :]
    return 0.25 * (
        blurred[rows, cols] + blurred[rows - 1, cols] + blurred[rows, cols - 1] + blurred[rows - 1, cols - 1]
    )


def test_coverage_matches_numerical_convolution() -> None:
    points = _arc()
    cover, signal, _ = _kernel_cover(points, 1.4, (40, 40))
    reference = _reference_cover(points, 1.4, (40, 40))
    assert np.abs(cover - reference).max() < 0.02
    assert np.abs(cover - reference).mean() < 1e-3
    # Brightness is carried per pixel from the nearest centreline point: between the end levels where covered.
    covered = cover > 0.05
    assert np.all(signal[covered] / cover[covered] >= 100 - 1e-3)
    assert np.all(signal[covered] / cover[covered] <= 200 + 1e-3)


def test_straight_band_profile_is_closed_form() -> None:
    """Across a horizontal band far from its ends, coverage is Phi((r - d)/s) - Phi((-r - d)/s) exactly."""
    from scipy.special import ndtr

    points = np.ascontiguousarray(np.stack([np.linspace(2.0, 37.0, 71), np.full(71, 15.3)], axis=-1))
    cover, _, _ = _kernel_cover(points, 1.1, (30, 40))
    d = np.arange(30) - 15.3
    expected = ndtr((1.1 - d) / SIGMA_PX) - ndtr((-1.1 - d) / SIGMA_PX)
    np.testing.assert_allclose(cover[:, 20], expected, atol=1e-6)
    # The flat tip: half coverage at the end point along the axis.
    tip_row = cover[15, :].astype(np.float64)
    assert abs(np.interp(37.0, np.arange(40), tip_row) - 0.5 * tip_row[20]) < 0.02


def test_accumulation_weights_add_up() -> None:
    points = _arc()
    shape = (40, 40)
    dist = np.full(shape, _kernels.FAR, dtype=np.float32)
    scratch = [np.zeros(shape, dtype=np.float32) for _ in range(3)]
    box = np.array([40, 40, -1, -1], dtype=np.int32)
    cover = np.zeros(shape, dtype=np.float32)
    signal = np.zeros(shape, dtype=np.float32)
    radius = np.full(len(points), 1.2)
    level = np.full(len(points), 50.0)
    for weight in (0.25, 0.5, 0.25):
        _kernels.stamp_centreline(points, radius, level, SIGMA_PX, FLAT, 0.0, 0, 10**6, dist, *scratch, box)
        _kernels.accumulate_cover(dist, *scratch, box, SIGMA_PX, np.full(shape[0], weight), cover, signal)
    single, _, _ = _kernel_cover(points, 1.2, shape)
    np.testing.assert_allclose(cover, single, atol=1e-6)
    np.testing.assert_allclose(signal, 50.0 * single, rtol=1e-5, atol=1e-5)


def test_invalid_arguments_return_status() -> None:
    shape = (10, 10)
    dist = np.full(shape, _kernels.FAR, dtype=np.float32)
    scratch = [np.zeros(shape, dtype=np.float32) for _ in range(3)]
    box = np.array([10, 10, -1, -1], dtype=np.int32)
    one = np.zeros((1, 2))
    assert (
        _kernels.stamp_centreline(one, np.ones(1), np.ones(1), 0.5, FLAT, 0.0, 0, 10**6, dist, *scratch, box)
        == _kernels.INVALID
    )
    two = np.array([[1.0, 1.0], [5.0, 5.0]])
    assert (
        _kernels.stamp_centreline(two, np.ones(3), np.ones(2), 0.5, FLAT, 0.0, 0, 10**6, dist, *scratch, box)
        == _kernels.INVALID
    )
    assert (
        _kernels.stamp_centreline(two, np.ones(2), np.ones(2), 0.0, FLAT, 0.0, 0, 10**6, dist, *scratch, box)
        == _kernels.INVALID
    )
    small = np.zeros((5, 5), dtype=np.float32)
    assert _kernels.accumulate_cover(dist, *scratch, box, 0.5, np.ones(10), small, small) == _kernels.INVALID


def test_rope_outside_the_image_touches_nothing() -> None:
    points = np.array([[-50.0, -50.0], [-40.0, -45.0]])
    shape = (20, 20)
    dist = np.full(shape, _kernels.FAR, dtype=np.float32)
    scratch = [np.zeros(shape, dtype=np.float32) for _ in range(3)]
    box = np.array([20, 20, -1, -1], dtype=np.int32)
    assert _kernels.stamp_centreline(points, np.ones(2), np.ones(2), 0.5, FLAT, 0.0, 0, 10**6, dist, *scratch, box) == 1
    cover = np.zeros(shape, dtype=np.float32)
    count = _kernels.accumulate_cover(dist, *scratch, box, 0.5, np.ones(20), cover, cover.copy())
    assert count == 0 and not cover.any()


ALLOCATION_SCRIPT = """
import numpy as np
from numba.core.runtime import rtsys
from ropecam.host.sim import _kernels
shape = (30, 40)
points = np.ascontiguousarray(np.stack([np.linspace(3, 30, 20), np.linspace(4, 20, 20)], axis=-1))
dist = np.full(shape, _kernels.FAR, dtype=np.float32)
scratch = [np.zeros(shape, dtype=np.float32) for _ in range(3)]
box = np.array([40, 30, -1, -1], dtype=np.int32)
cover, signal = np.zeros(shape, dtype=np.float32), np.zeros(shape, dtype=np.float32)
radius, level = np.ones(20), np.ones(20)
flat = np.ones((1, 1), dtype=np.float32)
row_weight = np.ones(shape[0])
def calls():
    _kernels.stamp_centreline(points, radius, level, 0.5, flat, 0.0, 0, 10**6, dist, *scratch, box)
    _kernels.accumulate_cover(dist, *scratch, box, 0.5, row_weight, cover, signal)
calls()
before = rtsys.get_allocation_stats()
for _ in range(10):
    calls()
after = rtsys.get_allocation_stats()
print(after.alloc - before.alloc, after.free - before.free)
"""


def test_kernels_do_not_allocate() -> None:
    """Under NUMBA_NRT_STATS=1, a call allocates only the wrappers of its array arguments (9 + 8 per pair)."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_NRT_STATS": "1"}
    env.pop("NUMBA_DISABLE_JIT", None)  # allocation counts are a property of the compiled code
    result = subprocess.run([sys.executable, "-c", ALLOCATION_SCRIPT], env=env, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    allocs, frees = (int(v) for v in result.stdout.split())
    assert allocs == frees
    assert allocs == 10 * (9 + 8)


def test_row_range_limits_what_is_stamped() -> None:
    points = _arc()
    shape = (40, 40)
    full, _, _ = _kernel_cover(points, 1.2, shape)
    dist = np.full(shape, _kernels.FAR, dtype=np.float32)
    scratch = [np.zeros(shape, dtype=np.float32) for _ in range(3)]
    box = np.array([40, 40, -1, -1], dtype=np.int32)
    cover = np.zeros(shape, dtype=np.float32)
    _kernels.stamp_centreline(points, np.full(len(points), 1.2), np.ones(len(points)), SIGMA_PX, FLAT, 0.0, 12, 20,
                              dist, *scratch, box)  # fmt: skip
    assert box[1] >= 12 and box[3] <= 20
    _kernels.accumulate_cover(dist, *scratch, box, SIGMA_PX, np.ones(40), cover, cover.copy())
    np.testing.assert_array_equal(cover[12:21], full[12:21])
    assert not cover[:12].any() and not cover[21:].any()
