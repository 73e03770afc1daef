"""`anchor_start`: the polyline starts at the foot of the fixed end on its own axis (against a slow reference)."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K

pytestmark = pytest.mark.kernel

NO = np.int32(0)
"""`anchor_start`'s `through`: start at the foot (a fixed end found, not given)."""


def _reference(poly: np.ndarray, point: np.ndarray, skip: float, span: float) -> np.ndarray:
    """Obvious version: arc lengths, interpolated axis points, foot, the points from the axis point on."""
    seg = np.hypot(*np.diff(poly, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    if arc[-1] < skip + span:
        return poly
    a = np.array([np.interp(skip, arc, poly[:, 0]), np.interp(skip, arc, poly[:, 1])])
    b = np.array([np.interp(skip + span, arc, poly[:, 0]), np.interp(skip + span, arc, poly[:, 1])])
    d = (b - a) / np.hypot(*(b - a))
    t = float(np.dot(point - a, d))
    if t >= 0:
        return poly
    kept = poly[arc >= skip] if skip > 0 else poly[1:]
    head = [a + t * d] + ([a] if np.hypot(*(kept[0] - a)) > 1e-6 else [])
    return np.vstack([np.array(head), kept])


@pytest.mark.parametrize("skip", [0.0, 2.5, 4.0])
def test_anchor_start_matches_reference(skip: float) -> None:
    rng = np.random.default_rng(3)
    s = np.arange(0.0, 60.0, 1.0)
    poly = np.stack([10 + 0.8 * s + 0.004 * s**2, 5 + 0.6 * s], axis=1) + rng.normal(0, 0.05, (s.size, 2))
    poly = poly.astype(np.float32)
    point = np.array([10 - 0.8 * 1.2, 5 - 0.6 * 1.2], np.float32)  # 1.2 px before the start, on the axis
    expected = _reference(poly.astype(np.float64), point.astype(np.float64), skip, 12.0)
    work = np.zeros((len(poly) + 2, 2), np.float32)  # a spare row: the start may need one more point
    work[: len(poly)] = poly
    count = K.anchor_start(work, np.int32(len(poly)), point[0], point[1], np.float32(skip), np.float32(12.0), NO)
    assert count == len(expected)
    np.testing.assert_allclose(work[:count], expected, atol=1e-4)


def test_the_foot_of_a_point_on_a_straight_axis_is_the_point() -> None:
    s = np.arange(0.0, 40.0, 0.7)
    poly = np.zeros((s.size + 4, 2), np.float32)  # spare rows: the start may need one more point
    poly[: s.size] = np.stack([3 + 0.6 * s, 7 - 0.8 * s], axis=1)
    count = K.anchor_start(poly, np.int32(s.size), np.float32(3 - 0.6 * 0.9), np.float32(7 + 0.8 * 0.9),
                           np.float32(0.0), np.float32(10.0), NO)  # fmt: skip
    assert count == s.size + 1
    np.testing.assert_allclose(poly[0], [3 - 0.6 * 0.9, 7 + 0.8 * 0.9], atol=1e-5)
    np.testing.assert_allclose(poly[1:count], np.stack([3 + 0.6 * s, 7 - 0.8 * s], axis=1), atol=1e-5)


def test_anchor_start_leaves_short_or_forward_cases_alone() -> None:
    poly = np.stack([np.arange(10.0), np.zeros(10)], axis=1).astype(np.float32)
    work = poly.copy()
    assert (
        K.anchor_start(work, np.int32(10), np.float32(-1.0), np.float32(0.0), np.float32(2.0), np.float32(20.0), NO)
        == 10
    )
    np.testing.assert_array_equal(work, poly)  # too short for the axis span
    assert (
        K.anchor_start(work, np.int32(10), np.float32(5.0), np.float32(0.0), np.float32(1.0), np.float32(3.0), NO) == 10
    )
    np.testing.assert_array_equal(work, poly)  # the point lies beyond the start: nothing to extend


def test_a_given_fixed_end_starts_the_polyline_at_itself() -> None:
    # A rope leaving a clamp that hides its first 20 px: its visible part's fitted axis is off by 3 degrees, so
    # its foot misses the given fixed end by about 1 px; the polyline starts at the fixed end itself.
    s = np.arange(0.0, 60.0, 1.0)
    angle = np.radians(3.0)
    direction = np.array([np.cos(angle), np.sin(angle)])
    poly = np.zeros((s.size + 2, 2), np.float32)
    poly[: s.size] = np.array([20.0, 0.0]) + (s[:, None] + 20.0) * direction[None, :] - 20.0 * direction
    point = np.array([0.0, 0.0], np.float32)
    found = poly.copy()
    count_found = K.anchor_start(found, np.int32(s.size), point[0], point[1], np.float32(2.0), np.float32(16.0), NO)
    foot_miss = float(np.hypot(*found[0]))
    assert foot_miss > 0.9
    given = poly.copy()
    count = K.anchor_start(given, np.int32(s.size), point[0], point[1], np.float32(2.0), np.float32(16.0),
                           np.int32(1))  # fmt: skip
    assert count == count_found
    np.testing.assert_allclose(given[0], point, atol=1e-6)
    np.testing.assert_array_equal(given[1:count], found[1:count])  # the rest as before
