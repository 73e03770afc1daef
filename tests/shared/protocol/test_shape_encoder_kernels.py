"""The shape encoder's kernels against slow, obvious references: fit-and-correct, byte counts, the body writer."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.shared.errors import ProtocolError
from ropecam.shared.jit import KernelStatus
from ropecam.shared.protocol._kernels import (
    apply_corrections,
    bspline_sample_table,
    chain_bytes,
    fit_bspline,
    fit_spline_with_corrections,
    fit_work_size,
    read_chain,
    relative_positions,
    sample_bspline,
    sample_with_table,
    svarint_bytes,
    uvarint_bytes,
    write_spline_body,
)
from ropecam.shared.protocol._kernels.spline import _basis_at, _cubic_basis, _knot
from ropecam.shared.protocol.bytecodec import ByteReader, ByteWriter
from ropecam.shared.protocol.examples import arc_polyline
from ropecam.shared.protocol.shapes import ShapeCodecConfig, decode_shape, encode_shape

pytestmark = pytest.mark.kernel


def _segment_distances(points: np.ndarray, curve: np.ndarray, t: np.ndarray, half_window: int) -> np.ndarray:
    """Distance of each point to the curve's segments starting within `half_window` of round(t * (m - 1))."""
    m = len(curve)
    out = np.empty(len(points))
    for i, p in enumerate(points):
        centre = int(min(1.0, max(0.0, t[i])) * (m - 1) + 0.5)
        best = np.inf
        for j in range(max(0, centre - half_window), min(m - 2, centre + half_window) + 1):
            a, d = curve[j], curve[j + 1] - curve[j]
            length2 = d @ d
            s = 0.0 if length2 == 0 else min(1.0, max(0.0, (p - a) @ d / length2))
            best = min(best, float(np.hypot(*(p - a - s * d))))
        out[i] = best
    return out


def _reference_fit_and_correct(points, t, m, shift, tolerance, half_window, rounds=8):
    """The documented procedure, step by step in NumPy (kernels only for the fit and the samples, tested
    elsewhere against their own references)."""
    scale = float(1 << shift)
    control = np.empty((m, 2))
    assert fit_bspline(points, t, m, np.empty(4), np.empty((m, m)), control) == m
    control_q = np.rint(control * scale).astype(np.int64)
    samples = np.empty((len(points), 2))
    sample_bspline(np.ascontiguousarray(control_q / scale), np.empty(4), samples)
    decoded = samples.copy()
    offsets = np.zeros((len(points), 2), dtype=np.int64)
    owner: dict[int, int] = {}
    for _ in range(rounds):
        distance = _segment_distances(points, decoded, t, half_window)
        distance[0] = max(distance[0], np.hypot(*(points[0] - decoded[0])))
        distance[-1] = max(distance[-1], np.hypot(*(points[-1] - decoded[-1])))
        bad = np.flatnonzero(distance > tolerance)
        if len(bad) == 0:
            index = np.flatnonzero(np.any(offsets != 0, axis=1))
            return control_q, index, offsets[index], float(distance.max())
        for i in bad:
            position = min(1.0, max(0.0, t[i])) * (len(points) - 1)
            target = int(np.rint(position))
            if owner.get(target, i) != i:  # taken by another point: a free neighbour, the point's side first
                near = target + 1 if position >= target else target - 1
                for other in (near, 2 * target - near):
                    if 0 <= other < len(points) and owner.get(other, i) == i:
                        target = other
                        break
            owner[target] = i
            offsets[target] = np.rint((points[i] - samples[target]) * scale).astype(np.int64)
            decoded[target] = samples[target] + offsets[target] / scale
    return None


def _call(points, m, shift=6, tolerance=0.05, half_window=3, origin_q=(0, 0)):
    n = len(points)
    t = np.empty(n)
    relative_positions(points, t)
    control_q = np.empty((m, 2), dtype=np.int64)
    index = np.empty(n, dtype=np.int64)
    offset_q = np.empty((n, 2), dtype=np.int64)
    stats = np.empty(2)
    first = np.empty(n, dtype=np.int64)
    table = np.empty((n, 4))
    bspline_sample_table(m, first, table)  # a status (negative) for m < 2: the fit below refuses such an m itself
    count = fit_spline_with_corrections(
        points, t, shift, 8, tolerance, half_window, np.array(origin_q, dtype=np.int64), first, table,
        np.empty(fit_work_size(n, m)), np.zeros(n + 1, dtype=np.int64), control_q, index, offset_q, stats,
    )  # fmt: skip
    return t, count, control_q, index[: max(count, 0)], offset_q[: max(count, 0)], stats


