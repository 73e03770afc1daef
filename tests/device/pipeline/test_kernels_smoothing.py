"""`smooth_polyline` (output smoothing of the rope centrelines) against a slow, obvious local regression."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.shared.errors import ConfigError

pytestmark = pytest.mark.kernel


def smooth_reference(poly: np.ndarray, half_width_px: float, block: int = 3, even_tolerance: float = 0.1) -> np.ndarray:
    """Per run of `block` points: the window of the middle one, its chord frame, a weighted quadratic fit by
    `np.linalg.lstsq`, every point of the run (or, outside that window, its own fit) moved across onto it.

    An evenly spaced window (centred on its point, as many points on each side, its ends within `even_tolerance`
    mean spacings of the offsets of evenly spaced points) is fitted at the positions ``o * spacing`` (o = -K..K)
    instead of the chord projections (`smooth_polyline`'s shortcut); a negative tolerance turns that off."""
    points = np.asarray(poly, dtype=np.float64)
    n = len(points)
    if n < 3 or half_width_px <= 0:
        return points.copy()
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    total = s[-1]
    half = half_width_px
    short = total <= 2 * half
    if short:
        half = 0.5 * total * (1 + 1e-6)

    spacing = total / (n - 1)

    def fit(i: int):
        """(window indices, along, normal, coefficients) of the fit for point i, or None."""
        centre = 0.5 * total if short else min(max(s[i], half), total - half)
        d = (s - centre) / half
        inside = np.flatnonzero((d >= -1 - 1e-12) & (d <= 1 + 1e-9))
        lo, hi = inside[0], inside[-1]
        chord = points[hi] - points[lo]
        if hi - lo < 2 or np.hypot(*chord) <= 0.5 * (s[hi] - s[lo]):
            return inside, None
        along = chord / np.hypot(*chord)
        normal = np.array([-along[1], along[0]])
        rel = points[lo : hi + 1] - points[i]
        x, y = rel @ along / half, rel @ normal
        w = np.sqrt(1.0 - 0.9 * np.minimum(d[lo : hi + 1] ** 2, 1.0))
        k = i - lo
        if (
            not short
            and centre == s[i]
            and hi - i == k >= 2
            and abs(s[hi] - s[i] - k * spacing) <= even_tolerance * spacing
            and abs(s[i] - s[lo] - k * spacing) <= even_tolerance * spacing
        ):
            x = np.arange(-k, k + 1) * spacing / half
            w = np.sqrt(1.0 - 0.9 * x**2)
        distinct = len(np.unique(np.round(x, 9)))
        if distinct < 2:
            return inside, None
        degree = min(2, distinct - 1)
        basis = np.stack([x**k for k in range(degree + 1)], axis=1)
        return inside, (along, normal, np.linalg.lstsq(basis * w[:, None], y * w, rcond=None)[0])

    out = points.copy()
    for first in range(0, n, block):
        run = range(first, min(first + block, n))
        middle = (run[0] + run[-1]) // 2
        window, model = fit(middle)
        for k in run:
            i, this = (middle, model) if k in window else (k, fit(k)[1])
            if this is None:
                continue
            along, normal, coef = this
            own = points[k] - points[i]
            x = own @ along / half
            out[k] = points[k] + (sum(c * x**p for p, c in enumerate(coef)) - own @ normal) * normal
    return out


def _smooth(poly: np.ndarray, half_width_px: float) -> np.ndarray:
    poly = np.ascontiguousarray(poly, dtype=np.float32)
    out = np.full((len(poly) + 3, 2), np.nan, np.float32)
    arc = np.zeros(len(poly) + 1)
    assert K.smooth_polyline(poly, np.int32(len(poly)), np.float32(half_width_px), arc, out) == len(poly)
    if len(poly):
        np.testing.assert_allclose(
            arc[: len(poly)],
            np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poly.astype(np.float64), axis=0).T))]),
            atol=1e-9,
        )
    assert np.all(np.isnan(out[len(poly) :]))  # nothing written beyond n
    return out[: len(poly)].astype(np.float64)


def _arc(radius_px: float, length_px: float, step_px: float, rng: np.random.Generator | None = None, noise=0.0):
    """Points (row, col) along a circular arc, unevenly spaced, optionally with Gaussian noise."""
    s = np.cumsum(np.concatenate([[0.0], step_px * (0.6 + 0.8 * (rng or np.random.default_rng(0)).random(400))]))
    s = s[s <= length_px]
    angle = s / radius_px
    poly = np.stack([100 + radius_px * np.sin(angle), 50 + radius_px * (1 - np.cos(angle))], axis=1)
    if rng is not None and noise:
        poly += rng.normal(0, noise, poly.shape)
    return poly


