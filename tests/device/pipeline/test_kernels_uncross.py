"""`uncross_shapes`: a rope whose start and end shapes cross (a wave: the body moves one way, the tip the other)
gets each stretch between the pinches in time order from the previous frame's end shape."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.workspace import OrderBuffers

pytestmark = pytest.mark.kernel

_X = np.linspace(0.0, 100.0, 101)
"""The rope's columns (px), fixed end at 0."""
_PERIOD_NS = 8_403_361
_EXPOSURE_NS = 4_000_000


def _shape(rows: np.ndarray) -> np.ndarray:
    """The shape (row, col) with `rows` at the columns `_X`."""
    return np.stack([rows, _X], axis=1).astype(np.float32)


def _wave(step: float) -> np.ndarray:
    """Rows of the rope `step` exposures after the previous end shape (row 10 everywhere): the body (x < 60) moves
    to larger rows, the tip the other way; the fixed end does not move."""
    return 10.0 + step * (_X / 100.0) * (60.0 - _X) / 5.0


def _sides(begin: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What the split gives for that band: its two sides (the larger rows and the smaller), the tip's begin first
    (the tip's order is right, the body's is not)."""
    hi, lo = np.maximum(begin, end), np.minimum(begin, end)
    return (_shape(hi), _shape(lo)) if begin[-1] >= end[-1] else (_shape(lo), _shape(hi))


def _remember(order: OrderBuffers, shape: np.ndarray, t_end_ns: int) -> None:
    """Remember `shape` as the previous frame's end shape (what `uncross_shapes` does on every frame)."""
    assert K.uncross_shapes(shape, shape.copy(), False, t_end_ns, 4 * _PERIOD_NS, 2.0, False, order.group) == 0


def test_the_stretch_before_a_pinch_is_put_in_order_by_the_previous_end_shape() -> None:
    order = OrderBuffers.make(256)
    _remember(order, _shape(_wave(0.0)), 0)
    true_begin, true_end = _wave(1.0), _wave(2.0)
    begin, end = _sides(true_begin, true_end)
    assert np.abs(begin[:50, 0] - true_begin[:50]).max() > 0.5  # the body is the wrong way round
    flipped = K.uncross_shapes(begin, end, False, _PERIOD_NS + _EXPOSURE_NS, 4 * _PERIOD_NS, 2.0, False, order.group)
    assert flipped == 1
    # on the true shapes (compared where the exchanged points now lie: they are spread evenly along the new arc)
    np.testing.assert_allclose(begin[:, 0], np.interp(begin[:, 1], _X, true_begin), atol=0.02)
    np.testing.assert_allclose(end[:, 0], np.interp(end[:, 1], _X, true_end), atol=0.02)
    steps = np.hypot(*np.diff(begin.astype(np.float64), axis=0).T)
    assert steps.max() - steps.min() < 0.01  # spread evenly along the arc, from end to end
    assert begin[0, 1] == 0.0 and begin[-1, 1] == 100.0
    # and this frame's end shape is now the previous one
    assert order.state[K.ORDER_PREV_COUNT] == len(_X)
    np.testing.assert_array_equal(order.prev_end[: len(_X)], end)


@pytest.mark.parametrize("reading", ["floor", "dip"])
def test_a_crossing_read_above_half_a_width_is_still_a_pinch(reading: str) -> None:
    # The split's two sides read farther apart than the true shapes (paper-soft 9 / 15 ms, simulated): by a
    # constant `floor` (a still stretch read as sweeping a little; the fixed end reads as far apart), or only around
    # the crossing (the local sweep smeared along the rope). Either way the crossing reads above half a rope width
    # (1 px here) but below a width, and the body, the wrong way round, must still be put in order.
    order = OrderBuffers.make(256)
    _remember(order, _shape(_wave(0.0)), 0)
    if reading == "floor":
        true_begin, true_end = _wave(1.0), _wave(2.0)
        apart = np.full_like(_X, 1.2)
    else:
        true_begin, true_end = _wave(2.0), _wave(6.0)
        apart = 1.5 * np.exp(-0.5 * ((_X - 60.0) / 5.0) ** 2)
    begin, end = _sides(true_begin, true_end)
    outward = (np.where(begin[:, 0] >= end[:, 0], 0.5, -0.5) * apart).astype(np.float32)
    begin[:, 0] += outward
    end[:, 0] -= outward
    gap = np.hypot(*(begin[55:66] - end[55:66]).T).min()
    assert 1.15 < gap < 2.0  # read above half a width (1 px), below one
    assert np.abs(begin[:50, 0] - true_begin[:50]).max() > 1.5  # the body is the wrong way round
    flipped = K.uncross_shapes(begin, end, False, _PERIOD_NS + _EXPOSURE_NS, 4 * _PERIOD_NS, 2.0, False, order.group)
    assert flipped == 1
    tolerance = 0.5 * apart.max() + 0.1
    np.testing.assert_allclose(begin[:, 0], np.interp(begin[:, 1], _X, true_begin), atol=tolerance)
    np.testing.assert_allclose(end[:, 0], np.interp(end[:, 1], _X, true_end), atol=tolerance)


def test_a_close_stretch_between_two_crossings_takes_its_side_from_the_tips_stretch() -> None:
    # A wave with two crossings at the turn of the swing (simulated lab, tuning seed, setup-240 frames 179, 202,
    # 217): the body and the tip move one way, the stretch between them the other, and that stretch's two shapes
    # lie less than half a rope width apart on average, so nearness to the previous end shape decides nothing.
    # It lies between two crossings: the band's side that is the start shape on the tip's stretch is the end shape
    # there. Kept as the split gave it, it was the wrong way round (centreline 0.3-0.6 px off, tips right).
    order = OrderBuffers.make(256)
    _remember(order, _shape(np.full_like(_X, 10.0)), 0)
    v = np.where(_X < 40.0, 3.0 * np.sin(np.pi * _X / 40.0), 0.0)
    v = np.where((_X >= 40.0) & (_X < 60.0), -1.0 * np.sin(np.pi * (_X - 40.0) / 20.0), v)
    v = np.where(_X >= 60.0, 4.0 * (_X - 60.0) / 40.0, v)
    true_begin, true_end = 10.0 + v, 10.0 + 2.0 * v
    begin, end = _sides(true_begin, true_end)
    middle = (_X > 40.0) & (_X < 60.0)
    assert np.abs(begin[middle, 0] - true_begin[middle]).max() > 0.9  # the middle is the wrong way round
    assert np.abs(begin[~middle, 0] - true_begin[~middle]).max() < 1e-5  # the rest is right
    assert np.abs(true_end - true_begin)[middle].mean() < 0.5 * 2.0  # too close for nearness
    flipped = K.uncross_shapes(begin, end, False, _PERIOD_NS + _EXPOSURE_NS, 4 * _PERIOD_NS, 2.0, False, order.group)
    assert flipped == 1
    np.testing.assert_allclose(begin[:, 0], np.interp(begin[:, 1], _X, true_begin), atol=0.05)
    np.testing.assert_allclose(end[:, 0], np.interp(end[:, 1], _X, true_end), atol=0.05)


@pytest.mark.parametrize("undecided", [False, True])
def test_the_tips_stretch_follows_the_previous_end_shape_only_when_the_tips_order_was_a_coin_flip(
    undecided: bool,
) -> None:
    # Tips the band's end put together give their order by a coin flip (simulated lab, tuning seed, frames 231-232:
    # the whole body the wrong way round, centreline 4.5-5 px off, tips right): the rope's stretch from its last
    # crossing to the tip is then put in order by the previous end shape as the others are. A decided tip order
    # keeps its stretch (a tip whipping against its body, with no pinch found, would be exchanged wrongly).
    order = OrderBuffers.make(256)
    _remember(order, _shape(np.full_like(_X, 10.0)), 0)
    true_begin, true_end = 10.0 + 0.03 * _X, 10.0 + 0.06 * _X  # a rigid swing: no crossing
    begin, end = _shape(true_end), _shape(true_begin)  # the wrong way round
    flipped = K.uncross_shapes(
        begin, end, False, _PERIOD_NS + _EXPOSURE_NS, 4 * _PERIOD_NS, 2.0, undecided, order.group
    )
    assert flipped == (1 if undecided else 0)
    want_begin, want_end = (true_begin, true_end) if undecided else (true_end, true_begin)
    np.testing.assert_allclose(begin[:, 0], np.interp(begin[:, 1], _X, want_begin), atol=0.02)
    np.testing.assert_allclose(end[:, 0], np.interp(end[:, 1], _X, want_end), atol=0.02)


def test_shapes_that_do_not_cross_are_left_alone() -> None:
    order = OrderBuffers.make(256)
    _remember(order, _shape(np.full_like(_X, 10.0)), 0)
    begin = _shape(10.0 + 0.02 * _X)
    end = _shape(10.0 + 0.04 * _X)
    want_begin, want_end = begin.copy(), end.copy()
    assert K.uncross_shapes(begin, end, False, _PERIOD_NS + _EXPOSURE_NS, 4 * _PERIOD_NS, 2.0, False, order.group) == 0
    np.testing.assert_array_equal(begin, want_begin)
    np.testing.assert_array_equal(end, want_end)


@pytest.mark.parametrize("previous", ["none", "too old", "single"])
def test_without_a_recent_previous_end_shape_nothing_is_exchanged(previous: str) -> None:
    order = OrderBuffers.make(256)
    t_end = _PERIOD_NS + _EXPOSURE_NS
    if previous == "too old":
        _remember(order, _shape(_wave(0.0)), t_end - 5 * _PERIOD_NS)
    begin, end = _sides(_wave(1.0), _wave(2.0))
    want_begin, want_end = begin.copy(), end.copy()
    single = previous == "single"
    got = K.uncross_shapes(begin, begin if single else end, single, t_end, 4 * _PERIOD_NS, 2.0, False, order.group)
    assert got == (-1 if single else 0)
    np.testing.assert_array_equal(begin, want_begin)
    np.testing.assert_array_equal(end, want_end)


def test_a_shape_longer_than_the_buffers_is_not_looked_at() -> None:
    order = OrderBuffers.make(64)
    begin, end = _sides(_wave(1.0), _wave(2.0))
    assert K.uncross_shapes(begin, end, False, _PERIOD_NS, 4 * _PERIOD_NS, 2.0, False, order.group) == -1
    assert order.state[K.ORDER_PREV_COUNT] == 0  # and nothing is remembered


def test_nearest_on_finds_the_foot_on_a_segment() -> None:
    line = _shape(np.full_like(_X, 5.0))
    distance, index = K.nearest_on(8.0, 40.3, line, len(_X), 30, 50)
    assert distance == pytest.approx(3.0)
    assert index == 40.0


@numba.njit
def _nearest_on_every_hypot(r, c, poly, n, lo, hi):  # type: ignore[no-untyped-def]
    """`nearest_on` as it was written first, compiled as the kernel is (libm's hypot, whose last bit may differ
    from Python's): `math.hypot` of every segment, the reference for its bits."""
    lo = max(0, lo)
    hi = min(n - 1, hi)
    if lo >= hi:
        lo = max(0, hi - 1)
    best = math.inf
    best_i = lo
    for i in range(lo, hi):
        ar = float(poly[i, 0])
        ac = float(poly[i, 1])
        dr = float(poly[i + 1, 0]) - ar
        dc = float(poly[i + 1, 1]) - ac
        length2 = dr * dr + dc * dc
        t = 0.0
        if length2 > 0.0:
            t = min(max(((r - ar) * dr + (c - ac) * dc) / length2, 0.0), 1.0)
        d = math.hypot(r - ar - t * dr, c - ac - t * dc)
        if d < best:
            best = d
            best_i = i + 1 if t > 0.5 else i
    return best, float(best_i)


def test_nearest_on_matches_hypot_of_every_segment_bit_for_bit() -> None:
    # It orders segments by their squared distance and takes hypot only of the nearest and of near-ties: the
    # distance and index must be those of hypot on every segment, ties (a point on a polyline's axis of
    # symmetry, repeated points, a point on a vertex) included.
    rng = np.random.default_rng(11)
    walk = np.cumsum(rng.normal(0.0, 1.0, (200, 2)), axis=0).astype(np.float32)
    walk[50:53] = walk[50]  # zero-length segments
    vee = np.array([[0.0, -5.0], [5.0, 0.0], [0.0, 5.0], [5.0, 0.0], [0.0, -5.0]], np.float32)
    near = rng.integers(0, 200, 400)
    off = rng.normal(0.0, 8.0, (400, 2))
    cases = [
        (walk, float(walk[k, 0] + dr), float(walk[k, 1] + dc), int(k) - 4)
        for k, (dr, dc) in zip(near, off, strict=True)
    ]
    cases += [(walk, float(walk[k, 0]), float(walk[k, 1]), k - 3) for k in range(3, 197)]  # on a vertex
    cases += [(vee, -3.0, 0.0, 0), (vee, 0.0, 0.0, 0), (vee, 5.0, 0.0, 0), (vee, 2.5, 2.5, 0)]
    for poly, r, c, lo in cases:
        for width in (1, 8, 24):
            expected = _nearest_on_every_hypot(r, c, poly, len(poly), lo, lo + width)
            got = K.nearest_on(r, c, poly, len(poly), lo, lo + width)
            assert got == expected, (r, c, lo, width)


def test_a_rigid_swing_with_noisy_edges_is_never_exchanged() -> None:
    # A pendulum's shapes never cross: by the fixed end they lie within the edges' noise of each other, and
    # nearness to the previous end shape must not exchange such stretches (that left steps in the shapes).
    rng = np.random.default_rng(3)
    radius = np.linspace(0.0, 180.0, 91)
    for trial in range(40):
        angle = rng.uniform(0.2, 1.2)
        order = OrderBuffers.make(256)

        def line(a: float) -> np.ndarray:
            pts = np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1) + rng.normal(0.0, 0.15, (91, 2))
            return pts.astype(np.float32)

        _remember(order, line(angle - 0.02), 0)
        begin, end = line(angle), line(angle + 0.02)
        assert K.uncross_shapes(begin, end, False, _PERIOD_NS, 4 * _PERIOD_NS, 3.0, False, order.group) == 0, trial


