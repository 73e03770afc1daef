"""Subpixel refinement, contour geometry and material point tracking against slow obvious references."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from scipy.special import erf

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._kernels.geometry import _split_from, _turn_at

pytestmark = pytest.mark.kernel


# The steps that the package's `find_segmentation_points` fuses, and the plain material point tracking, as
# references (the package calls only the fused kernels).
def signed_area(points: np.ndarray, n: int) -> float:
    """The signed area (shoelace, (row, col)) of the closed polygon of the first `n` points; positive for a
    clockwise traversal on screen."""
    r, c = points[:n, 0].astype(np.float64), points[:n, 1].astype(np.float64)
    return 0.5 * float(np.sum(c * np.roll(r, -1) - np.roll(c, -1) * r))


def turning_angles_far(points, n, scale, fixed_r, fixed_c, search_px, out_dist, out_turn) -> int:
    """The distance of every point from the fixed end into `out_dist`, and the turning angle (`turning_angles`)
    only where `split_contour` reads it: at the points at least ``R_far - search_px`` from the fixed end and at
    their two neighbours; 0 elsewhere. Returns the number of angles computed, or FULL."""
    if out_dist.shape[0] < n or out_turn.shape[0] < n:
        return K.FULL
    d_r = (points[:n, 0] - np.float32(fixed_r)).astype(np.float64)  # differences in float32, as the kernels
    d_c = (points[:n, 1] - np.float32(fixed_c)).astype(np.float64)
    d = np.sqrt(d_r * d_r + d_c * d_c)
    out_dist[:n] = d
    out_turn[:n] = 0.0
    zone = d >= d.max() - search_px
    needed = zone | np.roll(zone, 1) | np.roll(zone, -1)
    for k in np.flatnonzero(needed):
        out_turn[k] = _turn_at(points, n, scale, k)
    return int(np.count_nonzero(needed))


def split_contour(
    points, turn, dist, n, fixed_r, fixed_c, search_px, min_gap, corner_rad, work_arc, out_idx, scale=3
) -> int:
    """The segmentation points of a closed contour from its turning angles `turn` (at `scale`) and distances `dist`
    from the fixed end (`turning_angles_far`): the fixed end is the nearest point, the far point the farthest,
    then as `find_segmentation_points` (its `_split_from`). Writes ``out_idx = [fixed, seg_a, far, seg_b]``;
    returns 4, NOT_FOUND or FULL."""
    if n < 8:
        return K.NOT_FOUND
    if dist.shape[0] < n:
        return K.FULL
    i_fix, i_far = int(np.argmin(dist[:n])), int(np.argmax(dist[:n]))
    far_r = float(dist[i_far])
    found = _split_from(
        points, np.int32(scale), turn, dist, n, i_fix, i_far, far_r, search_px, min_gap, corner_rad, work_arc, out_idx
    )
    return int(found)


def _edge_image(angle_deg: float, offset_px: float, size: int = 41) -> tuple[np.ndarray, np.ndarray, float]:
    """A blurred straight step edge through the image centre shifted by `offset_px` along its normal."""
    normal = np.array([math.sin(math.radians(angle_deg)), math.cos(math.radians(angle_deg))])  # (row, col)
    rows, cols = np.mgrid[0:size, 0:size].astype(float)
    centre = (size - 1) / 2
    signed = (rows - centre) * normal[0] + (cols - centre) * normal[1] - offset_px
    image = 40 + 150 * 0.5 * (1 + erf(signed / (1.2 * math.sqrt(2))))
    return np.clip(np.rint(image), 0, 255).astype(np.uint8), normal, centre


@pytest.mark.parametrize(("angle", "offset"), [(0.0, 0.3), (17.0, -0.2), (45.0, 0.45), (71.0, 0.1)])
def test_subpixel_refinement_finds_the_edge(angle, offset) -> None:
    image, normal, centre = _edge_image(angle, offset)
    height, width = image.shape
    lo, hi = np.zeros(height, np.int32), np.full(height, width - 1, np.int32)
    bufs = [np.zeros((height, width), np.float32) for _ in range(5)]
    edges = np.zeros((height, width), np.uint8)
    K.detect_edges(
        image,
        np.array([0.25, 0.5, 0.25], np.float32),
        lo,
        hi,
        10.0,
        30.0,
        np.zeros((4, height), np.int32),
        *bufs,
        edges,
        np.zeros(height * width, np.int32),
    )
    chain = np.ascontiguousarray(np.argwhere(edges[5:-5, 5:-5] > 0) + 5).astype(np.int32)
    points = np.zeros(chain.shape, np.float32)
    K.refine_subpixel(bufs[4], bufs[2], bufs[3], chain, len(chain), points)
    distance = (points[:, 0] - centre) * normal[0] + (points[:, 1] - centre) * normal[1] - offset
    integer = (chain[:, 0] - centre) * normal[0] + (chain[:, 1] - centre) * normal[1] - offset
    assert np.abs(distance).mean() < 0.06
    assert np.abs(distance).mean() < 0.5 * np.abs(integer).mean() + 1e-9


def test_subpixel_matches_reference_parabola() -> None:
    rng = np.random.default_rng(2)
    mag = rng.uniform(0, 10, (12, 12)).astype(np.float32)
    gx = rng.normal(size=(12, 12)).astype(np.float32)
    gy = rng.normal(size=(12, 12)).astype(np.float32)
    chain = np.array([[3, 4], [5, 5], [8, 2], [6, 9]], np.int32)
    out = np.zeros((4, 2), np.float32)
    K.refine_subpixel(mag, gx, gy, chain, 4, out)
    for (r, c), got in zip(chain, out, strict=True):
        axis = np.array([0.0, 1.0]) if abs(gx[r, c]) >= abs(gy[r, c]) else np.array([1.0, 0.0])
        mm = mag[r - int(axis[0]), c - int(axis[1])]
        mp = mag[r + int(axis[0]), c + int(axis[1])]
        denom = mm - 2 * mag[r, c] + mp
        delta = np.clip(0.5 * (mm - mp) / denom, -1, 1) if denom < 0 else 0.0
        np.testing.assert_allclose(got, [r + delta * axis[0], c + delta * axis[1]], atol=1e-4)


def _closed_polygon(points: list[tuple[float, float]], step: float = 0.5) -> np.ndarray:
    out = []
    for a, b in zip(points, points[1:] + points[:1], strict=True):
        a, b = np.array(a, float), np.array(b, float)
        count = max(1, int(np.ceil(np.hypot(*(b - a)) / step)))
        out.extend(a + (b - a) * k / count for k in range(count))
    return np.array(out, np.float32)


def test_turning_angles_matches_reference() -> None:
    pts = _closed_polygon([(0, 0), (0, 10), (10, 10), (10, 0)], 1.0)
    turn = np.zeros(len(pts), np.float32)
    K.turning_angles(pts, len(pts), 2, turn)
    n = len(pts)
    for i in range(n):
        v1 = pts[i] - pts[(i - 2) % n]
        v2 = pts[(i + 2) % n] - pts[i]
        ref = math.acos(np.clip(v1 @ v2 / np.linalg.norm(v1) / np.linalg.norm(v2), -1, 1))
        assert turn[i] == pytest.approx(ref, abs=1e-5)
    assert turn.max() == pytest.approx(math.pi / 2, abs=1e-5)


def test_split_finds_the_corners_of_a_swept_band() -> None:
    # The outline of a band swept about (0, 0): side A along col 0, tip track from (40, 0) to (40, 12), side B back.
    pts = _closed_polygon([(0, -1), (40, -1), (40, 13), (0, 1)], 0.5)
    turn = np.zeros(len(pts), np.float32)
    K.turning_angles(pts, len(pts), 3, turn)
    idx = np.zeros(4, np.int32)
    dist = np.hypot(pts[:, 0], pts[:, 1]).astype(np.float64)
    assert split_contour(pts, turn, dist, len(pts), 0.0, 0.0, 6.0, 6, 0.5, np.zeros(len(pts), np.float32), idx) == 4
    fixed, seg_a, far, seg_b = idx
    assert np.hypot(*pts[fixed]) <= 1.01
    assert np.allclose(pts[seg_a], (40, -1), atol=0.6)
    assert np.allclose(pts[seg_b], (40, 13), atol=0.6)
    assert np.allclose(pts[far], (40, 13), atol=0.6)
    assert split_contour(pts[:6], turn, dist, 6, 0.0, 0.0, 6.0, 6, 0.5, np.zeros(6, np.float32), idx) == K.NOT_FOUND


def test_offset_side_moves_inward_by_the_modelled_half_width() -> None:
    pts = _closed_polygon([(0, 0), (0, 20), (4, 20), (4, 0)], 1.0)  # clockwise on screen
    assert signed_area(pts, len(pts)) > 0
    out = np.zeros((64, 2), np.float32)
    count = K.offset_side(pts, len(pts), 2, 18, 1, 1.0, 4.0, 0.0, 1, out)
    assert count == 17
    np.testing.assert_allclose(out[:count, 0], 2.0, atol=1e-5)  # moved down by half the width
    count = K.offset_side(pts, len(pts), 2, 18, 1, 1.0, 4.0, 4.0, 1, out)
    s = np.arange(count) / (count - 1)
    np.testing.assert_allclose(out[:count, 0], 0.5 * (4.0 - 4.0 * s), atol=1e-5)


def test_midline_of_two_parallel_sides() -> None:
    a = np.stack([np.linspace(0, 30, 31), np.zeros(31)], axis=1).astype(np.float32)
    b = np.stack([np.linspace(0, 30, 61), np.full(61, 4.0)], axis=1).astype(np.float32)
    out = np.zeros((31, 2), np.float32)
    dist = np.zeros(31, np.float32)
    assert K.midline(a, 31, b, 61, out, dist) == 31
    np.testing.assert_allclose(dist, 4.0, atol=1e-5)
    np.testing.assert_allclose(out[:, 1], 2.0, atol=1e-5)
    np.testing.assert_allclose(out[:, 0], a[:, 0], atol=1e-5)


def _track_reference(poly, arcs, length0):
    seg = np.hypot(*np.diff(poly, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    lc = cum[-1]  # eq. (9)
    out = []
    for arc in arcs:
        target = arc * lc / length0
        j = int(np.searchsorted(cum, target, side="right")) - 1  # eqs. (10)-(11)
        if target <= 0:
            out.append(poly[0])
        elif j >= len(poly) - 1:
            out.append(poly[-1])
        else:
            out.append(poly[j] + (target - cum[j]) / seg[j] * (poly[j + 1] - poly[j]))  # eq. (12)
    return np.array(out), lc


def test_material_point_tracking_matches_equations_9_to_12() -> None:
    rng = np.random.default_rng(4)
    poly = np.cumsum(rng.normal(size=(30, 2)), axis=0).astype(np.float32)
    arcs = np.array([0.0, 1.5, 7.25, 20.0, 33.3, 1000.0])
    length0 = 25.0
    fraction = arcs / length0
    out, lengths, work = np.zeros((2, len(arcs), 2), np.float32), np.zeros(2), np.zeros(len(poly))
    count, stretch, _ = K.track_shapes(poly, poly, True, fraction, length0, out, lengths, work)
    assert count == len(arcs)
    ref, lc = _track_reference(poly.astype(float), arcs, length0)
    np.testing.assert_allclose(out[0], ref, atol=1e-3)
    assert lengths[0] == pytest.approx(lc, rel=1e-6)
    assert stretch == pytest.approx(lc / length0, rel=1e-6)
    assert K.polyline_length(poly, len(poly)) == pytest.approx(lc, rel=1e-6)
    assert K.track_shapes(poly[:0], poly, True, fraction, length0, out, lengths, work)[0] == K.INVALID


def test_resample_keeps_ends_and_spacing() -> None:
    poly = np.array([[0, 0], [0, 10], [10, 10]], np.float32)
    out = np.zeros((50, 2), np.float32)
    count = K.resample_polyline(poly, 3, 3.0, out)
    assert count == 8
    np.testing.assert_allclose(out[0], poly[0])
    np.testing.assert_allclose(out[count - 1], poly[-1])
    steps = np.hypot(*np.diff(out[:count], axis=0).T)
    np.testing.assert_allclose(steps[steps > 2.8], 20 / 7, atol=1e-4)
    assert K.resample_polyline(poly, 3, 0.1, out) == K.FULL


def test_roi_contacts_counts_pixels_at_the_region_border() -> None:
    lo = np.array([2, 2, 2, 2, 2], np.int32)
    hi = np.array([6, 6, 6, 6, 6], np.int32)
    chain = np.array([[2, 2], [2, 4], [2, 6], [0, 4]], np.int32)
    assert K.count_roi_contacts(chain, 4, lo, hi, 10) == 2
    assert K.count_roi_contacts(chain, 4, lo, hi, 7) == 1


def test_trim_polyline_end_matches_reference() -> None:
    poly = np.array([[0, 0], [0, 10], [5, 10], [5, 12]], np.float32)
    for cut in (1.0, 2.0, 4.5, 16.9):
        work = poly.copy()
        count = K.trim_polyline_end(work, 4, cut)
        seg = np.hypot(*np.diff(poly, axis=0).T)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        target = cum[-1] - cut
        j = int(np.searchsorted(cum, target, side="right")) - 1
        expected = poly[j] + (target - cum[j]) / seg[j] * (poly[j + 1] - poly[j])
        np.testing.assert_allclose(work[count - 1], expected, atol=1e-5)
        assert K.polyline_length(work, count) == pytest.approx(target, abs=1e-4)
    assert K.trim_polyline_end(poly.copy(), 4, 100.0) == 0


def test_find_caps_matches_reference() -> None:
    turn = np.zeros(40, np.float32)
    turn[[3, 5, 22, 38]] = [3.0, 2.9, 2.5, 2.8]
    points = np.stack([np.arange(40, dtype=np.float32), np.zeros(40, np.float32)], axis=1)
    idx = np.zeros(2, np.int32)
    assert K.find_caps(turn, points, 40, 8, 0.0, idx) == 2
    assert idx.tolist() == [3, 22]  # 5 and 38 are within 8 steps of 3 (cyclic)
    assert K.find_caps(turn, points, 2, 1, 0.0, idx) == K.NOT_FOUND


def test_find_caps_keeps_the_ends_apart_on_a_band_walked_twice() -> None:
    # A band open at one end, traced out and back: every pixel twice, half the contour apart. Its U-turns at the
    # open end turn most, and both copies of one are far apart along the chain but at the same pixel.
    half = 40
    along = np.concatenate([np.arange(half), np.arange(half)[::-1]]).astype(np.float32)
    points = np.stack([along, np.zeros(2 * half, np.float32)], axis=1)
    points = np.concatenate([points, points])  # walked twice
    n = points.shape[0]
    turn = np.zeros(n, np.float32)
    turn[[0, 2 * half]] = np.pi  # the U-turn at the open end, both copies
    turn[[half, 3 * half]] = [2.0, 1.9]  # the band's far end (its cap), both copies
    idx = np.zeros(2, np.int32)
    assert K.find_caps(turn, points, n, n // 8, 0.0, idx) == 2
    assert idx.tolist() == [0, 2 * half]  # without a distance: the same end twice
    assert K.find_caps(turn, points, n, n // 8, 8.0, idx) == 2
    assert idx.tolist() == [0, half]
    assert K.find_caps(turn, points, n, n // 8, 100.0, idx) == 2
    assert idx.tolist() == [0, 2 * half]  # no end that far: as without the distance


def _rope_image(width_px: float, bright: bool) -> np.ndarray:
    cols = np.arange(60, dtype=float)
    coverage = np.clip(np.minimum(cols - 20.0, 20.0 + width_px - cols) + 0.5, 0, 1)
    row = 30 + 150 * coverage if bright else 200 - 150 * coverage
    image = np.tile(row, (40, 1))
    image[:5] = image[35:] = 30 if bright else 200  # the rope ends inside the image: a closed contour
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("bright", [True, False])
def test_widths_polarity_and_gradient_offset_on_a_straight_rope(bright) -> None:
    width_px = 5.0
    image = _rope_image(width_px, bright)
    height, width = image.shape
    lo, hi = np.zeros(height, np.int32), np.full(height, width - 1, np.int32)
    bufs = [np.zeros((height, width), np.float32) for _ in range(5)]
    edges = np.zeros((height, width), np.uint8)
    K.detect_edges(image, np.array([0.25, 0.5, 0.25], np.float32), lo, hi, 20.0, 60.0,
                   np.zeros((4, height), np.int32), *bufs, edges, np.zeros(height * width, np.int32))  # fmt: skip
    mag, gx, gy = bufs[4], bufs[2], bufs[3]
    labels, stack, start = (
        np.zeros((height, width), np.int32),
        np.zeros(height * width, np.int32),
        np.zeros(2, np.int32),
    )
    K.keep_largest_component(edges, lo, hi, 4, labels, stack, start)
    chain = np.zeros((4000, 2), np.int32)
    n = K.trace_contour(edges, lo, hi, start[0], start[1], chain, np.zeros(4000, np.int32))
    points = np.zeros((n, 2), np.float32)
    K.refine_subpixel(mag, gx, gy, chain[:n], n, points)
    expected = 1.0 if bright else -1.0
    widths = np.zeros(n, np.float32)
    middle = (chain[:n, 0] > 10) & (chain[:n, 0] < height - 11)
    K.measure_widths(edges, lo, hi, mag, gx, gy, chain[:n], n, np.float32(-expected), 30.0, widths)
    assert np.isnan(widths[middle]).all()  # looking away from the rope finds no opposite edge
    K.measure_widths(edges, lo, hi, mag, gx, gy, chain[:n], n, np.float32(expected), 30.0, widths)
    assert np.nanmedian(widths[middle]) == pytest.approx(width_px, abs=0.15)
    # Spans ending between the two edges: the far edge lies where this frame detected nothing (its pixels would be
    # an earlier frame's), so the walks from the near edge stop at the spans' end.
    left = middle & (chain[:n, 1] < 22)
    assert left.any()
    K.measure_widths(edges, lo, np.full(height, 22, np.int32), mag, gx, gy, chain[:n], n, np.float32(expected), 30.0,
                     widths)  # fmt: skip
    assert np.isnan(widths[left]).all()
    assert K.measure_widths(edges, lo[:-1], hi, mag, gx, gy, chain[:n], n, np.float32(expected), 30.0, widths) < 0
    out = np.zeros((n, 2), np.float32)
    count = K.offset_by_gradient(points, chain[:n], n, 0, n - 1, 1, gx, gy, np.float32(expected), 5.0, 0.0, out)
    assert count == n
    centre = 20.0 + width_px / 2  # columns 20 and 25 are half covered, 21-24 fully: the axis is at 22.5
    np.testing.assert_allclose(out[:count][middle, 1], centre, atol=0.15)
    # axis_offset is the offset refine_subpixel applies
    for i in np.flatnonzero(middle)[:5]:
        dr, dc = K.axis_offset(mag, gx, gy, chain[i, 0], chain[i, 1])
        np.testing.assert_allclose(points[i], chain[i] + np.array([dr, dc]), atol=1e-5)


def _outline(corners: list[tuple[float, float]], step: float = 0.5) -> np.ndarray:
    points = []
    for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
        a_, b_ = np.array(a, float), np.array(b, float)
        k = max(1, math.ceil(np.hypot(*(b_ - a_)) / step))
        points += [a_ + (b_ - a_) * t for t in np.arange(k) / k]
    return np.array(points, np.float32)


def test_split_takes_the_corners_whose_sides_are_equally_long() -> None:
    # A band from a fixed end at (5, 0): both sides 105 px long to the corners (0, 100) and (10, 100); its end
    # edge has a kink at (2, 102.5) (a faint end breaking up), sharper than the corner before it, which makes that
    # side 3.2 px too long.
    pts = _outline([(5, 0), (0, 0), (0, 100), (2, 102.5), (10, 100), (10, 0)])
    n = len(pts)
    turn = np.zeros(n, np.float32)
    K.turning_angles(pts, n, 3, turn)
    idx = np.zeros(4, np.int32)
    dist = np.hypot(pts[:, 0] - 5.0, pts[:, 1]).astype(np.float64)
    assert split_contour(pts, turn, dist, n, 5.0, 0.0, 20.0, 4, 0.5, np.zeros(n, np.float32), idx) == 4
    np.testing.assert_allclose(pts[idx[1]], [0, 100], atol=0.6)
    np.testing.assert_allclose(pts[idx[3]], [10, 100], atol=0.6)
    # "Largest turning per side" would take the kink: it turns more than the corner of its side.
    at = [int(np.argmin(np.hypot(*(pts - p).T))) for p in ([0, 100], [2, 102.5])]
    assert turn[at[1]] > turn[at[0]]
    assert split_contour(pts, turn, dist, n, 5.0, 0.0, 20.0, 4, 0.5, np.zeros(n - 1, np.float32), idx) == K.FULL
    assert split_contour(pts, turn, dist[:-1], n, 5.0, 0.0, 20.0, 4, 0.5, np.zeros(n, np.float32), idx) == K.FULL


def test_split_takes_no_dent_of_a_faint_side_for_its_corner() -> None:
    # A band from a fixed end at (5, 0) whose end tip swept outward: side A to the begin tip's corner (0, 100), the
    # band's end out to the end tip at (16, 104), the farthest point, and side B back with a dent of 1.5 px 12 px
    # from its end (a faint side's broken edge closed across its gap; simulated `lab-dark`, 240 frames, frame 98).
    # The dent is side B's sharpest turn but for the far point (which is a candidate only without other pairs), but
    # it does not turn over chords twice as long.
    pts = _outline([(5, 0), (0, 0), (0, 100), (16, 104), (10.6, 93), (12.1, 92), (10.5, 91), (10, 0)], 1.0)
    n = len(pts)
    dent = int(np.argmin(np.hypot(pts[:, 0] - 12.1, pts[:, 1] - 92.0)))
    assert _turn_at(pts, n, 3, dent) > 1.0
    assert _turn_at(pts, n, 6, dent) < 0.5 * _turn_at(pts, n, 3, dent)
    idx = np.zeros(4, np.int32)
    args = (np.int32(3), np.float32(5.0), np.float32(0.0), np.float32(20.0), np.int32(4), np.float32(0.5))
    found = K.find_segmentation_points(pts, np.int32(n), *args, np.zeros(n), np.zeros(n, np.float32),
                                       np.zeros(n, np.float32), idx)  # fmt: skip
    assert found == 4
    np.testing.assert_allclose(pts[idx[1]], [0, 100], atol=0.6)
    np.testing.assert_allclose(pts[idx[3]], [16, 104], atol=0.6)  # the far point: no other corner on side B
    # Without the dent the far point is the end's corner all the same.
    plain = _outline([(5, 0), (0, 0), (0, 100), (16, 104), (10, 0)], 1.0)
    m = len(plain)
    assert K.find_segmentation_points(plain, np.int32(m), *args, np.zeros(m), np.zeros(m, np.float32),
                                      np.zeros(m, np.float32), idx) == 4  # fmt: skip
    np.testing.assert_allclose(plain[idx[3]], [16, 104], atol=0.6)


def test_turning_angles_far_equals_turning_angles_in_the_tip_zone() -> None:
    pts = _outline([(5, 0), (0, 0), (0, 100), (2, 102.5), (10, 100), (10, 0)])
    n = len(pts)
    full = np.zeros(n, np.float32)
    far = np.full(n, -1.0, np.float32)
    K.turning_angles(pts, n, 3, full)
    dist = np.zeros(n)
    computed = turning_angles_far(pts, np.int32(n), np.int32(3), np.float32(5.0), np.float32(0.0), 20.0, dist, far)
    d = np.hypot(pts[:, 0] - 5.0, pts[:, 1])
    np.testing.assert_allclose(dist, d, rtol=1e-6)
    zone = d >= d.max() - 20.0
    needed = zone | np.roll(zone, 1) | np.roll(zone, -1)
    assert computed >= np.count_nonzero(needed)
    np.testing.assert_array_equal(far[needed], full[needed])
    assert np.all(far[~needed] == 0.0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_find_segmentation_points_equals_the_two_kernels(seed) -> None:
    # Bands with a noisy outline, a kink or not, fixed ends anywhere along the near end: the fused kernel gives
    # what `turning_angles_far` then `split_contour` give, distances and status included.
    rng = np.random.default_rng(seed)
    corners = [(5, 0), (0, 0), (0, 100), (2, 102.5), (10, 100), (10, 0)]
    if seed % 2:
        del corners[3]
    pts = _outline(corners) + rng.normal(0, 0.15, (len(_outline(corners)), 2)).astype(np.float32)
    pts = np.roll(pts, int(rng.integers(0, len(pts))), axis=0)
    n = len(pts)
    fixed = (np.float32(rng.uniform(3, 7)), np.float32(0.0))
    args = (np.int32(3), *fixed, np.float32(20.0))
    dist, turn, idx = np.zeros(n), np.zeros(n, np.float32), np.zeros(4, np.int32)
    turning_angles_far(pts, np.int32(n), *args, dist, turn)
    work = np.zeros(n, np.float32)
    expected = split_contour(pts, turn, dist, n, *fixed, np.float32(20.0), 4, 0.5, work, idx)
    dist2, turn2, idx2, work2 = (
        np.zeros(n),
        np.full(n, np.nan, np.float32),
        np.zeros(4, np.int32),
        np.zeros(n, np.float32),
    )
    got = K.find_segmentation_points(pts, np.int32(n), *args, np.int32(4), np.float32(0.5), dist2, turn2, work2, idx2)
    assert got == expected == 4
    np.testing.assert_array_equal(idx2, idx)
    if os.environ.get("NUMBA_DISABLE_JIT") == "1":
        # Plain Python rounds the float32 segment lengths of the test reference and the kernel differently
        # (~5e-8 relative); compiled, both are bit-identical.
        np.testing.assert_allclose(dist2, dist, rtol=1e-7, atol=0.0)
    else:
        np.testing.assert_array_equal(dist2, dist)
    np.testing.assert_array_equal(work2, work)
    written = ~np.isnan(turn2)
    np.testing.assert_array_equal(turn2[written], turn[written])
    assert np.all(turn[~written] == 0.0)  # only the angles nobody reads were left out
    # With its segment-length scratch: the same, for search zones from the tip's corners only to the whole band.
    for search in (np.float32(3.0), np.float32(20.0), np.float32(60.0), np.float32(200.0)):
        zone_args = (np.int32(3), *fixed, search, np.int32(4), np.float32(0.5))
        seg = np.full(n, np.nan)
        idx3, dist3, work3, turn3 = np.zeros(4, np.int32), np.zeros(n), np.zeros(n, np.float32), np.zeros(n, np.float32)
        want = K.find_segmentation_points(pts, np.int32(n), *zone_args, dist2, turn2, work2, idx2)
        assert K.find_segmentation_points_seg(pts, np.int32(n), *zone_args, dist3, turn3, work3, seg, idx3) == want
        np.testing.assert_array_equal(idx3, idx2)
        np.testing.assert_array_equal(dist3, dist2)
        np.testing.assert_array_equal(work3, work2)
        np.testing.assert_array_equal(turn3[turn3 != 0.0], turn2[turn3 != 0.0])
        assert (
            K.find_segmentation_points_seg(pts, np.int32(n), *zone_args, dist3, turn3, work3, seg[:-1], idx3) == K.FULL
        )
    short = np.zeros(n - 1)
    assert (
        K.find_segmentation_points(pts, np.int32(n), *args, np.int32(4), np.float32(0.5), short, turn2, work2, idx2)
        == K.FULL
    )
    assert (
        K.find_segmentation_points(pts, np.int32(6), *args, np.int32(4), np.float32(0.5), dist2, turn2, work2, idx2)
        == K.NOT_FOUND
    )


def test_known_length_variant_equals_the_plain_kernel() -> None:
    rng = np.random.default_rng(7)
    poly = np.cumsum(rng.normal(size=(30, 2)), axis=0).astype(np.float32)
    poly[5] = poly[4]  # a zero-length segment
    n = len(poly)
    total = K.polyline_length(poly, n)
    plain, known = np.zeros((40, 2), np.float32), np.zeros((40, 2), np.float32)
    assert K.resample_polyline(poly, n, 1.5, plain) == K.resample_polyline_of_length(poly, n, total, 1.5, known)
    np.testing.assert_array_equal(plain, known)
