"""The compact shape codec: the tolerance holds on every input, sizes on the rig scenario, the kernel is right."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.host.sim.rig_polylines import rig_frames
from ropecam.host.sim.stream import rig_frame_results
from ropecam.shared.errors import ConfigError, ProtocolError
from ropecam.shared.protocol import ShapeCodecConfig, ShapeHint, decode_message, encode_message
from ropecam.shared.protocol._kernels import distances_to_polyline, fit_bspline, sample_bspline
from ropecam.shared.protocol.bytecodec import ByteReader
from ropecam.shared.protocol.examples import arc_polyline
from ropecam.shared.protocol.shapes import ShapeKind, decode_shape, encode_shape, polyline_distances_px

pytestmark = pytest.mark.kernel


def _reference_distances(points: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Slow, obvious: distance of every point to every segment, minimum."""
    a, b = curve[:-1], curve[1:]
    out = []
    for p in points:
        d = b - a
        length2 = np.einsum("ij,ij->i", d, d)
        s = np.clip(np.einsum("ij,ij->i", p - a, d) / np.where(length2 > 0, length2, 1), 0, 1)
        out.append(np.min(np.hypot(*(p - a - s[:, None] * d).T)))
    return np.array(out)


def _reference_basis(t: np.ndarray, m: int) -> np.ndarray:
    """Slow, obvious Cox-de Boor recursion on the clamped uniform knots, shape (len(t), m)."""
    p = min(3, m - 1)
    knots = np.concatenate([np.zeros(p + 1), np.linspace(0, 1, m - p + 1)[1:-1], np.ones(p + 1)])

    def basis(i: int, k: int, x: float) -> float:
        if k == 0:
            if knots[i] <= x < knots[i + 1] or (x == 1.0 and knots[i] < 1.0 == knots[i + 1]):
                return 1.0
            return 0.0
        total = 0.0
        if knots[i + k] > knots[i]:
            total += (x - knots[i]) / (knots[i + k] - knots[i]) * basis(i, k - 1, x)
        if knots[i + k + 1] > knots[i + 1]:
            total += (knots[i + k + 1] - x) / (knots[i + k + 1] - knots[i + 1]) * basis(i + 1, k - 1, x)
        return total

    return np.array([[basis(i, p, float(x)) for i in range(m)] for x in t])


@pytest.mark.parametrize("m", [2, 3, 4, 7, 12])
def test_bspline_kernels_match_the_reference(m: int) -> None:
    rng = np.random.default_rng(m)
    points = np.cumsum(rng.normal(0, 1, (80, 2)), axis=0)
    t = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0, 1, 78)]))
    reference_basis = _reference_basis(t, m)
    reference, *_ = np.linalg.lstsq(reference_basis, points, rcond=None)
    control = np.empty((m, 2))
    assert fit_bspline(points, t, m, np.empty(4), np.empty((m, m)), control) == m
    np.testing.assert_allclose(control, reference, atol=1e-9)
    samples = np.empty((33, 2))
    assert sample_bspline(control, np.empty(4), samples) == 33
    np.testing.assert_allclose(samples, _reference_basis(np.linspace(0, 1, 33), m) @ control, atol=1e-9)
    # Too few points to determine the control points: a status, not a crash.
    assert fit_bspline(points[:2], t[[0, -1]], 8, np.empty(4), np.empty((8, 8)), np.empty((8, 2))) < 0


def _round_trip(points: np.ndarray | None, config: ShapeCodecConfig, origin=(0.0, 0.0)):
    encoded = encode_shape(points, config, origin)
    decoded, _ = decode_shape(ByteReader(encoded.data), origin)
    return encoded, decoded


def test_kernel_matches_brute_force_reference() -> None:
    rng = np.random.default_rng(3)
    curve = arc_polyline((10.0, 20.0), 150.0, 0.3, 0.004)
    points = curve + rng.normal(0, 0.2, curve.shape)
    t = np.linspace(0, 1, len(points))
    out = np.empty(len(points))
    assert distances_to_polyline(points, t, curve, 400, out) == len(points)
    np.testing.assert_allclose(out, _reference_distances(points, curve), atol=1e-12)
    assert distances_to_polyline(points, t[:-1], curve, 4, out) < 0  # inconsistent lengths: INVALID