def _body_and_tip(head: np.ndarray) -> np.ndarray:
    """A rope's motion over one exposure (rows): `head` (x < 20), then the body moving 0 -> 2.6 -> 0 px to larger
    rows up to a crossing at x = 60, and the tip moving the other way (4 px at the end)."""
    body = 25.0 * (_X / 60.0) ** 3 * (1.0 - _X / 60.0)
    return np.where(_X < 20.0, head, np.where(_X < 60.0, body, -0.1 * (_X - 60.0)))


def test_the_stretches_by_the_fixed_end_take_the_side_of_the_stretch_beyond_them() -> None:
    # By the fixed end the two shapes lie a fraction of a width apart, and the edges' noise makes pinches there
    # every few points: nearness cannot order those stretches. Without a crossing between them and the first
    # stretch nearness orders, they are the same stretch of rope and are exchanged with it (simulated `lab late
    # swing`, tuning seed, frames 8, 13-16, 28-30: the body's order restored, the first 10-30 % of the rope left
    # the wrong way round, 0.5-1.2 px off, on each of them).
    base = 25.0 * (_X / 60.0) ** 3 * (1.0 - _X / 60.0)
    ripple = 1.0 + 0.4 * np.sin(2.0 * np.pi * _X / 4.0)  # a dip every 4 points: pinches below half a width
    step = _body_and_tip(base * ripple)
    order = OrderBuffers.make(256)
    _remember(order, _shape(np.full_like(_X, 10.0)), 0)
    true_begin, true_end = 10.0 + step, 10.0 + 2.0 * step
    begin, end = _sides(true_begin, true_end)
    assert np.abs(begin[12:25, 0] - true_begin[12:25]).max() > 0.3  # the stretch by the fixed end too
    flipped = K.uncross_shapes(begin, end, False, _PERIOD_NS + _EXPOSURE_NS, 4 * _PERIOD_NS, 2.0, False, order.group)
    assert flipped >= 2
    off_b = np.abs(begin[:, 0] - np.interp(begin[:, 1], _X, true_begin))
    off_e = np.abs(end[:, 0] - np.interp(end[:, 1], _X, true_end))
    assert max(off_b[12:].max(), off_e[12:].max()) < 0.05
    # the first points, where the separation fades to the edges' noise (a dip to a third of it), are left alone
    assert max(off_b.max(), off_e.max()) <= np.abs(step[:12]).max() + 0.01