@pytest.mark.parametrize(("noise", "m"), [(0.0, 6), (0.02, 8), (0.03, 5), (0.05, 9), (0.2, 12)])
def test_fit_and_correct_matches_the_reference(noise, m) -> None:
    rng = np.random.default_rng(int(noise * 100) + m)
    points = arc_polyline((100.0, 40.0), 200.0, 0.4, 0.006) + rng.normal(0, noise, (201, 2))
    t, count, control_q, index, offset_q, stats = _call(points, m)
    expected = _reference_fit_and_correct(points, t, m, 6, 0.05, 3)
    if expected is None:  # heavy noise: 8 rounds of corrections are not enough, on both sides
        assert count == KernelStatus.NO_CONVERGENCE
        return
    assert count == len(expected[1])
    np.testing.assert_array_equal(control_q, expected[0])
    np.testing.assert_array_equal(index, expected[1])
    np.testing.assert_array_equal(offset_q, expected[2])
    assert stats[0] == pytest.approx(expected[3], abs=1e-12)
    # stats[1]: the bytes of the chain from the origin and of the correction list, as written.
    reference = np.zeros((1, 2), dtype=np.int64)
    body = np.empty(4096, dtype=np.uint8)
    assert stats[1] == write_spline_body(control_q, reference, index, offset_q, body)


def test_fit_and_correct_statuses() -> None:
    points = arc_polyline((0.0, 0.0), 40.0, 0.0, 0.0)
    assert _call(points[:3], 8)[1] < 0  # too few points for 8 control points: the fit's status
    rng = np.random.default_rng(0)
    wild = rng.uniform(0, 300, (200, 2))
    # Random points far from any smooth curve: corrections land on neighbouring samples of each other and can
    # take more than 8 rounds; then the kernel says so instead of returning a wrong bound.
    counts = [_call(wild, m)[1] for m in (4, 6)]
    assert all(c == KernelStatus.NO_CONVERGENCE or c > 0 for c in counts)


@pytest.mark.parametrize("value", [0, 1, 63, 64, 127, 128, 8191, 8192, 2**40, -1, -64, -65, -(2**40)])
def test_varint_byte_counts(value) -> None:
    writer = ByteWriter()
    writer.svarint(value)
    assert svarint_bytes(value) == len(writer)
    if value >= 0:
        writer = ByteWriter()
        writer.uvarint(value)
        assert uvarint_bytes(value) == len(writer)


def _reference_body(control_q, reference_q, index, offset_q) -> bytes:
    items = control_q - reference_q
    writer = ByteWriter()
    writer.svarint(int(items[0, 0]))
    writer.svarint(int(items[0, 1]))
    if len(items) > 1:
        writer.svarint(int(items[1, 0] - items[0, 0]))
        writer.svarint(int(items[1, 1] - items[0, 1]))
    for du, dv in np.diff(items, n=2, axis=0).tolist():
        writer.svarint(du)
        writer.svarint(dv)
    writer.uvarint(len(index))
    previous = -1
    for i, (du, dv) in zip(index.tolist(), offset_q.tolist(), strict=True):
        writer.uvarint(i - previous - 1)
        writer.svarint(du)
        writer.svarint(dv)
        previous = i
    return writer.getvalue()


