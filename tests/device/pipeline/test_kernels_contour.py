"""Component selection, contour tracing, the paper's operator and scoring, against slow obvious references."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from scipy import ndimage

from ropecam.device.pipeline import _kernels as K

_NO_PROFILE = np.zeros(0)  # `spans_around_chain` without a measured profile
_NO_MOVED = np.zeros((0, 2), np.float32)  # nor the moved points

pytestmark = pytest.mark.kernel

FREEMAN = {(0, 1): 0, (-1, 1): 1, (-1, 0): 2, (-1, -1): 3, (0, -1): 4, (1, -1): 5, (1, 0): 6, (1, 1): 7}

_NO_MASK = np.zeros((1, 1), np.uint8)
_NO_MASK.flags.writeable = False
"""No static mask (a 1x1 placeholder)."""


def _label_buffers(shape):
    height, width = shape
    return (
        np.zeros(height, np.int32),
        np.full(height, width - 1, np.int32),
        np.zeros(shape, np.int32),
        np.zeros(height * width, np.int32),
        np.zeros(2, np.int32),
    )


def _trace(mask):
    lo, hi, labels, stack, start = _label_buffers(mask.shape)
    edges = mask.astype(np.uint8).copy()
    size = K.keep_largest_component(edges, lo, hi, 1, labels, stack, start)
    chain = np.zeros((4 * mask.size, 2), np.int32)
    codes = np.zeros(4 * mask.size, np.int32)
    n = K.trace_contour(edges, lo, hi, start[0], start[1], chain, codes)
    return size, edges, chain[:n], codes[:n]


def test_largest_component_matches_scipy() -> None:
    rng = np.random.default_rng(5)
    mask = rng.random((60, 80)) < 0.3
    lo, hi, labels, stack, start = _label_buffers(mask.shape)
    edges = mask.astype(np.uint8)
    size = K.keep_largest_component(edges, lo, hi, 1, labels, stack, start)
    ref_labels, _ = ndimage.label(mask, structure=np.ones((3, 3)))
    sizes = np.bincount(ref_labels.ravel())[1:]
    best = int(np.argmax(sizes)) + 1
    assert size == sizes.max()
    np.testing.assert_array_equal(edges == 1, ref_labels == best)
    np.testing.assert_array_equal(edges == 2, mask & (ref_labels != best))
    first = np.argwhere(ref_labels == best)[0]
    assert tuple(start) == tuple(first)


def test_largest_component_too_small_is_not_found() -> None:
    mask = np.zeros((10, 10), np.uint8)
    mask[2, 2:5] = 1
    lo, hi, labels, stack, start = _label_buffers(mask.shape)
    assert K.keep_largest_component(mask, lo, hi, 4, labels, stack, start) == K.NOT_FOUND
    assert not (mask == 1).any()


@pytest.mark.parametrize("shape", ["ring", "disk", "band", "spur"])
def test_trace_matches_opencv_outer_contour(shape) -> None:
    mask = np.zeros((40, 50), np.uint8)
    if shape == "ring":
        cv2.circle(mask, (25, 20), 12, 1, 1)
    elif shape == "disk":
        cv2.circle(mask, (25, 20), 9, 1, -1)
    elif shape == "band":
        cv2.ellipse(mask, (25, 20), (18, 5), 30, 0, 360, 1, 1)
    else:
        cv2.rectangle(mask, (10, 10), (35, 25), 1, 1)
        mask[25:33, 20] = 1  # an outward spur
    _, edges, chain, codes = _trace(mask)
    contours, _ = cv2.findContours((edges == 1).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    ref = contours[0][:, 0, ::-1]  # (row, col)
    assert len(chain) == len(ref)
    assert {tuple(p) for p in chain} == {tuple(p) for p in ref}
    r, c = chain[:, 0].astype(np.float64), chain[:, 1].astype(np.float64)
    assert np.sum(c * np.roll(r, -1) - np.roll(c, -1) * r) >= 0  # clockwise on screen (shoelace)
    for i in range(len(chain)):
        step = tuple(chain[(i + 1) % len(chain)] - chain[i])
        assert codes[i] == FREEMAN[step]


def test_trace_single_pixel() -> None:
    mask = np.zeros((5, 5), np.uint8)
    mask[2, 3] = 1
    _, _, chain, _ = _trace(mask)
    assert chain.tolist() == [[2, 3]]


def _tau_reference(chain):
    operator = {(-1, -1): -3, (-1, 0): 6, (-1, 1): 2, (0, -1): -5, (0, 1): 5, (1, -1): -2, (1, 0): -6, (1, 1): 3}
    n = len(chain)
    taus = []
    for i in range(n):
        image = np.zeros((3, 3), int)
        for j in (i - 1, (i + 1) % n):
            d = tuple(chain[j] - chain[i])
            if d in operator:
                image[d[0] + 1, d[1] + 1] = 1
        kernel = np.array([[-3, 6, 2], [-5, 0, 5], [-2, -6, 3]])
        taus.append(int((kernel * image).sum()))
    return taus


def test_operator_matches_reference_and_is_zero_on_straight_runs() -> None:
    mask = np.zeros((40, 50), np.uint8)
    cv2.ellipse(mask, (25, 20), (18, 9), 20, 0, 360, 1, 1)
    _, _, chain, _ = _trace(mask)
    tau = np.zeros(len(chain), np.int32)
    K.apply_operator(chain, len(chain), tau)
    assert tau.tolist() == _tau_reference(chain)
    square = np.zeros((20, 20), np.uint8)
    cv2.rectangle(square, (4, 4), (14, 14), 1, 1)
    _, _, chain, _ = _trace(square)
    tau = np.zeros(len(chain), np.int32)
    K.apply_operator(chain, len(chain), tau)
    corners = {(4, 4), (4, 14), (14, 4), (14, 14)}
    for p, t in zip(chain.tolist(), tau.tolist(), strict=True):
        assert (t != 0) == (tuple(p) in corners)


# Feature 2.2's 90-degree corners of two adjacent knots: the paper's four pairs and the same corner in the other
# four orientations, matched in either order.
CORNERS = [{3, -4}, {-3, 4}, {-2, -9}, {2, 9}, {-4, 9}, {4, -9}, {-2, 3}, {2, -3}]


def _score_reference(chain, tau, e1, e2, radius):
    knots = [i for i in range(len(chain)) if tau[i] != 0]
    m = len(knots)
    scores = []
    for k in range(m):
        t = tau[knots[k]]
        tp, tn = tau[knots[k - 1]], tau[knots[(k + 1) % m]]
        tpp, tnn = tau[knots[k - 2]], tau[knots[(k + 2) % m]]
        score = 0.0
        if t + tn != 0 and t + tp != 0:
            score += 1.0
        elif (t + tn == 0) != (t + tp == 0) and not (tp + tnn == 0 or tn + tpp == 0):
            score += 0.5
        if t in (1, -1, 5, -5):
            r1 = chain[knots[k]] - chain[knots[k - 2]]
            r2 = chain[knots[k]] - chain[knots[(k + 2) % m]]
            theta = math.degrees(math.acos(np.clip(r1 @ r2 / np.linalg.norm(r1) / np.linalg.norm(r2), -1, 1)))
            score += 0.5 if theta < 120 else 0.0
        elif {t, tn} in CORNERS or {t, tp} in CORNERS:
            score += 0.5
        near = min(np.hypot(*(chain[knots[k]] - e1)), np.hypot(*(chain[knots[k]] - e2))) < radius
        score += 1.0 if near else 0.0
        scores.append(score)
    return knots, scores


def test_scoring_matches_reference() -> None:
    mask = np.zeros((60, 60), np.uint8)
    pts = np.array([[10, 10], [30, 12], [50, 40], [35, 50], [20, 30]], np.int32)
    cv2.polylines(mask, [pts], True, 1, 1)
    _, _, chain, _ = _trace(mask)
    tau = np.zeros(len(chain), np.int32)
    K.apply_operator(chain, len(chain), tau)
    knots = np.zeros(len(chain), np.int32)
    scores = np.zeros(len(chain), np.float32)
    e1, e2 = np.array([10.0, 10.0]), np.array([40.0, 50.0])
    m = K.score_knots(chain, tau, len(chain), e1[0], e1[1], e2[0], e2[1], 8.0, knots, scores)
    ref_knots, ref_scores = _score_reference(chain.astype(float), tau, e1, e2, 8.0)
    assert knots[:m].tolist() == ref_knots
    np.testing.assert_allclose(scores[:m], ref_scores)
    assert set(np.unique(scores[:m])) <= {0.0, 0.5, 1.0, 1.5, 2.0, 2.5}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_listed_component_equals_the_span_scan(seed) -> None:
    rng = np.random.default_rng(seed)
    height, width = 40, 60
    edges = (rng.random((height, width)) < 0.3).astype(np.uint8)
    lo = rng.integers(0, 20, height).astype(np.int32)
    hi = (lo + rng.integers(-2, 45, height)).astype(np.int32)
    inside = np.zeros((height, width), bool)
    for r in range(height):
        inside[r, lo[r] : min(hi[r], width - 1) + 1] = hi[r] >= lo[r]
    listed = np.flatnonzero(edges.ravel() & inside.ravel()).astype(np.int32)  # raster order
    a, b = edges.copy(), edges.copy()
    la = np.full((height, width), 7, np.int32)  # stale labels must not matter
    lb = la.copy()
    sa, sb = np.zeros(height * width, np.int32), np.zeros(height * width, np.int32)
    start_a, start_b = np.zeros(2, np.int32), np.zeros(2, np.int32)
    size_a = K.keep_largest_component(a, lo, hi, 3, la, sa, start_a)
    size_b = K.keep_largest_listed(b, lo, hi, listed, len(listed), 3, False, lb, sb, start_b)
    assert size_a == size_b > 0
    np.testing.assert_array_equal(a[inside], b[inside])
    np.testing.assert_array_equal(start_a, start_b)
    assert K.keep_largest_listed(b.copy(), lo, hi, listed, len(listed), 10_000, False, lb, sb, start_b) == K.NOT_FOUND
    # The list in any order gives the same component and start (detect_edges lists strong pixels first).
    shuffled = rng.permutation(listed).astype(np.int32)
    c = edges.copy()
    start_c = np.zeros(2, np.int32)
    assert K.keep_largest_listed(c, lo, hi, shuffled, len(shuffled), 3, False, lb, sb, start_c) == size_a
    np.testing.assert_array_equal(a[inside], c[inside])
    np.testing.assert_array_equal(start_a, start_c)


def test_listed_component_ties_go_to_the_first_in_raster_order() -> None:
    edges = np.zeros((12, 12), np.uint8)
    edges[2, 6:9] = 1  # three pixels, first in raster order
    edges[8, 1:4] = 1  # three pixels too
    lo, hi, labels, stack, start = _label_buffers(edges.shape)
    listed = np.flatnonzero(edges.ravel())[::-1].astype(np.int32)  # the later component listed first
    assert K.keep_largest_listed(edges, lo, hi, listed, len(listed), 2, True, labels, stack, start) == 3
    assert tuple(start) == (2, 6)
    assert (edges[2, 6:9] == 1).all() and (edges[8, 1:4] == 2).all()


def test_border_contacts_match_reference() -> None:
    chain = np.array([[0, 5], [3, 0], [3, 9], [7, 4], [9, 9], [4, 4]], np.int32)
    height, width = 10, 10
    on_border = [(r, c) for r, c in chain if r in (0, height - 1) or c in (0, width - 1)]
    assert K.count_border_contacts(chain, len(chain), height, width, -1e9, -1e9, 5.0) == len(on_border)
    far = [(r, c) for r, c in on_border if math.hypot(r - 0.0, c - 5.0) > 3.5]
    assert K.count_border_contacts(chain, len(chain), height, width, 0.0, 5.0, 3.5) == len(far)


@pytest.mark.parametrize("seed", [0, 1])
def test_roi_contacts_match_reference(seed) -> None:
    rng = np.random.default_rng(seed)
    height, width = 30, 40
    lo = rng.integers(0, 15, height).astype(np.int32)
    hi = (lo + rng.integers(-3, 30, height)).astype(np.int32)
    chain = np.stack([rng.integers(0, height, 200), rng.integers(0, width, 200)], axis=1).astype(np.int32)

    def inside(r, c):
        return lo[r] <= c <= hi[r]

    want = 0
    for r, c in chain:
        neighbours = [(r + dr, c + dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if (dr, dc) != (0, 0)]
        if any(0 <= rr < height and 0 <= cc < width and not inside(rr, cc) for rr, cc in neighbours):
            want += 1
    assert K.count_roi_contacts(chain, len(chain), lo, hi, width) == want


def test_listed_component_on_a_detected_band_equals_the_span_scan(blurred_frames) -> None:
    # detect_edges leaves 0 around the band: keep_largest_listed may flood without span tests (ring_clear).
    image = blurred_frames[2].image
    height, width = image.shape
    lo, hi = np.zeros(height, np.int32), np.full(height, width - 1, np.int32)
    planes = [np.zeros((height, width), np.float32) for _ in range(5)]
    edges = np.full((height, width), 7, np.uint8)  # stale values outside the band must not matter
    stack = np.zeros(height * width, np.int32)
    work = np.zeros((4, height), np.int32)
    weights = np.array([0.25, 0.5, 0.25], np.float32)
    K.detect_edges(image, weights, lo, hi, 20.0, 50.0, work, *planes, edges, stack)
    points = np.ascontiguousarray(np.argwhere(edges == 1)[::7].astype(np.float32))
    K.spans_around_chain(points, len(points), 5, 0.0, _NO_PROFILE, 1.0, 0.0, 0.0, 0.0, height, width, lo, hi, _NO_MOVED)
    rows = np.flatnonzero(hi >= lo)
    assert rows.min() > 0 and rows.max() < height - 1 and lo[rows].min() > 0 and hi[rows].max() < width - 1
    edges[:] = 7
    count = K.detect_edges(image, weights, lo, hi, 20.0, 50.0, work, *planes, edges, stack)
    inside = np.zeros((height, width), bool)
    for r in range(height):
        inside[r, lo[r] : hi[r] + 1] = hi[r] >= lo[r]
    a, b = edges.copy(), edges.copy()
    a[~inside] = 0  # the span scan sees only the band
    labels = np.zeros((height, width), np.int32)
    work_stack = np.zeros(height * width, np.int32)
    start_a, start_b = np.zeros(2, np.int32), np.zeros(2, np.int32)
    size_a = K.keep_largest_component(a, lo, hi, 3, labels, work_stack, start_a)
    size_b = K.keep_largest_listed(b, lo, hi, stack, count, 3, True, labels, work_stack, start_b)
    assert size_a == size_b > 100
    np.testing.assert_array_equal(a[inside], b[inside])
    np.testing.assert_array_equal(start_a, start_b)


@pytest.mark.parametrize("shape", ["ring", "disk", "band", "spur", "dot"])
def test_trace_closed_equals_trace_contour(shape) -> None:
    mask = np.zeros((40, 50), np.uint8)
    if shape == "ring":
        cv2.circle(mask, (25, 20), 12, 1, 1)
    elif shape == "disk":
        cv2.circle(mask, (25, 20), 9, 1, -1)
    elif shape == "band":
        cv2.ellipse(mask, (25, 20), (18, 5), 30, 0, 360, 1, 1)
    elif shape == "spur":
        cv2.rectangle(mask, (10, 10), (35, 25), 1, 1)
        mask[25:33, 20] = 1
    else:
        mask[7, 9] = 1
    _, edges, chain, codes = _trace(mask)
    start = np.argwhere(edges == 1)[0].astype(np.int32)
    out_chain = np.zeros((4 * mask.size, 2), np.int32)
    out_codes = np.zeros(4 * mask.size, np.int32)
    n = K.trace_closed(edges.reshape(-1), mask.shape[1], start[0], start[1], out_chain, out_codes)
    np.testing.assert_array_equal(out_chain[:n], chain)
    np.testing.assert_array_equal(out_codes[:n], codes)
    if n > 1:  # a buffer one short of the chain
        assert K.trace_closed(edges.reshape(-1), mask.shape[1], start[0], start[1], out_chain[: n - 1],
                              out_codes[: n - 1]) == K.FULL  # fmt: skip


def _band_of(image, margin_px):
    """Detect the edges of `image` whole, then a band of discs around every 3rd edge pixel."""
    height, width = image.shape
    lo, hi = np.zeros(height, np.int32), np.full(height, width - 1, np.int32)
    planes = [np.zeros((height, width), np.float32) for _ in range(5)]
    edges = np.zeros((height, width), np.uint8)
    stack = np.zeros(height * width, np.int32)
    work = np.zeros((4, height), np.int32)
    weights = np.array([0.25, 0.5, 0.25], np.float32)
    K.detect_edges(image, weights, lo, hi, 20.0, 50.0, work, *planes, edges, stack)
    points = np.ascontiguousarray(np.argwhere(edges == 1)[::3].astype(np.float32))
    K.spans_around_chain(
        points, len(points), margin_px, 0.0, _NO_PROFILE, 1.0, 0.0, 0.0, 0.0, height, width, lo, hi, _NO_MOVED
    )
    edges[:] = 7  # stale values outside the band must not matter
    count = K.detect_edges(image, weights, lo, hi, 20.0, 50.0, work, *planes, edges, stack)
    return lo, hi, planes, edges, stack, count


@pytest.mark.parametrize(("frame", "ring_clear", "whole"), [(2, True, False), (4, True, False), (2, False, False),
                                                             (5, True, True)])  # fmt: skip
def test_trace_rope_equals_the_kernels_one_by_one(blurred_frames, frame, ring_clear, whole) -> None:
    image = blurred_frames[frame].image
    height, width = image.shape
    lo, hi, planes, edges, stack, count = _band_of(image, 5)
    if whole:  # spans reaching the image border: the checked trace
        lo[:], hi[:] = 0, width - 1
        edges[:] = 0
        count = K.detect_edges(image, np.array([0.25, 0.5, 0.25], np.float32), lo, hi, 20.0, 50.0,
                               np.zeros((4, height), np.int32), *planes, edges, stack)  # fmt: skip
    gx, gy, mag = planes[2], planes[3], planes[4]
    capacity = 4000
    ref_edges = edges.copy()
    labels, work_stack = np.zeros((height, width), np.int32), np.zeros(height * width, np.int32)
    start = np.zeros(2, np.int32)
    size = K.keep_largest_listed(ref_edges, lo, hi, stack, count, 20, ring_clear, labels, work_stack, start)
    chain, codes = np.zeros((capacity, 2), np.int32), np.zeros(capacity, np.int32)
    n = K.trace_contour(ref_edges, lo, hi, start[0], start[1], chain, codes)
    n = K.prune_excursions(chain, codes, n, width, work_stack)
    points = np.zeros((capacity, 2), np.float32)
    K.refine_subpixel(mag, gx, gy, chain, n, points)
    contacts = K.count_roi_contacts(chain, n, lo, hi, width)
    on_border = int(np.count_nonzero((chain[:n, 0] % (height - 1) == 0) | (chain[:n, 1] % (width - 1) == 0)))
    assert size > 100 and n > 100
    out = [np.zeros((height, width), np.int32), np.zeros(height * width, np.int32), np.zeros(2, np.int32),
           np.zeros((capacity, 2), np.int32), np.zeros(capacity, np.int32), np.zeros((capacity, 2), np.float32),
           np.full(3, -5, np.int32)]  # fmt: skip
    got = K.trace_rope(edges, lo, hi, stack, count, 20, ring_clear, _NO_MASK, mag, gx, gy, K.Contour(*out))
    assert got == n
    np.testing.assert_array_equal(edges, ref_edges)
    np.testing.assert_array_equal(out[2], start)
    np.testing.assert_array_equal(out[3][:n], chain[:n])
    np.testing.assert_array_equal(out[4][:n], codes[:n])
    np.testing.assert_array_equal(out[5][:n], points[:n])
    assert out[6].tolist() == [size, contacts, on_border]
    # A band cut through the rope: contacts counted as count_roi_contacts does.
    lo2, hi2 = lo.copy(), hi.copy()
    rows = np.flatnonzero(hi >= lo)
    cut = rows[len(rows) // 2 :]
    hi2[cut] = np.maximum(lo2[cut], (lo2[cut] + hi2[cut]) // 2)
    edges[:] = 0
    count = K.detect_edges(image, np.array([0.25, 0.5, 0.25], np.float32), lo2, hi2, 20.0, 50.0,
                           np.zeros((4, height), np.int32), *planes, edges, stack)  # fmt: skip
    ref_edges = edges.copy()
    K.keep_largest_listed(ref_edges, lo2, hi2, stack, count, 20, ring_clear, labels, work_stack, start)
    n = K.trace_contour(ref_edges, lo2, hi2, start[0], start[1], chain, codes)
    n = K.prune_excursions(chain, codes, n, width, work_stack)
    got = K.trace_rope(edges, lo2, hi2, stack, count, 20, ring_clear, _NO_MASK, mag, gx, gy, K.Contour(*out))
    assert got == n > 0
    assert out[6][1] == K.count_roi_contacts(chain, n, lo2, hi2, width) > 0


def test_trace_rope_without_a_component(blurred_frames) -> None:
    image = blurred_frames[2].image
    height, width = image.shape
    lo, hi, planes, edges, stack, count = _band_of(image, 5)
    out = [np.zeros((height, width), np.int32), np.zeros(height * width, np.int32), np.zeros(2, np.int32),
           np.zeros((10, 2), np.int32), np.zeros(10, np.int32), np.zeros((10, 2), np.float32),
           np.full(3, -5, np.int32)]  # fmt: skip
    keep = edges.copy()
    assert (
        K.trace_rope(
            edges, lo, hi, stack, count, 10**6, True, _NO_MASK, planes[4], planes[2], planes[3], K.Contour(*out)
        )
        == K.NOT_FOUND
    )
    assert out[6].tolist() == [0, 0, 0]
    assert (
        K.trace_rope(keep, lo, hi, stack, count, 20, True, _NO_MASK, planes[4], planes[2], planes[3], K.Contour(*out))
        == K.FULL
    )
    assert out[6][0] > 100


def _shapes(case):
    """An edge map (1 = edge) with components off the image border, and the minimum size to ask for."""
    mask = np.zeros((48, 64), np.uint8)
    min_px = 5
    if case == "thick ring":  # pixels inside the outer boundary: groups the chain misses that touch it
        cv2.circle(mask, (30, 22), 12, 1, 2)
    elif case == "disk":
        cv2.circle(mask, (30, 22), 9, 1, -1)
    elif case == "larger below":  # the first component in raster order is not the largest
        cv2.circle(mask, (15, 8), 4, 1, 1)
        cv2.ellipse(mask, (35, 30), (20, 9), 20, 0, 360, 1, 1)
    elif case == "tie":  # equal components: the first in raster order wins
        cv2.rectangle(mask, (5, 5), (15, 15), 1, 1)
        cv2.rectangle(mask, (30, 25), (40, 35), 1, 1)
    elif case == "small others":
        cv2.ellipse(mask, (30, 14), (20, 7), 10, 0, 360, 1, 1)
        mask[30:32, 10:12] = 1
        mask[40, 50] = 1
        cv2.circle(mask, (45, 36), 3, 1, 1)
    elif case == "first too small":  # the first component is below min_px, a later one is not
        mask[4, 30] = 1
        cv2.circle(mask, (30, 26), 10, 1, 1)
        min_px = 3
    elif case == "all too small":
        mask[5:7, 5:7] = 1
        mask[20, 20:23] = 1
        min_px = 10
    else:  # a component and a hole in it, with a spur into the hole
        cv2.rectangle(mask, (10, 8), (50, 38), 1, 1)
        cv2.rectangle(mask, (20, 16), (40, 30), 1, 1)
        mask[30:39, 30] = 1
    return mask, min_px


@pytest.mark.parametrize(
    "case",
    ["thick ring", "disk", "larger below", "tie", "small others", "first too small", "all too small", "nested"],
)
@pytest.mark.parametrize("spans", ["wide", "tight"])
def test_trace_rope_traced_first_equals_the_kernels_one_by_one(case, spans) -> None:
    # trace_rope traces the first listed pixel's component before knowing it is the largest (`keep_traced`);
    # the slow way: scan the spans for the largest component, trace it, refine and count contacts one by one.
    mask, min_px = _shapes(case)
    height, width = mask.shape
    rng = np.random.default_rng(7)
    lo, hi = np.full(height, 1, np.int32), np.full(height, width - 2, np.int32)
    if spans == "tight":  # spans hugging the edges (contacts), and empty rows with extreme bounds
        for r in range(height):
            cols = np.flatnonzero(mask[r])
            if cols.size:
                lo[r], hi[r] = max(cols[0] - rng.integers(0, 2), 1), min(cols[-1] + rng.integers(0, 2), width - 2)
            else:
                lo[r], hi[r] = np.iinfo(np.int32).max, np.iinfo(np.int32).min
    lo[0], hi[0], lo[-1], hi[-1] = 1, 0, 1, 0  # rows 0 and height - 1 empty: the spans keep off the border
    mag = rng.uniform(0, 100, mask.shape).astype(np.float32)
    gx = rng.normal(0, 50, mask.shape).astype(np.float32)
    gy = rng.normal(0, 50, mask.shape).astype(np.float32)
    gx[::5, ::3] = gy[::5, ::3] = 0.0  # no gradient: no offset
    mag[::4, ::2] = mag[1::4, ::2]  # flat magnitude: no maximum
    edge_list = rng.permutation(np.flatnonzero(mask)).astype(np.int32)
    ref = mask.copy()
    labels, work_stack = np.zeros(mask.shape, np.int32), np.zeros(mask.size, np.int32)
    start = np.zeros(2, np.int32)
    size = K.keep_largest_component(ref, lo, hi, min_px, labels, work_stack, start)
    capacity = 4 * mask.size
    chain, codes = np.zeros((capacity, 2), np.int32), np.zeros(capacity, np.int32)
    points = np.zeros((capacity, 2), np.float32)
    out = [np.zeros(mask.shape, np.int32), np.zeros(mask.size, np.int32), np.full(2, -3, np.int32),
           np.zeros((capacity, 2), np.int32), np.zeros(capacity, np.int32), np.zeros((capacity, 2), np.float32),
           np.full(3, -5, np.int32)]  # fmt: skip
    edges = mask.copy()
    got = K.trace_rope(edges, lo, hi, edge_list, len(edge_list), min_px, True, _NO_MASK, mag, gx, gy, K.Contour(*out))
    np.testing.assert_array_equal(edges, ref)
    if size < 0:
        assert got == K.NOT_FOUND and case == "all too small"
        assert out[6].tolist() == [0, 0, 0] and out[2].tolist() == [-3, -3]
        return
    n = K.trace_contour(ref, lo, hi, start[0], start[1], chain, codes)
    n = K.prune_excursions(chain, codes, n, width, work_stack)
    K.refine_subpixel(mag, gx, gy, chain, n, points)
    assert got == n > 0
    np.testing.assert_array_equal(out[2], start)
    np.testing.assert_array_equal(out[3][:n], chain[:n])
    np.testing.assert_array_equal(out[4][:n], codes[:n])
    np.testing.assert_array_equal(out[5][:n], points[:n])
    assert out[6].tolist() == [size, K.count_roi_contacts(chain, n, lo, hi, width), 0]
    if spans == "tight":
        assert out[6][1] > 0
    if case == "larger below":
        assert start[0] > 15  # the second component was chosen
    # A chain buffer too short: FULL, with the component's size, as the kernels one by one.
    short = [*out[:3], out[3][: n - 1], out[4][: n - 1], *out[5:]]
    edges = mask.copy()
    if n > 1:
        assert (
            K.trace_rope(
                edges, lo, hi, edge_list, len(edge_list), min_px, True, _NO_MASK, mag, gx, gy, K.Contour(*short)
            )
            == K.FULL
        )
        assert out[6][0] == size
        np.testing.assert_array_equal(edges, ref)


def _u_curve(shape=(40, 60), thick_end=False):
    """A one-pixel open U (the rope's two sides joined at its tip, cut at the clamp), as the mask leaves it."""
    mask = np.zeros(shape, bool)
    mask[5:30, 10] = True  # one side
    mask[5:30, 14] = True  # the other
    mask[30, 10:15] = True  # the tip's cap
    if thick_end:
        mask[5, 15] = True  # the walk returns on a neighbouring pixel at this end
    return mask


@pytest.mark.parametrize("thick_end", [False, True])
def test_keep_open_once_keeps_an_out_and_back_walk_once(thick_end) -> None:
    mask = _u_curve(thick_end=thick_end)
    size, _, chain, codes = _trace(mask)
    n = len(chain)
    assert n >= K.OPEN_RATIO * size  # walked out and back
    chain, codes = chain.copy(), codes.copy()
    m = K.keep_open_once(chain, codes, np.int32(n), np.int32(size))
    kept = chain[:m]
    ends = {tuple(kept[0]), tuple(kept[-1])}
    assert ends <= {(5, 10), (5, 14), (5, 15), (6, 14)}  # from one cut end to the other
    assert len({tuple(p) for p in kept}) >= size - 2  # every pixel of the curve, about once
    assert m <= size + 2


def test_keep_open_once_leaves_a_closed_outline() -> None:
    mask = _u_curve()
    mask[5, 10:15] = True  # closed at the fixed end: a ring
    size, _, chain, codes = _trace(mask)
    before = chain.copy()
    m = K.keep_open_once(chain, codes, np.int32(len(chain)), np.int32(size))
    assert m == len(before)
    np.testing.assert_array_equal(chain, before)


def test_trace_rope_walks_an_open_outline_once() -> None:
    """The contour stage on a rope cut at its clamp: the chain from one cut end round the tip to the other."""
    mask = _u_curve((40, 60))
    height, width = mask.shape
    edges = mask.astype(np.uint8)
    listed = np.flatnonzero(edges.ravel()).astype(np.int32)
    lo = np.zeros(height, np.int32)
    hi = np.full(height, width - 1, np.int32)
    mag = np.ones(mask.shape, np.float32)
    gx = np.zeros(mask.shape, np.float32)
    labels = np.zeros(mask.shape, np.int32)
    stack = np.zeros(height * width, np.int32)
    start = np.zeros(2, np.int32)
    chain = np.zeros((4 * mask.size, 2), np.int32)
    codes = np.zeros(4 * mask.size, np.int32)
    points = np.zeros((4 * mask.size, 2), np.float32)
    counts = np.zeros(3, np.int32)
    static = np.zeros(mask.shape, np.uint8)
    static[:5, 8:17] = K.MASK_ALWAYS  # the clamp above the cut ends (5, 10) and (5, 14)
    static.flags.writeable = False
    n = K.trace_rope(
        edges,
        lo,
        hi,
        listed,
        len(listed),
        5,
        False,
        static,
        mag,
        gx,
        gx,
        K.Contour(labels, stack, start, chain, codes, points, counts),
    )
    assert counts[0] == mask.sum()
    assert mask.sum() - 4 <= n <= mask.sum()  # once (the walk cuts the cap's corners), not out and back
    assert {tuple(chain[0]), tuple(chain[n - 1])} == {(5, 10), (5, 14)}


def _open_band(reach_px=4):
    """A band's outline open at its far end (a tip moving along the rope: no edge there), closed at the clamp,
    whose sides are two pixels thick along part of their length (an out-and-back walk of 1.2-1.6 x its pixels),
    with the clamp's mask above it."""
    mask = np.zeros((50, 40), bool)
    mask[5:40, 10] = True  # one side, to its open end (39, 10)
    mask[5:40, 10 + reach_px] = True  # the other
    mask[5, 10 : 11 + reach_px] = True  # sealed at the clamp
    mask[10:22, 11] = True  # two pixels thick in places
    mask[22:34, 9 + reach_px] = True
    static = np.zeros(mask.shape, np.uint8)
    static[:5, 8 : 13 + reach_px] = K.MASK_ALWAYS
    static.flags.writeable = False
    return mask, static


def _trace_rope_on(mask, static, ring_clear):
    height, width = mask.shape
    edges = mask.astype(np.uint8)
    listed = np.flatnonzero(edges.ravel()).astype(np.int32)
    lo = np.full(height, 1, np.int32)
    hi = np.full(height, width - 2, np.int32)
    mag = np.ones(mask.shape, np.float32)
    gx = np.zeros(mask.shape, np.float32)
    chain = np.zeros((4 * mask.size, 2), np.int32)
    contour = K.Contour(
        np.zeros(mask.shape, np.int32), np.zeros(height * width, np.int32), np.zeros(2, np.int32), chain,
        np.zeros(4 * mask.size, np.int32), np.zeros((4 * mask.size, 2), np.float32), np.zeros(3, np.int32),
    )  # fmt: skip
    n = K.trace_rope(edges, lo, hi, listed, len(listed), 5, ring_clear, static, mag, gx, gx, contour)
    return n, edges, contour


@pytest.mark.parametrize("ring_clear", [False, True])
@pytest.mark.parametrize("apart", [4, 7])
def test_trace_rope_joins_a_band_outline_open_at_its_far_end(ring_clear, apart) -> None:
    """An outline walked out and back because the band's far end has no edge (simulated `lab`, 240 frames, frame
    90: `LOST_TRACK`, "the band's edge is broken"; its ends 3 px apart, frame 158's 7 px) is joined there and traced
    as a ring."""
    mask, static = _open_band(apart)
    size, edges, chain, _ = _trace(mask)
    n = len(chain)
    assert size < n < K.OPEN_RATIO * size  # not `keep_open_once`'s
    assert K.count_revisits(chain, np.int32(n), edges) > K.BROKEN_OUTLINE * n  # broken, as traced alone
    m, edges, contour = _trace_rope_on(mask, static, ring_clear)
    assert K.count_revisits(contour.chain[:m], np.int32(m), edges) <= K.JOINED_REVISITS * m
    assert contour.counts[0] == size + apart - 1  # the join's pixels (39, 11..9 + apart)
    assert np.all(edges[39, 10 : 11 + apart] == 1)
    assert m <= size + apart - 1
    # Without the clamp's mask (the mask still being learned: a still rope open at its clamp) it is left alone.
    no_static = np.zeros_like(static)
    no_static.flags.writeable = False
    m, edges, contour = _trace_rope_on(mask, no_static, ring_clear)
    assert m == n and contour.counts[0] == size and not edges[39, 11 : 10 + apart].any()


def test_trace_rope_leaves_an_open_outline_whose_ends_lie_apart() -> None:
    """Ends farther apart than `JOIN_REACH_PX`: no join (the outline check then says the band's edge is broken)."""
    mask, static = _open_band(K.JOIN_REACH_PX + 2)
    size, _, chain, _ = _trace(mask)
    assert size < len(chain) < K.OPEN_RATIO * size
    m, edges, contour = _trace_rope_on(mask, static, True)
    assert m == len(chain) and contour.counts[0] == size
    np.testing.assert_array_equal(edges != 0, mask)


@pytest.mark.parametrize("ring_clear", [False, True])
def test_trace_rope_drops_a_spur_of_noise_hung_on_a_band_side(ring_clear) -> None:
    """A band's closed outline with a spur of noise off one side next to its far end (simulated `read noise =
    10 DN`, tuning seed, frame 26: a spur's turnaround was taken for the band's corner): traced as the ring alone,
    as the outline without the spur traces."""
    band = np.zeros((60, 40), bool)
    band[5, 10:19] = band[54, 10:19] = True
    band[5:55, 10] = band[5:55, 18] = True
    spur = band.copy()
    spur[44, 3:10] = True  # 7 px out of the left side, 10 px from the far end
    m_ref, _, ref = _trace_rope_on(band, _NO_MASK, ring_clear)
    ref_chain = ref.chain[:m_ref].copy()
    _, _, raw, _ = _trace(spur)
    assert len(raw) > m_ref  # the spur walked out and back
    m, _, contour = _trace_rope_on(spur, _NO_MASK, ring_clear)
    assert m == m_ref
    differ = np.flatnonzero(np.any(contour.chain[:m] != ref_chain, axis=1))
    assert len(differ) <= 1  # the trace cuts the corner into the spur's root: that pixel kept for the side's
    assert np.abs(contour.chain[differ] - ref_chain[differ]).max(initial=0) <= 1


@pytest.mark.parametrize("ring_clear", [False, True])
def test_trace_rope_joins_an_open_outline_that_walks_few_pixels_twice(ring_clear) -> None:
    """An outline open at its far end whose sides are two pixels thick along most of their length walks only a few
    of its pixels twice (between `JOINED_REVISITS` and `BROKEN_OUTLINE`: simulated `plate edge = 0.7`, tuning seed,
    frame 27, 14.5 %, where a side cut by the plate's masked bevel left the band open): joined as well."""
    apart = 4
    mask, static = _open_band(apart)
    mask[8:36, 11] = True  # both sides two pixels thick from the clamp nearly to the open end
    mask[8:36, 9 + apart] = True
    size, edges, chain, _ = _trace(mask)
    n = len(chain)
    revisits = K.count_revisits(chain, np.int32(n), edges)
    assert K.JOINED_REVISITS * n < revisits <= K.BROKEN_OUTLINE * n
    m, edges, contour = _trace_rope_on(mask, static, ring_clear)
    assert contour.counts[0] == size + apart - 1  # the join's pixels
    assert np.all(edges[39, 10 : 11 + apart] == 1)
    assert K.count_revisits(contour.chain[:m], np.int32(m), edges) <= K.JOINED_REVISITS * m
