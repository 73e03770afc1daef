"""Time order, motion model and material points of a frame against slow, obvious references (lists, complex
numbers, NumPy's polynomial fit and interpolation)."""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._kernels.tracking import _predict
from ropecam.device.pipeline.motion import MotionModel
from ropecam.device.pipeline.time_order import TimeOrder
from ropecam.device.pipeline.tracking import PointTracker

pytestmark = pytest.mark.kernel


# ------------------------------------------------------------------------------------------- time order
def _fit(history: list[tuple[int, tuple[float, float]]], t: int) -> tuple[float, float]:
    """The tip at `t` from a least-squares polynomial through the samples (quadratic from four, line from two,
    mean of one), by NumPy."""
    times = np.array([s[0] for s in history], np.float64)
    tips = np.array([s[1] for s in history], np.float64)
    degree = 2 if len(history) >= 4 else min(len(history), 2) - 1
    if degree == 0:
        return float(tips[:, 0].mean()), float(tips[:, 1].mean())
    x = (times - times[-1]) / max(1, times[-1] - times[0])
    xt = (t - times[-1]) / max(1, times[-1] - times[0])
    return tuple(float(np.polyval(np.polyfit(x, tips[:, k], degree), xt)) for k in range(2))  # type: ignore[return-value]


class _ReferenceOrder:
    """The time order written plainly with a list of (t, (row, col)) samples."""

    def __init__(self) -> None:
        self.history: list[tuple[int, tuple[float, float]]] = []
        self.ordered = False
        self.rejects = 0

    def remember(self, begin: tuple[float, float], end: tuple[float, float], single: bool, t0: int, t1: int) -> None:
        if single:
            self.history.append(((t0 + t1) // 2, begin))
        else:
            self.history += [(t0, begin), (t1, end)]
        del self.history[:-6]

    def order(self, a, b, single, t0, t1, max_age):
        history = self.history
        if history and t0 - history[-1][0] > max_age:
            history.clear()
            self.ordered = False
        if single or not history:
            self.ordered = single
            self.remember(a, b, single, t0, t1)
            return 0, 1.0 if single else 0.5
        if not self.ordered:
            last = history[-2:] if len(history) >= 2 and history[-2][0] < history[-1][0] else history[-1:]
            pairs = sorted((math.dist(q, p), j, mine) for j, (_, p) in enumerate(last) for mine, q in enumerate((a, b)))
            _, j, mine = pairs[0]
            if len(last) == 2 and j == 0:
                (ta, pa), (tb, pb) = history[-2], history[-1]
                history[-2], history[-1] = (ta, pb), (tb, pa)
            d0, d1 = pairs[0][0], pairs[1][0]
            self.ordered = True
            begin, end = (a, b) if mine == 0 else (b, a)
            self.remember(begin, end, False, t0, t1)
            return mine, 0.5 + 0.5 * (d1 - d0) / (d1 + d0 + 1e-6)
        pb, pe = _fit(history, t0), _fit(history, t1)
        straight = math.dist(a, pb) ** 2 + math.dist(b, pe) ** 2
        swapped = math.dist(b, pb) ** 2 + math.dist(a, pe) ** 2
        confidence = 0.5 + 0.5 * abs(straight - swapped) / (straight + swapped + 1e-6)
        swap = 0 if straight <= swapped else 1
        last = history[-1][1]
        d_a, d_b = math.dist(a, last), math.dist(b, last)
        separation = math.dist(a, b)
        near_swap = 1 if d_b < d_a else 0
        if (
            near_swap != swap
            and confidence < K.NEAR_UNDECIDED
            and separation >= K.NEAR_MIN_SEPARATION_PX
            and abs(d_a - d_b) >= K.NEAR_DECISIVE * separation
        ):
            swap, confidence = near_swap, 0.5 + 0.5 * abs(d_a - d_b) / (d_a + d_b + 1e-6)
        pred_sweep = math.dist(pb, pe)
        mid_miss = 0.5 * math.dist((a[0] + b[0], a[1] + b[1]), (pb[0] + pe[0], pb[1] + pe[1]))
        sweep_miss = abs(math.dist(a, b) - pred_sweep)
        reach = math.dist((0.5 * (pb[0] + pe[0]), 0.5 * (pb[1] + pe[1])), history[-1][1])
        tolerance = max(3.0, 0.5 * pred_sweep, 0.25 * reach)
        odd = mid_miss > tolerance or sweep_miss > tolerance
        if odd and self.rejects < 1:
            self.rejects += 1
            return swap, 0.5 + 0.5 * (confidence - 0.5) * 0.5
        if odd:
            history.clear()
            self.ordered = False
        self.rejects = 0
        begin, end = (a, b) if swap == 0 else (b, a)
        self.remember(begin, end, False, t0, t1)
        return swap, confidence


def _flat(samples: list[tuple[int, tuple[float, float]]]) -> list[float]:
    return [v for t, (r, c) in samples for v in (t, r, c)]


def _shape(tip: tuple[float, float]) -> np.ndarray:
    return np.array([[0.0, 0.0], tip], np.float32)


def test_the_tip_prediction_matches_a_polynomial_fit() -> None:
    rng = np.random.default_rng(3)
    for count in range(1, K.HISTORY + 1):
        state = np.zeros(K.ORDER_STATE_SIZE, np.int64)
        tips = np.zeros((K.HISTORY, 2))
        times = np.sort(rng.choice(10**8, count, replace=False)).astype(np.int64)
        state[:count] = times
        state[K.ORDER_COUNT] = count
        tips[:count] = rng.normal(200.0, 50.0, (count, 2))
        t0, t1 = int(times[-1]) + 8_000_000, int(times[-1]) + 12_000_000
        out = np.array(_predict(t0, t1, state, tips, count))  # `order_shapes`' prediction of the tips
        history = [(int(t), (float(r), float(c))) for t, (r, c) in zip(times, tips[:count], strict=True)]
        expected = _fit(history, t0) + _fit(history, t1)
        np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-6)


def test_order_shapes_matches_the_reference_through_swings_gaps_and_bad_frames() -> None:
    """A tip swinging with reversals between frames, shapes handed over in random order, single shapes, failed
    splits (both tips at one corner) and gaps of several periods: every decision, confidence and remembered
    sample agrees with the plain reference."""
    rng = np.random.default_rng(11)
    order, reference = TimeOrder(), _ReferenceOrder()
    period, exposure = 33_333_333, 15_000_000
    t = 0
    for k in range(400):
        t += period * (int(rng.integers(2, 8)) if rng.random() < 0.05 else 1)
        t0, t1 = t, t + exposure

        def tip(time_ns: int) -> tuple[float, float]:
            angle = 0.9 * math.cos(2 * math.pi * time_ns * 1e-9 / 1.1)
            return (float(np.float32(200 + 300 * math.cos(angle))), float(np.float32(400 + 300 * math.sin(angle))))

        a, b = tip(t0), tip(t1)
        if rng.random() < 0.05:
            b = (a[0] + 0.5, a[1] + 0.5)
        if rng.random() < 0.5:
            a, b = b, a
        single = rng.random() < 0.05
        a = tuple(float(v) for v in np.float32(np.array(a) + rng.normal(0, 0.2, 2)))
        b = a if single else tuple(float(v) for v in np.float32(np.array(b) + rng.normal(0, 0.2, 2)))
        sa = _shape(a)
        sb = sa if single else _shape(b)
        begin, _, confidence = order.order(sa, sb, t0, t1, period)
        swap, expected_confidence = reference.order(a, b, single, t0, t1, 4 * period)
        assert (begin is sb and sa is not sb) == bool(swap), k
        assert confidence == pytest.approx(expected_confidence, abs=1e-9), k
        assert _flat(order.samples) == pytest.approx(_flat(reference.history), abs=1e-9), k
    assert order.order(sa, sb, t1, t1, period)[2] in (0.5, 1.0)  # exposure unknown: no order, nothing remembered
    assert _flat(order.samples) == pytest.approx(_flat(reference.history), abs=1e-9)


def test_a_coin_flip_of_the_fitted_path_is_decided_by_nearness() -> None:
    """A whipping tip turns across its fitted path: the fit's predicted motion (along rows) is square to this
    frame's tips (apart along columns), a coin flip, while the last sample (where the last exposure ended) lies
    decisively nearer to one of them (simulated lab-rolling, tuning seed, frames 172, 206, 212, 221, 231: the fit's
    order was wrong at confidence 0.501-0.505, nearness right)."""
    order, period, exposure = TimeOrder(), 8_403_361, 4_000_000
    for k in range(3):
        begin, end = _shape((100.0 + 10 * k, 40.0)), _shape((104.0 + 10 * k, 40.0))
        order.order(begin, end, k * period, k * period + exposure, period)
    t0 = 3 * period
    a, b = (126.3, 44.0), (125.7, 48.0)
    history = order.samples
    pb, pe = _fit(history, t0), _fit(history, t0 + exposure)
    straight = math.dist(a, pb) ** 2 + math.dist(b, pe) ** 2
    swapped = math.dist(b, pb) ** 2 + math.dist(a, pe) ** 2
    assert swapped < straight and 0.5 + 0.5 * (straight - swapped) / (straight + swapped) < K.NEAR_UNDECIDED
    sa, sb = _shape(a), _shape(b)
    begin, end, confidence = order.order(sa, sb, t0, t0 + exposure, period)
    assert begin is sa and end is sb  # a is nearer to where the last exposure ended, (124, 40)
    assert confidence > 0.5
    # A decided fit is not overruled: tips apart along the fitted motion, the nearer one given second.
    order2 = TimeOrder()
    for k in range(3):
        begin, end = _shape((100.0 + 10 * k, 40.0)), _shape((104.0 + 10 * k, 40.0))
        order2.order(begin, end, k * period, k * period + exposure, period)
    c, d = _shape((128.0, 40.0)), _shape((132.0, 40.0))
    assert order2.order(d, c, t0, t0 + exposure, period)[0] is c


def test_order_shapes_refuses_empty_shapes() -> None:
    empty = np.zeros((0, 2), np.float32)
    state, tips = np.zeros(K.ORDER_STATE_SIZE, np.int64), np.zeros((K.HISTORY, 2))
    assert K.order_shapes(empty, _shape((1.0, 1.0)), False, 0, 10, 100, state, tips)[0] == K.INVALID
    with pytest.raises(ValueError, match="cannot order"):
        TimeOrder().order(empty, empty, 0, 10, None)


def test_time_order_accepts_read_only_shapes() -> None:
    a, b = _shape((10.0, 10.0)), _shape((10.0, 20.0))
    a.flags.writeable = b.flags.writeable = False
    begin, end, confidence = TimeOrder().order(a, b, 0, 10, None)
    assert (begin is a, end is b, confidence) == (True, True, 0.5)


# ------------------------------------------------------------------------------------------- motion model
class _ReferenceMotion:
    """The motion model with complex numbers and lists (`cmath`)."""

    def __init__(self) -> None:
        self.times: list[int] = []
        self.logs: list[complex] = []
        self.sweep = 0.0
        self.exposure = 0

    def observe(self, t_mid, tip_mid, fixed, sweep, exposure):
        z = complex(tip_mid[0] - fixed[0], tip_mid[1] - fixed[1])
        if abs(z) < 1.0 or (self.times and t_mid <= self.times[-1]):
            self.times, self.logs, self.sweep, self.exposure = [], [], 0.0, 0
            if abs(z) < 1.0:
                return
        log = cmath.log(z)
        if self.logs:
            log -= 2j * math.pi * round((log.imag - self.logs[-1].imag) / (2 * math.pi))
        self.times = [*self.times, t_mid][-3:]
        self.logs = [*self.logs, log][-3:]
        self.sweep = sweep if math.isfinite(sweep) else 0.0
        self.exposure = exposure

    def predict(self, t, exposure):
        if not self.times:
            return 1.0, 0.0, 0.0
        gap = float(t + exposure // 2 - self.times[-1])
        if len(self.times) == 1 or gap <= 0:
            scale = gap / self.exposure if self.exposure > 0 and gap > 0 else 1.0
            return 1.0, 0.0, 1.3 * self.sweep * max(1.0, scale) + 1.0
        rate = (self.logs[-1] - self.logs[-2]) / (self.times[-1] - self.times[-2])
        radius = math.exp(self.logs[-1].real)
        if len(self.times) == 2:
            step = rate * gap
            uncertainty = 0.5 * abs(cmath.exp(step) - 1) * radius
        else:
            dt0, dt1 = self.times[-2] - self.times[-3], self.times[-1] - self.times[-2]
            accel = (rate - (self.logs[-2] - self.logs[-3]) / dt0) / (0.5 * (dt0 + dt1))
            step = (rate + 0.5 * dt1 * accel) * gap + 0.5 * accel * gap**2
            uncertainty = 0.3 * abs(cmath.exp(rate * gap) - 1) * radius + abs(accel) * gap**2 * radius
        if abs(step.real) >= 1.0:
            return 1.0, 0.0, 2.6 * self.sweep + 1.0
        factor = cmath.exp(step)
        return factor.real, factor.imag, uncertainty + 0.25 * self.sweep + 2.0


def test_motion_model_matches_the_reference() -> None:
    """Tips swinging about a fixed end (across the +-pi cut of the angle), time stamps that stall or go back,
    a tip on the fixed end, an implausible jump: every prediction agrees with the complex-number reference."""
    rng = np.random.default_rng(7)
    model, reference = MotionModel(), _ReferenceMotion()
    fixed = np.array([40.0, 512.0], np.float32)
    fixed_rc = (float(fixed[0]), float(fixed[1]))
    t, exposure = 0, 4_000_000
    for k in range(300):
        t += 8_403_361 if rng.random() > 0.05 else -int(rng.integers(0, 3)) * 8_403_361
        angle = math.pi + 2.5 * math.sin(t * 1e-9 * 4.0)
        radius = 1.2 if rng.random() < 0.02 else (0.3 if rng.random() < 0.02 else 400.0 * (1 + 0.01 * k % 3))
        mid = np.array([fixed[0] + radius * math.cos(angle), fixed[1] + radius * math.sin(angle)])
        sweep_dir = rng.normal(0, 4, 2)
        begin = np.array([[0, 0], mid - sweep_dir], np.float32)
        end = np.array([[0, 0], mid + sweep_dir], np.float32)
        split_sweep = float(rng.uniform(0, 10)) if rng.random() > 0.05 else math.nan
        prediction = model.predict(t, exposure)
        assert prediction == pytest.approx(reference.predict(t, exposure), rel=1e-9, abs=1e-9), k
        model.observe(begin, end, fixed, t + exposure // 2, split_sweep, exposure)
        (br, bc), (er, ec) = begin[-1].tolist(), end[-1].tolist()
        tip_mid = (0.5 * (br + er), 0.5 * (bc + ec))
        reference.observe(
            t + exposure // 2, tip_mid, fixed_rc, max(split_sweep, math.hypot(er - br, ec - bc)), exposure
        )
        assert model.frames == len(reference.times)
        assert model.sweep_px == pytest.approx(reference.sweep, rel=1e-12)
    model.clear()
    assert model.predict(t, exposure) == (1.0, 0.0, 0.0)


def test_observe_motion_refuses_empty_shapes() -> None:
    with pytest.raises(ValueError, match="cannot observe"):
        MotionModel().observe(np.zeros((0, 2), np.float32), _shape((1, 1)), np.zeros(2, np.float32), 1, 0.0, 1)


# ------------------------------------------------------------------------------------------- material points
def _reference_points(poly: np.ndarray, arcs_px: np.ndarray) -> np.ndarray:
    seg = np.hypot(*np.diff(poly.astype(np.float64), axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    return np.stack([np.interp(arcs_px, s, poly[:, k]) for k in range(2)], axis=1)


@pytest.mark.parametrize("length0_px", [None, 150.0])
def test_track_shapes_matches_interpolation_along_the_arc(length0_px) -> None:
    rng = np.random.default_rng(5)
    arc_m = (0.0, 0.1, 0.35, 0.2, 0.5, 0.6)  # one out of order: searched from the start
    tracker = PointTracker(arc_m, 0.5, length0_px, length0_frames=2)
    for k in range(6):
        shapes = []
        for _ in range(2):
            steps = rng.uniform(0.5, 3.0, int(rng.integers(20, 120)))
            angle = np.cumsum(rng.normal(0, 0.1, steps.size))
            poly = np.concatenate(
                [[[5.0, 5.0]], 5.0 + np.cumsum(np.stack([steps * np.cos(angle), steps * np.sin(angle)], 1), 0)]
            )
            shapes.append(poly.astype(np.float32))
        begin, end = shapes[0], (shapes[0] if k == 3 else shapes[1])
        points_b, stretch_b, points_e, stretch_e = tracker.track_shapes(begin, end)
        length0 = tracker.reference_length_px
        for poly, points, stretch, slot in ((begin, points_b, stretch_b, 0), (end, points_e, stretch_e, 1)):
            lc = float(np.hypot(*np.diff(poly.astype(np.float64), axis=0).T).sum())
            # (the kernel differences the float32 points in float32, as `polyline_length`)
            assert tracker.lengths_px[slot] == pytest.approx(lc, rel=1e-6)
            assert stretch == pytest.approx(tracker.lengths_px[slot] / length0, rel=1e-12)
            arcs = np.array(arc_m) / 0.5 * lc  # fraction * Lc0 * (Lc / Lc0)
            np.testing.assert_allclose(points, _reference_points(poly, np.minimum(arcs, lc)), atol=2e-3)


def test_track_shapes_refuses_empty_shapes_and_copes_with_read_only_ones() -> None:
    tracker = PointTracker((0.1,), 1.0, 10.0)
    with pytest.raises(ValueError, match="cannot track"):
        tracker.track_shapes(np.zeros((0, 2), np.float32), np.zeros((0, 2), np.float32))
    poly = np.array([[0, 0], [0, 10]], np.float32)
    poly.flags.writeable = False
    points, stretch, _, _ = tracker.track_shapes(poly, poly)
    assert points.tolist() == [[0.0, 1.0]] and stretch == 1.0
    long_poly = np.stack([np.zeros(3000), np.arange(3000)], axis=1).astype(np.float32)  # beyond the work buffer
    assert tracker.track_shapes(long_poly, poly)[1] == pytest.approx(299.9)


# ------------------------------------------------------------------------------------------- all three at once
def _motion(state: np.ndarray, log: np.ndarray) -> K.Motion:
    """The motion group of `state` and `log` (`track_frame` reads only those two)."""
    return K.Motion(state, log, np.zeros((2, 16)), np.zeros(16), np.zeros(1, K.BAND_STATE))


def test_track_frame_is_order_then_material_points_then_motion() -> None:
    """`track_frame` gives what `order_shapes`, `uncross_shapes`, `restore_tip_sweep`, `track_shapes` and
    `observe_motion` give called in turn (the
    reference here), states included, through swaps, single shapes, unknown exposures; it writes nothing when a
    size is wrong."""
    rng = np.random.default_rng(21)
    fraction = np.array([0.0, 0.25, 0.5, 1.0])
    fixed = np.array([20.0, 300.0], np.float32)
    states = [
        (np.zeros(K.ORDER_STATE_SIZE, np.int64), np.zeros((K.HISTORY, 2)), np.zeros(K.MOTION_FRAMES + 2, np.int64),
         np.zeros((K.MOTION_FRAMES + 1, 2)), np.zeros((2, 4, 2), np.float32), np.zeros(2), np.zeros(512),
         np.zeros((512, 2), np.float32), np.zeros((3, 1024, 2), np.float32))
        for _ in range(2)
    ]  # fmt: skip
    period, exposure = 8_403_361, 4_000_000
    length0 = 300.0  # the shapes' length (Lc0): `restore_tip_sweep` moves only tips whose mean length is Lc0's
    moved = 0
    for k in range(80):
        t0 = k * period
        t1 = t0 + (exposure if k % 17 else 0)
        angle = 0.6 * math.sin(k * 0.15)
        tip = np.array([20 + 300 * math.cos(angle), 300 + 300 * math.sin(angle)])
        shapes = []
        for shift in (0.0, 4.0 * math.cos(k * 0.15)):
            line = np.linspace(fixed, tip + shift, int(rng.integers(30, 90)))
            shapes.append((line + rng.normal(0, 0.1, line.shape)).astype(np.float32))
        if rng.random() < 0.5:
            shapes.reverse()
        a = shapes[0]
        b = a if k % 11 == 0 else shapes[1]
        a_ref, b_ref = a.copy(), (None if a is b else b.copy())  # track_frame may exchange stretches in place
        b_ref = a_ref if b_ref is None else b_ref
        order_state, hist_rc, motion_state, motion_log, out, lengths, work, prev_end, splice = states[0]
        got = K.track_frame(a, b, a is b, t0, t1, 4 * period, K.Order(order_state, hist_rc, prev_end, splice), fixed,
                            2.5, t1 - t0, _motion(motion_state, motion_log), length0,
                            K.Track(fraction, out, lengths, work), 3.0)  # fmt: skip
        order_state, hist_rc, motion_state, motion_log, out_ref, lengths_ref, work_ref, prev_end, splice = states[1]
        a, b = a_ref, b_ref
        if t1 > t0:
            swap, confidence = K.order_shapes(a, b, a is b, t0, t1, 4 * period, order_state, hist_rc)
        else:  # exposure unknown: no order
            swap, confidence = 0, (1.0 if a is b else 0.5)
        begin, end = (b, a) if swap else (a, b)
        if t1 > t0:
            undecided = confidence < K.NEAR_UNDECIDED
            group = K.Order(order_state, hist_rc, prev_end, splice)
            if K.uncross_shapes(begin, end, a is b, t1, 4 * period, 3.0, undecided, group) > 0 and undecided:
                count = order_state[K.ORDER_COUNT]  # the tip's stretch may have changed sides: the history follows
                if count >= 2 and order_state[count - 2] == t0 and order_state[count - 1] == t1:
                    hist_rc[count - 2] = begin[-1]
                    hist_rc[count - 1] = end[-1]
            if a is not b:
                moved += K.restore_tip_sweep(begin, end, fixed, t0, t1, 4 * period, t1 - t0, motion_state, motion_log,
                                             order_state, hist_rc, length0)  # fmt: skip
        _, stretch_begin, stretch_end = K.track_shapes(
            begin, end, a is b, fraction, length0, out_ref, lengths_ref, work_ref
        )
        K.observe_motion(begin, end, fixed, t0 + (t1 - t0) // 2, 2.5, t1 - t0, motion_state, motion_log)
        assert got == (swap, confidence, stretch_begin, stretch_end), k
        for mine, ref in zip(states[0], states[1], strict=True):
            np.testing.assert_array_equal(mine, ref)
    assert moved > 0  # the sequence includes tips the band's end put together (the shift of 4 cos(0.15 k) px)
    before = [s.copy() for s in states[0]]
    order_state, hist_rc, motion_state, motion_log, out, lengths, work, prev_end, splice = states[0]
    long_shape = np.zeros((600, 2), np.float32)  # longer than the scratch
    assert K.track_frame(long_shape, a, False, 10**9, 10**9 + 1, 4 * period,
                         K.Order(order_state, hist_rc, prev_end, splice), fixed, 2.5, 1,
                         _motion(motion_state, motion_log), 120.0, K.Track(fraction, out, lengths, work),
                         3.0)[0] == K.INVALID  # fmt: skip
    for now, then in zip(states[0], before, strict=True):
        np.testing.assert_array_equal(now, then)
