"""The band prediction's measured error (`need_profile`) against a slow, obvious nearest-point search."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K

pytestmark = pytest.mark.kernel

FIXED = (20.0, 100.0)


def _outline(bend: float, n: int = 500) -> np.ndarray:
    """The closed outline of a rope hanging from FIXED (down one side, round the tip, up, round the top), bent by
    `bend` px sideways at mid-length, at ~1 px steps."""
    s = np.linspace(0.0, 1.0, 200)
    centre = np.column_stack([FIXED[0] + 160 * s, FIXED[1] + bend * np.sin(math.pi * s) + 30 * s**2])
    tip = [centre[-1] + 4 * np.array([math.sin(a), math.cos(a)]) for a in np.linspace(0, math.pi, 12)]
    top = [centre[0] + 4 * np.array([-math.sin(a), -math.cos(a)]) for a in np.linspace(0, math.pi, 12)]
    side = np.array([0.0, 4.0])
    path = np.vstack([centre + side, tip, (centre - side)[::-1], top])  # closed: steps of ~1 px all round
    steps = np.hypot(*np.diff(path, axis=0).T)
    t = np.concatenate([[0], np.cumsum(steps)])
    u = np.linspace(0, t[-1], n, endpoint=False)
    return np.column_stack([np.interp(u, t, path[:, 0]), np.interp(u, t, path[:, 1])]).astype(np.float32)


def _reference_need(moved, found, margin, bins):
    """Per bin of the nearest predicted point's s = d / d_max, the largest max(0, distance - margin) (a neighbour
    bin when the nearest point lies within 0.1 px of a bin's edge is not told apart here)."""
    d_fixed = np.hypot(moved[:, 0] - FIXED[0], moved[:, 1] - FIXED[1]).astype(np.float64)
    share = d_fixed / d_fixed.max()
    need = np.zeros(bins)
    for p in found.astype(np.float64):
        d = np.hypot(moved[:, 0] - p[0], moved[:, 1] - p[1])
        j = int(np.argmin(d))
        b = min(bins - 1, int(share[j] * bins))
        need[b] = max(need[b], d[j] - margin)
    return need


def _steady(frames: int) -> bool:
    """`need_profile`'s `steady` for a motion model of `frames` frames."""
    return frames >= K.MOTION_FRAMES - 1


@pytest.mark.parametrize("start", [0, 137])
def test_need_per_bin_matches_the_nearest_point_search(start) -> None:
    moved = _outline(0.0)
    found = np.roll(_outline(3.5, 470), start, axis=0)  # bent in the middle, another start and spacing
    bins = 12
    need = np.full((2, bins), 0.25)
    profile = np.zeros(bins)
    matched = K.need_profile(moved, len(moved), found, len(found), 3, *FIXED, 1.5, 2.0, _steady(3), need, profile)
    assert matched == len(found)
    # The walk along the chain stops at a local nearest point: never nearer than the nearest, hardly farther.
    reference = _reference_need(moved, found, 3, bins)
    assert np.all(need[0] >= reference - 1e-4) and np.all(need[0] <= reference + 0.1)
    assert need[0].max() > 0.3 and need[0][0] == 0.0  # the bend needs more than the margin, the fixed end not
    np.testing.assert_array_equal(need[1], 0.25)  # the previous frame's
    worst = [max(need[0, max(0, b - 1) : b + 2].max(), need[1, max(0, b - 1) : b + 2].max()) for b in range(bins)]
    np.testing.assert_allclose(profile, 1.5 * np.array(worst) + 2.0)


def test_no_profile_while_the_motion_model_is_young_and_bad_input() -> None:
    moved = _outline(0.0)
    found = _outline(2.0)
    need = np.zeros((2, 8))
    profile = np.zeros(8)
    assert K.need_profile(moved, len(moved), found, len(found), 4, *FIXED, 1.5, 3.0, _steady(1), need, profile) > 0
    assert np.all(np.isinf(profile))
    empty = np.zeros((0, 2), np.float32)
    assert K.need_profile(moved, len(moved), empty, 0, 4, *FIXED, 1.5, 3.0, _steady(3), need, profile) == K.INVALID
    assert K.need_profile(moved, len(moved), found, len(found), 4, *FIXED, 1.5, 3.0, _steady(3), need, np.zeros(5)) < 0


def test_invalid_found_points_are_skipped() -> None:
    """A NaN or far-off found point (a gap in the contour) is neither matched nor moves the match along the chain."""
    moved = _outline(0.0)
    found = _outline(3.5, 470)
    bad = np.insert(found, [100, 300], [[np.nan, 5.0], [1e10, 5.0]], axis=0).astype(np.float32)
    results = []
    for chain in (found, bad):
        need = np.zeros((2, 8))
        profile = np.zeros(8)
        matched = K.need_profile(moved, len(moved), chain, len(chain), 3, *FIXED, 1.5, 2.0, _steady(3), need, profile)
        results.append((matched, need[0].copy(), profile))
    assert results[0][0] == len(found) and results[1][0] == len(found)
    np.testing.assert_array_equal(results[1][1], results[0][1])
    np.testing.assert_array_equal(results[1][2], results[0][2])
