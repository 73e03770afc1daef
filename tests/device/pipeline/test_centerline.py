"""The centreline of the blurred band (``method = "centerline"``): the side cut (`band_sides`) and the pairing
(`midline`) against slow references, and the stage end to end on flat- and round-ended synthetic ropes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticFrame
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.centerline import CenterlineExtractor
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus, Method

from .conftest import distance_to_polyline


def _arc(poly: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poly.astype(np.float64), axis=0).T))])


def _at_arc(poly: np.ndarray, arc: np.ndarray, s: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(s, arc, poly[:, 0]), np.interp(s, arc, poly[:, 1])], axis=-1)


def _midline_reference(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Slow and obvious: the point of `b` at the same fraction of its length as each vertex of `a`."""
    arc_a, arc_b = _arc(a), _arc(b)
    partner = _at_arc(b.astype(np.float64), arc_b, arc_a / arc_a[-1] * arc_b[-1])
    return 0.5 * (a + partner), np.hypot(*(a - partner).T)


def _dedupe(poly: np.ndarray) -> np.ndarray:
    keep = np.concatenate([[True], np.hypot(*np.diff(poly, axis=0).T) > 1e-6])
    return poly[keep]


def _band_sides_reference(points, i_fix, i_far, zone_px):
    """Slow and obvious: the point halfway round the contour from `i_fix`, kept within the run of points around
    `i_far` at least ``d(i_far) - zone_px`` from point `i_fix`; the two sides up to it."""
    n = len(points)
    walk = points[[(i_fix + s) % n for s in range(n + 1)]].astype(np.float64)
    arc = _arc(walk)
    far = np.hypot(*(walk - walk[0]).T) >= np.hypot(*(points[i_far] - points[i_fix])) - zone_px
    lo = hi = (i_far - i_fix) % n
    while lo - 1 > 0 and far[lo - 1]:
        lo -= 1
    while hi + 1 < n and far[hi + 1]:
        hi += 1
    half = min(max(0.5 * arc[-1], arc[lo]), arc[hi])
    end = _at_arc(walk, arc, np.array(half))
    side_a = np.vstack([walk[arc < half], end])
    side_b = np.vstack([walk[::-1][arc[::-1] > half], end])
    return end, side_a, side_b


def _wedge(length: float, half_angle: float, fixed_cap: float, step: float = 0.7) -> np.ndarray:
    """A blurred band's outline: a flat cap at the fixed end (0, 0), side A down to the track at angle
    -`half_angle`, the tip's track (an arc of radius `length` about the fixed end), side B back up; (row, col)."""
    out = []

    def line(p, q):
        count = max(1, int(np.ceil(np.hypot(*(q - p)) / step)))
        out.extend(p + (q - p) * k / count for k in range(count))

    c_a = np.array([0.0, -fixed_cap])
    c_b = np.array([0.0, fixed_cap])
    corner_a = length * np.array([np.cos(half_angle), -np.sin(half_angle)])
    corner_b = length * np.array([np.cos(half_angle), np.sin(half_angle)])
    line(np.zeros(2), c_a)
    line(c_a, corner_a)
    count = max(2, int(np.ceil(2 * half_angle * length / step)))
    for k in range(count):
        angle = -half_angle + 2 * half_angle * k / count
        out.append(length * np.array([np.cos(angle), np.sin(angle)]))
    line(corner_b, c_b)
    line(c_b, np.zeros(2))
    return np.array(out, np.float32)


@pytest.mark.kernel
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_midline_matches_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    s_a = np.sort(rng.uniform(0, 80, 50))
    s_b = np.sort(rng.uniform(0, 90, 23))
    a = np.stack([s_a, 0.1 * s_a**1.2 + rng.normal(0, 0.3, 50)], axis=1).astype(np.float32)
    b = np.stack([s_b, 6.0 + 0.2 * s_b + rng.normal(0, 0.3, 23)], axis=1).astype(np.float32)
    out = np.zeros((60, 2), np.float32)
    dist = np.zeros(60, np.float32)
    assert K.midline(a, 50, b, 23, out, dist) == 50
    mid, width = _midline_reference(a, b)
    np.testing.assert_allclose(out[:50], mid, atol=2e-3)
    np.testing.assert_allclose(dist[:50], width, atol=2e-3)
    np.testing.assert_allclose(out[49], 0.5 * (a[-1] + b[-1]), atol=1e-5)  # the shared free end, exactly