@pytest.mark.parametrize("relative", [False, True])
def test_body_writer_and_chain_bytes_match_the_reference(relative) -> None:
    rng = np.random.default_rng(5)
    control_q = np.cumsum(rng.integers(-3000, 3000, (9, 2)), axis=0)
    reference_q = control_q + rng.integers(-40, 40, (9, 2)) if relative else np.array([[512 * 64, -7]])
    index = np.array([0, 3, 4, 150, 151, 400])
    offset_q = rng.integers(-200, 200, (6, 2))
    expected = _reference_body(control_q, reference_q, index, offset_q)
    out = np.empty(200, dtype=np.uint8)
    count = write_spline_body(control_q, reference_q, index, offset_q, out)
    assert out[:count].tobytes() == expected
    chain_only = _reference_body(control_q, reference_q, index[:0], offset_q[:0])[:-1]  # without the count byte
    assert chain_bytes(np.ascontiguousarray(control_q - reference_q)) == len(chain_only)
    assert write_spline_body(control_q, reference_q, index, offset_q, out[: len(expected) - 1]) == KernelStatus.FULL
    three_rows = np.zeros((3, 2), dtype=np.int64)  # neither one row nor one per control point
    assert write_spline_body(control_q, three_rows, index, offset_q, out) == KernelStatus.INVALID


def test_relative_positions_match_numpy() -> None:
    points = arc_polyline((3.0, 4.0), 50.0, 1.0, 0.02) + np.random.default_rng(1).normal(0, 0.1, (51, 2))
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    out = np.empty(51)
    assert relative_positions(points, out) == 51
    np.testing.assert_allclose(out, arc / arc[-1], atol=1e-15)
    same = np.zeros((4, 2))
    assert relative_positions(same, out) == 4
    np.testing.assert_allclose(out[:4], np.linspace(0, 1, 4))


def test_hint_with_many_corrections_does_not_stick() -> None:
    # A hinted count far too small for this shape (the previous frame was a straight rope): the encoder searches
    # upwards instead of sending hundreds of corrections.
    points = arc_polyline((100.0, 40.0), 400.0, 0.2, 0.01) + np.random.default_rng(2).uniform(-0.02, 0.02, (401, 2))
    hinted = encode_shape(points, ShapeCodecConfig(), control_hint=4, explore=False)
    assert hinted.corrections <= 2 and len(hinted.data) < 60
    decoded, _ = decode_shape(ByteReader(hinted.data))
    assert decoded is not None and len(decoded) == len(points)


def test_shapes_no_spline_can_carry_cost_few_fits(monkeypatch) -> None:
    # A random walk: no count converges within the correction rounds. The search gives up after a few counts and
    # sends the points raw (lossless at the quantum) instead of fitting every count up to the maximum.
    import ropecam.shared.protocol.shapes as shapes_module

    calls = []
    original = shapes_module.fit_spline_with_corrections
    monkeypatch.setattr(shapes_module, "fit_spline_with_corrections", lambda *a: (calls.append(1), original(*a))[1])
    walk = np.cumsum(np.random.default_rng(0).normal(0, 1, (300, 2)), axis=0)
    encoded = encode_shape(walk, ShapeCodecConfig(), control_hint=20, explore=False)
    assert encoded.kind.name == "RAW"
    assert len(calls) <= 6
    decoded, _ = decode_shape(ByteReader(encoded.data))
    assert np.max(np.abs(decoded - walk)) <= 1 / 128 + 1e-12


def test_chain_and_correction_readers_match_the_reference() -> None:
    rng = np.random.default_rng(8)
    control_q = np.cumsum(rng.integers(-3000, 3000, (9, 2)), axis=0)
    index = np.array([0, 3, 4, 150, 151, 199])
    offset_q = rng.integers(-200, 200, (6, 2))
    data = np.frombuffer(_reference_body(control_q, np.zeros((1, 2), np.int64), index, offset_q), dtype=np.uint8)
    limit = 65536 * 64
    items = np.empty((9, 2), dtype=np.int64)
    position = read_chain(data, 0, limit, items)
    np.testing.assert_array_equal(items, control_q)
    assert data[position] == len(index)  # the correction count follows the chain
    points = rng.normal(0, 100, (200, 2))
    expected = points.copy()
    for i, (du, dv) in zip(index, offset_q, strict=True):
        expected[i] += (du / 64.0, dv / 64.0)
    assert apply_corrections(data, position + 1, len(index), limit, 6, points) == len(data)
    np.testing.assert_array_equal(points, expected)
    # Hostile input: a status, never a read or write out of bounds.
    assert read_chain(data[:5], 0, limit, items) == KernelStatus.FULL
    assert read_chain(data, 0, 100, items) == KernelStatus.INVALID  # beyond the limit
    assert read_chain(np.full(20, 0xFF, dtype=np.uint8), 0, limit, items) == KernelStatus.INVALID  # over-long
    assert apply_corrections(data, position + 1, len(index), limit, 6, np.zeros((150, 2))) == KernelStatus.INVALID
    assert apply_corrections(data[:-1], position + 1, len(index), limit, 6, np.zeros((200, 2))) == KernelStatus.FULL