@pytest.mark.parametrize(
    ("length_px", "half_width_px", "noise"),
    [(300.0, 24.0, 0.1), (300.0, 8.0, 0.3), (40.0, 24.0, 0.1), (120.0, 5.0, 0.0), (6.0, 4.0, 0.05)],
)
def test_matches_the_reference(length_px, half_width_px, noise) -> None:
    rng = np.random.default_rng(int(length_px + half_width_px))
    poly = _arc(150.0, length_px, 1.0, rng, noise).astype(np.float32)
    np.testing.assert_allclose(_smooth(poly, half_width_px), smooth_reference(poly, half_width_px), atol=2e-4)


def _even_arc(radius_px: float, length_px: float, step_px: float, rng: np.random.Generator, noise: float):
    """Points (row, col) `step_px` apart along a circular arc (as `resample_polyline` leaves them), with noise."""
    angle = np.arange(0.0, length_px, step_px) / radius_px
    poly = np.stack([100 + radius_px * np.sin(angle), 50 + radius_px * (1 - np.cos(angle))], axis=1)
    return poly + rng.normal(0, noise, poly.shape)


@pytest.mark.parametrize(("radius_px", "noise"), [(150.0, 0.1), (60.0, 0.1), (400.0, 0.0)])
def test_evenly_spaced_windows_take_the_shortcut(radius_px, noise) -> None:
    # Resampled centrelines are evenly spaced: their inner windows are fitted at the even positions (the moments
    # are the same for all of them), which is the reference with the shortcut, close to the fit at the chord
    # projections (the two differ in how the noise and the bend project).
    poly = _even_arc(radius_px, 240.0, 2.0, np.random.default_rng(3), noise).astype(np.float32)
    ours = _smooth(poly, 24.0)
    np.testing.assert_allclose(ours, smooth_reference(poly, 24.0), atol=2e-4)
    exact = smooth_reference(poly, 24.0, even_tolerance=-1.0)
    assert 1e-6 < np.max(np.abs(ours - exact)) < 0.03  # the shortcut was taken, and it changes little


@pytest.mark.parametrize("radius_px", [40.0, 60.0, 100.0])
def test_the_shortcut_flattens_a_bend_less(radius_px) -> None:
    # On a circle the offset is a quadratic plus x**4 / (24 R**3) in the arc offset, plus x**4 / (8 R**3) in the
    # chord projection: the even positions leave a third of the flattening (inner points; the ends share a path).
    poly = _even_arc(radius_px, 240.0, 2.0, np.random.default_rng(3), 0.0).astype(np.float32)

    def flattening(points: np.ndarray) -> float:
        return float(
            np.max(np.abs(np.hypot(points[:, 0] - 100.0, points[:, 1] - 50.0 - radius_px) - radius_px)[15:-15])
        )

    ours = flattening(_smooth(poly, 24.0))
    assert ours < 0.5 * flattening(smooth_reference(poly, 24.0, even_tolerance=-1.0))
    assert ours < 24.0**4 / (24.0 * radius_px**3)


def test_degenerate_windows_keep_long_segments_and_duplicates() -> None:
    # A long last segment (the tip moved out by the band's extent) and repeated points: the windows near them hold
    # one or two distinct positions, so the fit falls back to a line or leaves the point.
    poly = np.array([[0, 0], [1, 0.2], [1, 0.2], [2, 0.1], [3, 0.3], [60, 1.0]], np.float32)
    ours = _smooth(poly, 4.0)
    np.testing.assert_allclose(ours, smooth_reference(poly, 4.0), atol=2e-4)
    np.testing.assert_allclose(ours[-1], poly[-1], atol=1e-4)  # the far end stays where it was measured


def test_a_hairpin_tighter_than_the_window_is_left_alone() -> None:
    angle = np.linspace(0, 1.8 * np.pi, 60)
    poly = np.stack([5 * np.cos(angle), 5 * np.sin(angle)], axis=1).astype(np.float32)  # 56 px around r = 5 px
    np.testing.assert_array_equal(_smooth(poly, 24.0), poly)


@pytest.mark.parametrize("n", [0, 1, 2])
def test_short_polylines_and_zero_width_are_copied(n) -> None:
    poly = np.arange(2 * n, dtype=np.float32).reshape(n, 2)
    np.testing.assert_array_equal(_smooth(poly, 10.0), poly)
    poly = _arc(100.0, 50.0, 1.0).astype(np.float32)
    np.testing.assert_array_equal(_smooth(poly, 0.0), poly)


def test_refuses_a_small_output_buffer() -> None:
    poly = _arc(100.0, 50.0, 1.0).astype(np.float32)
    out = np.zeros((len(poly) - 1, 2), np.float32)
    assert K.smooth_polyline(poly, np.int32(len(poly)), np.float32(5.0), np.zeros(len(poly)), out) == K.INVALID
    out = np.zeros((len(poly), 2), np.float32)
    assert K.smooth_polyline(poly, np.int32(len(poly)), np.float32(5.0), np.zeros(3), out) == K.INVALID