@pytest.mark.kernel
def test_midline_edge_cases() -> None:
    a = np.array([[0, 0], [0, 0], [10, 0]], np.float32)  # a repeated point
    b = np.array([[0, 4], [5, 4], [5, 4], [10, 4]], np.float32)
    out = np.zeros((3, 2), np.float32)
    dist = np.zeros(3, np.float32)
    assert K.midline(a, 3, b, 4, out, dist) == 3
    np.testing.assert_allclose(out, [[0, 2], [0, 2], [10, 2]], atol=1e-6)
    np.testing.assert_allclose(dist, 4.0, atol=1e-6)
    assert K.midline(a, 3, b[:1], 1, out, dist) == 3  # a one-point side: every pair ends there
    np.testing.assert_allclose(out[:, 1], 2.0, atol=1e-6)
    assert K.midline(a, 3, b, 0, out, dist) == 0
    assert K.midline(a, 3, b, 4, np.zeros((2, 2), np.float32), dist) == K.FULL


@pytest.mark.kernel
@pytest.mark.parametrize(("far_at", "zone_px"), [("corner_a", 30.0), ("corner_b", 30.0), ("middle", 30.0)])
def test_band_sides_cut_the_middle_of_the_far_end(far_at: str, zone_px: float) -> None:
    pts = _wedge(100.0, 0.12, 1.5)
    n = len(pts)
    d = np.hypot(*pts.T)
    on_track = np.flatnonzero(np.abs(d - 100.0) < 1e-3)
    i_far = {"corner_a": on_track[0], "corner_b": on_track[-1], "middle": on_track[len(on_track) // 2]}[far_at]
    side_a = np.zeros((n + 2, 2), np.float32)
    side_b = np.zeros((n + 2, 2), np.float32)
    na = K.band_sides(pts, n, 0, int(i_far), np.float32(zone_px), side_a, side_b)
    assert na > 0
    nb = n + 3 - na
    end, ref_a, ref_b = _band_sides_reference(pts, 0, int(i_far), zone_px)
    np.testing.assert_allclose(side_a[na - 1], end, atol=1e-3)
    np.testing.assert_allclose(side_b[nb - 1], end, atol=1e-3)
    np.testing.assert_allclose(_dedupe(side_a[:na]), _dedupe(ref_a), atol=1e-3)
    np.testing.assert_allclose(_dedupe(side_b[:nb]), _dedupe(ref_b), atol=1e-3)
    # Wherever the far point lies on the track, the cut is the track's middle (the wedge is symmetric).
    np.testing.assert_allclose(end, [100.0, 0.0], atol=0.05)


@pytest.mark.kernel
def test_band_sides_stay_at_the_far_end_with_an_appendix_on_one_side() -> None:
    pts = _wedge(100.0, 0.12, 1.5)
    # A 120 px loop out and back on side A, 40 px from the fixed end: the halfway point moves onto side B, out of
    # the far run; the cut is then the run's end nearest to it (the corner of the track on side B).
    i = int(np.argmin(np.abs(np.hypot(*pts.T) - 40.0) + 1e3 * (pts[:, 1] > 0)))
    out_and_back = np.concatenate([np.linspace(0, 60, 86), np.linspace(60, 0, 86)[1:-1]])
    loop = pts[i] + np.stack([np.zeros_like(out_and_back), -out_and_back], axis=1)
    pts = np.vstack([pts[:i], loop, pts[i:]]).astype(np.float32)
    n = len(pts)
    d = np.hypot(*pts.T)
    i_far = int(np.argmax(d))
    side_a = np.zeros((n + 2, 2), np.float32)
    side_b = np.zeros((n + 2, 2), np.float32)
    na = K.band_sides(pts, n, 0, i_far, np.float32(20.0), side_a, side_b)
    end, ref_a, _ = _band_sides_reference(pts, 0, i_far, 20.0)
    np.testing.assert_allclose(side_a[na - 1], end, atol=1e-3)
    np.testing.assert_allclose(_dedupe(side_a[:na]), _dedupe(ref_a), atol=1e-3)
    assert np.hypot(*end) >= 80.0 - 1e-3  # at the far end, not on side B


@pytest.mark.kernel
def test_band_sides_refuse_bad_input() -> None:
    pts = _wedge(50.0, 0.1, 1.5)
    n = len(pts)
    big = np.zeros((n + 2, 2), np.float32)
    i_far = int(np.argmax(np.hypot(*pts.T)))
    assert K.band_sides(pts, 3, 0, 1, np.float32(5.0), big, big.copy()) == K.NOT_FOUND
    assert K.band_sides(pts, n, 0, 0, np.float32(5.0), big, big.copy()) == K.NOT_FOUND
    assert K.band_sides(pts, n, 0, n, np.float32(5.0), big, big.copy()) == K.NOT_FOUND
    assert K.band_sides(pts, n, 0, i_far, np.float32(1e4), big, big.copy()) == K.NOT_FOUND  # no far end
    assert K.band_sides(pts, n, 0, i_far, np.float32(5.0), big[:20], big.copy()) == K.FULL


def test_extractor_refuses_bad_arguments() -> None:
    with pytest.raises(ValueError, match="capacity"):
        CenterlineExtractor(4)
    with pytest.raises(ValueError, match="output_step_px"):
        CenterlineExtractor(100, 0.0)
    pts = np.zeros((200, 2), np.float32)
    with pytest.raises(ValueError, match="n must be <= capacity 100"):
        CenterlineExtractor(100).extract(pts, 150, 0, 10)
    assert CenterlineExtractor(100).extract(pts, 5, 0, 3) is None


def _ideal_midline(frame: SyntheticFrame) -> np.ndarray:
    """The middle of the band: the true shapes at the two instants paired by arc length, (u, v)."""
    b, e = frame.begin_uv, frame.end_uv
    s = np.linspace(0.0, 1.0, 400)
    return 0.5 * (_at_arc(b, _arc(b), s * _arc(b)[-1]) + _at_arc(e, _arc(e), s * _arc(e)[-1]))


@pytest.mark.parametrize("rope_end", ["flat", "round"])
def test_centerline_is_the_middle_of_the_band_on_flat_and_round_ends(fast_rope, fast_frames, rope_end) -> None:
    # Before the band's far end was cut at its middle, the centreline ended at the contour point farthest from
    # the fixed end, anywhere on the tip's track: up to 3.7 px from its middle here (half the sweep is 6 px).
    frames = fast_frames[:4] if rope_end == "flat" else list(replace(fast_rope, rope_end="round").frames(4))
    radius = 0.5 * fast_rope.diameter_px
    pipeline = Pipeline(PipelineConfig(method="centerline"), (fast_rope.width, fast_rope.height))
    for frame in frames:
        r = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
        # The first frame of a rope already swinging is measured about a fixed end only guessed (`fixed_end_guess`);
        # the next one confirms it (the tip moved, the fixed end did not).
        assert r.status is FrameStatus.OK or (frame.index == 0 and r.reason == "fixed_end_guess"), r.message
        assert r.method is Method.CENTERLINE
        assert r.begin is r.end
        ours = r.begin[:, ::-1].astype(np.float64)
        ideal = _ideal_midline(frame)
        sweep = float(np.hypot(*(frame.tip_begin_uv - frame.tip_end_uv)))
        assert sweep > 10.0  # a wide band: the far end's middle is far from both tips
        # The whole rope, along the middle of the band ...
        assert distance_to_polyline(ours, ideal).mean() < 0.1
        assert distance_to_polyline(ideal[::10], ours).mean() < 0.15
        # ... to the middle of the tip's track (a round end's cap lies a radius beyond the end of the axis).
        tip_error = float(np.hypot(*(ours[-1] - ideal[-1])))
        assert tip_error < (0.6 if rope_end == "flat" else radius + 0.3), tip_error


def test_centerline_is_sub_pixel_on_a_short_exposure(fast_rope) -> None:
    rope = replace(fast_rope, exposure_us=1000)
    pipeline = Pipeline(PipelineConfig(method="centerline"), (rope.width, rope.height))
    for frame in rope.frames(2):
        r = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
        assert r.status is FrameStatus.OK
        ours = r.begin[:, ::-1].astype(np.float64)
        for true in (frame.begin_uv, frame.end_uv):
            assert (
                distance_to_polyline(_at_arc(true, _arc(true), np.linspace(0, _arc(true)[-1], 100)), ours).mean() < 0.5
            )
            assert np.hypot(*(ours[-1] - true[-1])) < 1.0