@pytest.mark.parametrize(("n", "m"), [(2, 2), (3, 3), (7, 4), (50, 6), (203, 10), (400, 17), (64, 64)])
def test_sampling_table_is_bit_identical(n, m) -> None:
    # The encoder's bound rests on sampling exactly as the decoder does: the table must not change a single bit.
    control = np.random.default_rng(n + m).uniform(-300.0, 900.0, (m, 2))
    first = np.empty(n, dtype=np.int64)
    table = np.empty((n, 4))
    assert bspline_sample_table(m, first, table) == n
    direct, tabled = np.empty((n, 2)), np.empty((n, 2))
    assert sample_bspline(control, np.empty(4), direct) == n
    assert sample_with_table(control, first, table, tabled) == n
    assert direct.tobytes() == tabled.tobytes()
    if m >= 6:  # a table of a larger m reaches past the control points: refused, not read out of bounds
        assert sample_with_table(control[: m // 2], first, table, tabled) == KernelStatus.INVALID
    assert bspline_sample_table(1, first, table) == KernelStatus.INVALID


@pytest.mark.parametrize("m", [4, 5, 9, 17, 64])
def test_unrolled_cubic_basis_is_bit_identical(m) -> None:
    # fit_bspline's cubic path must fit exactly what the generic recurrence gives (the bytes depend on it).
    generic = np.empty(4)
    segments = m - 3
    for t in np.concatenate([np.linspace(0.0, 1.0, 1001), np.random.default_rng(m).random(500), [1e-17, 1 - 1e-16]]):
        first = _basis_at(t, m, 3, generic)
        span = 3 + min(int(t * segments), segments - 1)
        assert first == span - 3
        knots = [_knot(span + k, m, 3) for k in range(-2, 4)]
        assert np.array(_cubic_basis(t, *knots)).tobytes() == generic.tobytes(), t


def test_one_call_decoder_matches_the_step_by_step_parser(monkeypatch, jit_enabled) -> None:
    # decode_shape parses a spline body in one kernel (decode_spline) and falls back to the step-by-step parser on
    # any fault: both must give the same points, and every fault the same message. In plain Python (33 s at the
    # compiled run's density) every 4th cut and flip of those is tried: still every part of the message.
    import ropecam.shared.protocol.shapes as shapes_module

    rng = np.random.default_rng(7)
    cases = []
    for k, noise in enumerate((0.0, 0.02, 0.1, 1.0)):
        n = 50 + 97 * k
        t = np.linspace(0.0, 1.0, n)
        points = np.stack([100 + 300 * t, 40 + 80 * np.sin(3 * t + k)], 1) + rng.normal(0, noise, (n, 2))
        begin = encode_shape(points, ShapeCodecConfig(), (100.0, 40.0))
        end = encode_shape(points + rng.normal(0, 0.3, (n, 2)) + 2.0, ShapeCodecConfig(), (100.0, 40.0), begin)
        cases.append(begin.data + end.data)

    def parse(data: bytes) -> list[object]:
        reader = ByteReader(data)
        try:
            begin_px, begin_q = decode_shape(reader, (100.0, 40.0))
            end_px, end_q = decode_shape(reader, (100.0, 40.0), begin_q)
        except ProtocolError as exc:
            return [str(exc)]
        return [None if a is None else a.tobytes() for a in (begin_px, begin_q, end_px, end_q)]

    sparse = 1 if jit_enabled else 4
    inputs = cases + [c[:cut] for c in cases for cut in range(1, len(c), 3 * sparse)]  # every kind of truncation
    inputs += [
        bytes(b ^ 0x55 if i == j else b for i, b in enumerate(c)) for c in cases for j in range(2, len(c), 5 * sparse)
    ]
    fast = [parse(data) for data in inputs]
    monkeypatch.setattr(shapes_module, "decode_spline", lambda *args: KernelStatus.INVALID)
    assert fast == [parse(data) for data in inputs]