def test_quadratics_are_reproduced_and_the_ends_are_not_pulled_in() -> None:
    # A parabola sampled unevenly: every point of a quadratic in arc length is kept (up to the arc-length vs
    # parameter difference, tiny for this gentle curve), the ends included; a moving average would pull the ends
    # inward by several pixels and flatten the bend.
    u = np.cumsum(np.concatenate([[0.0], 0.6 + 0.8 * np.random.default_rng(1).random(300)]))
    poly = np.stack([u, 2e-4 * (u - 50.0) ** 2], axis=1)
    ours = _smooth(poly, 24.0)
    assert np.max(np.hypot(*(ours - poly).T)) < 0.01
    moving_average = np.convolve(poly[:, 0], np.ones(25) / 25, mode="valid")
    assert moving_average[0] - poly[0, 0] > 5.0  # what the test would catch


def test_noise_is_removed_and_the_arc_kept() -> None:
    rng = np.random.default_rng(7)
    clean = _arc(120.0, 360.0, 1.0)
    noisy = clean + rng.normal(0, 0.1, clean.shape)
    ours = _smooth(noisy, 24.0)

    def off_circle(points: np.ndarray) -> np.ndarray:
        return np.abs(np.hypot(points[:, 0] - 100.0, points[:, 1] - 50.0 - 120.0) - 120.0)

    assert np.sqrt(np.mean(off_circle(ours) ** 2)) < 0.35 * np.sqrt(np.mean(off_circle(noisy) ** 2))
    assert off_circle(ours).max() < 0.1
    # The ends stay at the ends: their distance from the true ends is noise-sized, not a shrinkage.
    assert np.hypot(*(ours[0] - clean[0])) < 0.15
    assert np.hypot(*(ours[-1] - clean[-1])) < 0.15
    length = float(np.sum(np.hypot(*np.diff(ours, axis=0).T)))
    assert abs(length - 360.0) < 1.0


@pytest.mark.jit_only  # pipeline-level (10 s without JIT); the kernel's own tests run in plain Python
def test_config_key_and_its_effect_in_the_pipeline(rope, blurred_frames) -> None:
    frames = blurred_frames[:4]
    with pytest.raises(ConfigError, match="output_smoothing_px"):
        PipelineConfig(output_smoothing_px=-1.0)

    def roughness(smoothing_px: float) -> float:
        pipeline = Pipeline(PipelineConfig(output_smoothing_px=smoothing_px), (rope.width, rope.height))
        values = []
        for frame in frames:
            r = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
            for shape in (r.begin, r.end):
                values.append(np.abs(np.diff(shape.astype(np.float64), n=2, axis=0)).mean())
        return float(np.mean(values))

    assert roughness(24.0) < 0.5 * roughness(0.0)
    assert math.isclose(PipelineConfig().output_smoothing_px, 24.0)


@pytest.mark.jit_only  # pipeline-level (10 s without JIT); the kernel's own tests run in plain Python
def test_smooth_output_is_compact_on_the_wire(rope, blurred_frames) -> None:
    """End to end: pipeline -> FrameResult -> wire. Smooth shapes need (almost) no spline corrections, which makes
    a FrameResult less than half the bytes, and the decoded shapes still lie within 0.05 px of the device's."""
    from ropecam.device.pipeline.result import to_wire
    from ropecam.shared.protocol import ShapeHint, decode_message, encode_message, polyline_distances_px

    def stream(smoothing_px: float) -> list[int]:
        pipeline = Pipeline(PipelineConfig(output_smoothing_px=smoothing_px), (rope.width, rope.height))
        hint = ShapeHint()
        sizes = []
        for frame in blurred_frames:
            record = to_wire(pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us))
            data = encode_message(
                record, device_id=1, sequence=frame.index, t_ns=frame.t_ns, pack_options={"hint": hint}
            )
            sizes.append(len(data))
            back = decode_message(data).record
            for device, decoded in ((record.begin_px, back.begin_px), (record.end_px, back.end_px)):
                assert np.max(polyline_distances_px(device, decoded)) <= 0.05 + 1e-9
                assert np.hypot(*(device[-1] - decoded[-1])) <= 0.05 + 1e-9
        return sizes

    smooth, raw = stream(24.0), stream(0.0)
    assert np.mean(smooth) < 0.6 * np.mean(raw)
    assert np.mean(smooth) <= 170


def test_sliding_sums_over_a_long_even_polyline() -> None:
    # 500 evenly spaced points from near the image corner to ~1000 px away (the sums are taken about the first
    # point: differences of float32 coordinates that must not round): ~170 runs, the power sums slide from run to
    # run and are recomputed every `_SLIDES` runs; every point stays on the reference's fit.
    rng = np.random.default_rng(11)
    s = np.arange(500) * 2.0
    poly = np.stack([5.3 + 0.6 * s + 1e-5 * (s - 500.0) ** 2, 7.1 + 0.8 * s], axis=1)  # a gentle bend
    poly = (poly + rng.normal(0, 0.02, poly.shape)).astype(np.float32)
    np.testing.assert_allclose(_smooth(poly, 24.0), smooth_reference(poly, 24.0), atol=2e-4)
