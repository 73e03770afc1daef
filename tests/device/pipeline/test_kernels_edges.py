"""Canny kernel and span kernels against OpenCV, SciPy and slow obvious references."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy import ndimage

from ropecam.device.pipeline import _kernels as K

_NO_PROFILE = np.zeros(0)  # `spans_around_chain` without a measured profile
_NO_MOVED = np.zeros((0, 2), np.float32)  # nor the moved points

pytestmark = pytest.mark.kernel


def _buffers(height: int, width: int) -> dict[str, np.ndarray]:
    return {
        "work": np.zeros((4, height), np.int32),
        "tmp": np.zeros((height, width), np.float32),
        "smooth": np.zeros((height, width), np.float32),
        "gx": np.zeros((height, width), np.float32),
        "gy": np.zeros((height, width), np.float32),
        "mag": np.zeros((height, width), np.float32),
        "edges": np.zeros((height, width), np.uint8),
        "stack": np.zeros(height * width, np.int32),
    }


def _canny(image, lo, hi, low, high, weights=(1.0,)):
    b = _buffers(*image.shape)
    w = np.asarray(weights, np.float32)
    count = K.detect_edges(
        image,
        w,
        lo,
        hi,
        low,
        high,
        b["work"],
        b["tmp"],
        b["smooth"],
        b["gx"],
        b["gy"],
        b["mag"],
        b["edges"],
        b["stack"],
    )
    return count, b


def _agreement(ours: np.ndarray, ref: np.ndarray) -> float:
    union = np.count_nonzero(ours | ref)
    return 1.0 if union == 0 else np.count_nonzero(ours & ref) / union


@pytest.mark.parametrize(("low", "high"), [(20, 60), (50, 100), (5, 10)])
def test_canny_matches_opencv_on_rope_frames(blurred_frames, spans_full, low, high, jit_enabled) -> None:
    for frame in blurred_frames[: 3 if jit_enabled else 1]:  # plain Python: ~2.5 s per frame
        image = frame.image
        lo, hi = spans_full(*image.shape)
        count, b = _canny(image, lo, hi, low, high)
        ref = cv2.Canny(image, low, high, L2gradient=True) > 0
        ours = b["edges"] > 0
        assert count == np.count_nonzero(ours)
        assert _agreement(ours, ref) >= 0.99


@pytest.mark.parametrize("seed", [0, 1])
def test_canny_matches_opencv_on_noise(spans_full, seed) -> None:
    image = np.random.default_rng(seed).integers(0, 256, (61, 83)).astype(np.uint8)
    lo, hi = spans_full(*image.shape)
    for low, high in [(100, 300), (300, 800)]:
        _, b = _canny(image, lo, hi, low, high)
        ref = cv2.Canny(image, low, high, L2gradient=True) > 0
        assert _agreement(b["edges"] > 0, ref) >= 0.99


def test_smoothing_matches_scipy(blurred_frames, spans_full) -> None:
    image = blurred_frames[0].image
    x = np.arange(-2, 3)
    weights = np.exp(-0.5 * x**2).astype(np.float32)
    weights /= weights.sum()
    lo, hi = spans_full(*image.shape)
    _, b = _canny(image, lo, hi, 10, 30, weights)
    ref = ndimage.convolve1d(image.astype(np.float64), weights, axis=0, mode="nearest")
    ref = ndimage.convolve1d(ref, weights, axis=1, mode="nearest")
    np.testing.assert_allclose(b["smooth"], ref, atol=1e-3)
    gx = ndimage.correlate(ref, np.array([[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]], float), mode="nearest")
    np.testing.assert_allclose(b["gx"], gx, atol=1e-2)


def test_canny_inside_spans_equals_full_frame(blurred_frames, spans_full) -> None:
    image = blurred_frames[1].image
    height, width = image.shape
    lo_full, hi_full = spans_full(height, width)
    _, full = _canny(image, lo_full, hi_full, 20, 50, (0.25, 0.5, 0.25))
    points = np.ascontiguousarray(np.argwhere(full["edges"] > 0).astype(np.float32))
    lo = np.zeros(height, np.int32)
    hi = np.zeros(height, np.int32)
    K.spans_around_chain(points, len(points), 6, 0.0, _NO_PROFILE, 1.0, 0.0, 0.0, 0.0, height, width, lo, hi, _NO_MOVED)
    _, roi = _canny(image, lo, hi, 20, 50, (0.25, 0.5, 0.25))
    inside = np.zeros((height, width), bool)
    for r in range(height):
        inside[r, lo[r] : hi[r] + 1] = hi[r] >= lo[r]
    np.testing.assert_array_equal(roi["edges"][inside], full["edges"][inside])
    assert inside.mean() < 0.25
    # The edge list left in the stack: every edge pixel of the spans once (flat indices), the strong ones first
    # in raster order.
    count = int(np.count_nonzero(roi["edges"][inside]))
    listed = np.flatnonzero((roi["edges"] > 0) & inside)
    np.testing.assert_array_equal(np.sort(roi["stack"][:count]), listed)
    strong = roi["mag"].ravel()[roi["stack"][:count]] > 50
    assert strong[: np.count_nonzero(strong)].all()
    assert np.all(np.diff(roi["stack"][: np.count_nonzero(strong)]) > 0)


@pytest.mark.parametrize("rotation", [(1.0, 0.0), (0.9, 0.2)])
def test_spans_around_chain_matches_reference(rotation) -> None:
    rng = np.random.default_rng(3)
    height, width = 50, 70
    points = rng.uniform([-3, -3], [height + 3, width + 3], (12, 2)).astype(np.float32)
    lo = np.zeros(height, np.int32)
    hi = np.zeros(height, np.int32)
    rows = K.spans_around_chain(
        points, len(points), 3, 4.0, _NO_PROFILE, *rotation, 10.0, 20.0, height, width, lo, hi, _NO_MOVED
    )
    mask = np.zeros((height, width), bool)
    dist = np.hypot(points[:, 0] - 10.0, points[:, 1] - 20.0)
    rr, cc = np.mgrid[0:height, 0:width]
    for (pr, pc), d in zip(points, dist, strict=True):
        m = 3 + int(np.ceil(4.0 * d / dist.max()))
        z = complex(*rotation) * complex(pr - 10.0, pc - 20.0)
        pr, pc = 10.0 + z.real, 20.0 + z.imag
        half = np.sqrt(np.maximum(0.0, m * m - (rr - pr) ** 2))
        inside_rows = np.abs(rr - pr) <= m
        mask |= inside_rows & (cc >= np.floor(pc - half)) & (cc <= np.ceil(pc + half))
    assert rows == int(mask.any(axis=1).sum())
    for r in range(height):
        cols = np.flatnonzero(mask[r])
        if cols.size:
            assert (lo[r], hi[r]) == (cols.min(), cols.max())
        else:
            assert hi[r] < lo[r]


def test_union_spans_matches_reference() -> None:
    lo = np.array([5, 1, 0, 7, 3, 9], np.int32)
    hi = np.array([6, 0, 2, 8, 2, 12], np.int32)  # rows 1 and 4 empty
    out_lo = np.array([1, 3, 4, 1, 1, 10], np.int32)
    out_hi = np.array([0, 5, 9, 0, 4, 11], np.int32)  # rows 0 and 3 empty
    want = []
    for a, b, c, d in zip(lo, hi, out_lo.copy(), out_hi.copy(), strict=True):
        cols = set(range(a, b + 1)) | set(range(c, d + 1))
        want.append((min(cols), max(cols)) if cols else None)
    rows = K.union_spans(lo, hi, out_lo, out_hi)
    assert rows == sum(w is not None for w in want)
    for r, w in enumerate(want):
        if w is None:
            assert out_hi[r] < out_lo[r]
        else:
            assert (out_lo[r], out_hi[r]) == w


def test_coarse_spans_cover_the_rope_and_drop_noise(blurred_frames) -> None:
    image = blurred_frames[0].image.copy()
    height, width = image.shape
    image[5, 7] = 255  # one hot pixel: a cross of 5 active cells, dropped by min_cells
    block = 4
    sums = np.zeros((height // block, width // block), np.int32)
    labels = np.zeros_like(sums)
    stack = np.zeros(max(sums.size, width), np.int32)
    lo = np.zeros(height, np.int32)
    hi = np.zeros(height, np.int32)
    kept = K.coarse_spans(image, block, int(block * block * 20 / 8), 8, 2, sums, labels, stack, lo, hi)
    assert kept > 0
    # The sums are the block sums.
    ref = image[: sums.shape[0] * block, : sums.shape[1] * block].astype(np.int64)
    ref = ref.reshape(sums.shape[0], block, sums.shape[1], block).sum(axis=(1, 3))
    np.testing.assert_array_equal(sums, ref)
    inside = np.zeros((height, width), bool)
    for r in range(height):
        inside[r, lo[r] : hi[r] + 1] = hi[r] >= lo[r]
    lo_full = np.zeros(height, np.int32)
    hi_full = np.full(height, width - 1, np.int32)
    _, full = _canny(image, lo_full, hi_full, 20, 50, (0.25, 0.5, 0.25))
    rope = full["edges"] > 0
    rope[:20, :20] = False  # the hot pixel's own edges
    assert rope.any() and inside[rope].all()  # every rope edge is inside the coarse spans
    assert not inside[:10, :10].any()  # the hot pixel is not
    assert inside.mean() < 0.3
    blank = np.full((height, width), 30, np.uint8)
    assert K.coarse_spans(blank, block, 40, 3, 2, sums, labels, stack, lo, hi) == 0
    assert (hi < lo).all()


def _union_reference(lo, hi, rows_apart, cols_apart, width):
    """Slow obvious spans: the union of the rows within `rows_apart`, widened and clipped (None = empty)."""
    out = []
    for r in range(len(lo)):
        cols = [c for rr in range(max(0, r - rows_apart), min(len(lo), r + rows_apart + 1)) for c in (lo[rr], hi[rr])
                if hi[rr] >= lo[rr]]  # fmt: skip
        out.append(None if not cols else (max(0, min(cols) - cols_apart), min(width - 1, max(cols) + cols_apart)))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_grow_spans_out_of_place_and_in_place_match_reference(seed) -> None:
    rng = np.random.default_rng(seed)
    height, width = 30, 40
    lo = rng.integers(-1, 38, height).astype(np.int32)
    hi = (lo + rng.integers(-6, 12, height)).astype(np.int32)
    lo[:3], hi[:3] = 1, 0  # empty rows at the top and a gap
    lo[12:15], hi[12:15] = 5, 2
    rows = np.flatnonzero(hi >= lo)
    first, last = int(rows[0]), int(rows[-1])
    out_lo = np.full(height, -7, np.int32)
    out_hi = np.full(height, -7, np.int32)
    K.grow_spans(lo, hi, first, last, 1, width, out_lo, out_hi)
    for r, want in enumerate(_union_reference(lo, hi, 1, 1, width)):
        if max(first - 1, 0) <= r <= min(last + 1, height - 1):
            assert (out_lo[r], out_hi[r]) == (want if want else (1, 0)), r
    K.grow_spans(out_lo, out_hi, max(first - 1, 0), min(last + 1, height - 1), 3, width, out_lo, out_hi)
    for r, want in enumerate(_union_reference(lo, hi, 2, 4, width)):
        if max(first - 2, 0) <= r <= min(last + 2, height - 1):
            assert (out_lo[r], out_hi[r]) == (want if want else (1, 0)), r


def test_edges_are_zero_around_the_spans(blurred_frames) -> None:
    # keep_largest_closed relies on it: 0 on the Sobel spans outside the spans, whatever the map held before.
    image = blurred_frames[3].image
    height, width = image.shape
    lo_full, hi_full = np.zeros(height, np.int32), np.full(height, width - 1, np.int32)
    _, full = _canny(image, lo_full, hi_full, 20, 50, (0.25, 0.5, 0.25))
    points = np.ascontiguousarray(np.argwhere(full["edges"] > 0)[::5].astype(np.float32))
    lo, hi = np.zeros(height, np.int32), np.zeros(height, np.int32)
    K.spans_around_chain(points, len(points), 4, 0.0, _NO_PROFILE, 1.0, 0.0, 0.0, 0.0, height, width, lo, hi, _NO_MOVED)
    b = _buffers(height, width)
    b["edges"][:] = 7
    count = K.detect_edges(image, np.array([0.25, 0.5, 0.25], np.float32), lo, hi, 20, 50, b["work"], b["tmp"],
                           b["smooth"], b["gx"], b["gy"], b["mag"], b["edges"], b["stack"])  # fmt: skip
    inside = np.zeros((height, width), bool)
    for r in range(height):
        inside[r, lo[r] : hi[r] + 1] = hi[r] >= lo[r]
    ring = ndimage.binary_dilation(inside, np.ones((3, 3), bool)) & ~inside
    assert ring.any() and (b["edges"][ring] == 0).all()
    assert set(np.unique(b["edges"][inside])) <= {0, 1}
    assert count == np.count_nonzero(b["edges"][inside]) > 0


def test_smooth_box_gives_the_values_detect_gives() -> None:
    # `EdgeDetector.smooth_box` fills the smoothed image outside the band with the values a band there would get.
    from ropecam.device.pipeline.edges import EdgeDetector

    rng = np.random.default_rng(3)
    frame = rng.integers(0, 256, (40, 50), dtype=np.uint8)
    whole = EdgeDetector(40, 50, 1.0, 20.0, 50.0)
    whole.detect(frame, whole.full_lo, whole.full_hi)
    assert whole.smooth_box(frame, 0, 39, 0, 49) == 0  # the spans of its last detect cover it: nothing to do
    boxed = EdgeDetector(40, 50, 1.0, 20.0, 50.0)
    boxed.smooth[:] = -1.0
    for r0, r1, c0, c1 in ((0, 5, 0, 7), (10, 30, 20, 49), (35, 39, 3, 3)):
        boxed.smooth_box(frame, r0, r1, c0, c1)
        np.testing.assert_array_equal(boxed.smooth[r0 : r1 + 1, c0 : c1 + 1], whole.smooth[r0 : r1 + 1, c0 : c1 + 1])