def test_polyline_distances_is_local_but_exact_for_matching_curves() -> None:
    curve = arc_polyline((0.0, 0.0), 300.0, 1.0, -0.003)
    points = curve[::3] + 0.01
    np.testing.assert_allclose(polyline_distances_px(points, curve), _reference_distances(points, curve), atol=1e-12)


@pytest.mark.parametrize("noise", ["uniform", "gaussian", "none"])
def test_rig_shapes_stay_within_tolerance(noise: str) -> None:
    config = ShapeCodecConfig()
    for frame in rig_frames(12, seed=5, noise=noise)[::3]:
        begin = encode_shape(frame.begin_px, config, frame.fixed_end_px)
        end = encode_shape(frame.end_px, config, frame.fixed_end_px, reference=begin)
        reader = ByteReader(begin.data + end.data)
        begin_px, begin_q = decode_shape(reader, frame.fixed_end_px)
        end_px, _ = decode_shape(reader, frame.fixed_end_px, begin_q)
        assert reader.remaining == 0
        for device, decoded in ((frame.begin_px, begin_px), (frame.end_px, end_px)):
            # Independent of the codec's own (windowed) check: every point against every segment.
            assert np.max(_reference_distances(device, decoded)) <= 0.05 + 1e-9
            assert np.hypot(*(device[0] - decoded[0])) <= 0.05 and np.hypot(*(device[-1] - decoded[-1])) <= 0.05
        assert begin.kind is ShapeKind.SPLINE
        if noise == "gaussian":  # ~1 % of the points stray beyond 0.05 px and need corrections
            assert len(begin.data) + len(end.data) < 160
        else:
            assert end.kind is ShapeKind.SPLINE_RELATIVE
            assert len(begin.data) + len(end.data) < 60


def test_tighter_tolerance_holds_and_costs_more_bytes(shape_error) -> None:
    frame = rig_frames(1, seed=2)[0]
    loose, _ = _round_trip(frame.begin_px, ShapeCodecConfig(tolerance_px=0.05))
    tight, decoded_tight = _round_trip(frame.begin_px, ShapeCodecConfig(tolerance_px=0.02, quantum_shift=8))
    assert shape_error(frame.begin_px, decoded_tight) <= 0.02 + 1e-9
    assert len(tight.data) > len(loose.data)


def test_kinked_and_random_polylines_still_meet_the_bound(shape_error) -> None:
    rng = np.random.default_rng(11)
    kinked = np.vstack([arc_polyline((0.0, 0.0), 100.0, 0.0, 0.0), arc_polyline((100.0, 0.0), 100.0, 1.5, 0.0)[1:]])
    for points in (kinked, rng.uniform(0, 300, (40, 2)), rng.uniform(0, 300, (3, 2))):
        _, decoded = _round_trip(points, ShapeCodecConfig())
        assert shape_error(points, decoded) <= 0.05 + 1e-9


def test_absent_shape_and_bad_arguments() -> None:
    encoded, decoded = _round_trip(None, ShapeCodecConfig())
    assert decoded is None and encoded.data == b"\x00"
    with pytest.raises(ValueError, match="points_px"):
        encode_shape(np.zeros((1, 2)), ShapeCodecConfig())
    with pytest.raises(ValueError, match="finite"):
        encode_shape(np.array([[0.0, 1.0], [np.nan, 2.0]]), ShapeCodecConfig())
    with pytest.raises(ConfigError, match="quantum"):
        ShapeCodecConfig(tolerance_px=0.001, quantum_shift=6)


def test_relative_shape_without_reference_is_a_protocol_error() -> None:
    frame = rig_frames(1)[0]
    begin = encode_shape(frame.begin_px, ShapeCodecConfig())
    end = encode_shape(frame.end_px, ShapeCodecConfig(), reference=begin)
    assert end.kind is ShapeKind.SPLINE_RELATIVE
    with pytest.raises(ProtocolError, match="reference"):
        decode_shape(ByteReader(end.data))


def test_rig_frame_results_average_at_most_200_bytes(frames_match) -> None:
    hint = ShapeHint()
    sizes = []
    for index, record in enumerate(rig_frame_results(24, seed=9, stretch_wobble=0.002)):
        t_ns = record.exposure_end_t_ns + 2_000_000
        data = encode_message(record, device_id=1, sequence=index, t_ns=t_ns, pack_options={"hint": hint})
        sizes.append(len(data))
        frames_match(record, decode_message(data).record)
    assert np.mean(sizes) <= 200, sizes