def test_a_crossing_by_the_fixed_end_keeps_the_stretch_before_it() -> None:
    # The first 20 % of the rope moves the other way (a crossing at x = 20, 0.3 px apart at most there): its
    # sides are right, only the body is the wrong way round, and the body's exchange must not be carried past
    # the crossing (simulated `lab late swing`, tuning seed, frames 10, 25, 51-52: 0.2-0.3 px off where it was).
    step = _body_and_tip(-0.3 * np.sin(np.pi * _X / 20.0))
    order = OrderBuffers.make(256)
    _remember(order, _shape(np.full_like(_X, 10.0)), 0)
    true_begin, true_end = 10.0 + step, 10.0 + 2.0 * step
    begin, end = _sides(true_begin, true_end)
    assert np.abs(begin[:19, 0] - true_begin[:19]).max() < 1e-5  # right by the fixed end
    assert np.abs(begin[25:55, 0] - true_begin[25:55]).max() > 1.0  # the body the wrong way round
    K.uncross_shapes(begin, end, False, _PERIOD_NS + _EXPOSURE_NS, 4 * _PERIOD_NS, 2.0, False, order.group)
    np.testing.assert_allclose(begin[:, 0], np.interp(begin[:, 1], _X, true_begin), atol=0.05)
    np.testing.assert_allclose(end[:, 0], np.interp(end[:, 1], _X, true_end), atol=0.05)


def test_a_single_shape_is_the_previous_shape_of_the_next_split() -> None:
    # A one-shape frame (the split's static fallback: the band's middle, the rope at mid-exposure) is remembered:
    # the next exposure's start lies nearer to it than its end (simulated `lab-rolling`, tuning seed, set up from
    # its first 2 s: frame 71, the first split after two fallbacks, had its body the wrong way round, centreline
    # 1.0 px off, reported OK).
    order = OrderBuffers.make(256)
    middle = _shape(_wave(0.0))
    assert K.uncross_shapes(middle, middle, True, 0, 4 * _PERIOD_NS, 2.0, False, order.group) == -1
    assert order.state[K.ORDER_PREV_COUNT] == len(_X)
    true_begin, true_end = _wave(1.0), _wave(2.0)
    begin, end = _sides(true_begin, true_end)
    flipped = K.uncross_shapes(begin, end, False, _PERIOD_NS + _EXPOSURE_NS, 4 * _PERIOD_NS, 2.0, False, order.group)
    assert flipped == 1
    np.testing.assert_allclose(begin[:, 0], np.interp(begin[:, 1], _X, true_begin), atol=0.02)
