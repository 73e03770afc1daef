"""The band in one call (`band_stage`) against its steps one by one: `need_profile` on the last band's moved points,
`predict_motion`, `spans_around_chain` (each tested against its own slow reference)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K

pytestmark = pytest.mark.kernel

HEIGHT, WIDTH = 240, 200
FIXED = np.array([20.0, 100.0], np.float32)
MARGIN, GAIN, FLOOR, SHARE = 4, 1.5, 1.5, 0.04
T0_NS, PERIOD_NS, EXPOSURE_NS = 1_000_000_000, 8_400_000, 4_000_000


def _outline(angle: float, bend: float) -> np.ndarray:
    """The closed outline (~1 px steps) of a rope hanging from FIXED at `angle` (rad), bent by `bend` px."""
    s = np.linspace(0.0, 1.0, 160)
    axis = np.array([math.cos(angle), math.sin(angle)])
    normal = np.array([-axis[1], axis[0]])
    centre = FIXED + 150 * s[:, None] * axis + (bend * np.sin(math.pi * s))[:, None] * normal
    path = np.vstack([centre + 4 * normal, (centre - 4 * normal)[::-1]])
    steps = np.hypot(*np.diff(np.vstack([path, path[:1]]), axis=0).T)
    t = np.concatenate([[0], np.cumsum(steps)])
    u = np.arange(0.0, t[-1], 1.0)
    closed = np.vstack([path, path[:1]])
    return np.column_stack([np.interp(u, t, closed[:, 0]), np.interp(u, t, closed[:, 1])]).astype(np.float32)


def _motion(frames: int) -> tuple[np.ndarray, np.ndarray]:
    """A motion model that has observed `frames` frames of the rope swinging (`observe_motion`)."""
    state = np.zeros(K.MOTION_FRAMES + 2, np.int64)
    log = np.zeros((K.MOTION_FRAMES + 1, 2), np.float64)
    for k in range(frames):
        shape = np.ascontiguousarray(_outline(0.05 * k, 0.0)[:160])
        t_ns = T0_NS + k * PERIOD_NS
        K.observe_motion(shape, shape, FIXED, t_ns + EXPOSURE_NS // 2, 3.0, EXPOSURE_NS, state, log)
    return state, log


def _steps(points, measure, use_profile, predict, t_ns, state, log, need, profile, last, moved):
    """The same as `band_stage`, one kernel at a time; `last` = (fixed r, c, motion, moved points, steady)."""
    if measure:
        fr, fc, motion, n_moved, steady = last
        K.need_profile(moved, n_moved, points, len(points), MARGIN, fr, fc, GAIN, FLOOR + SHARE * motion, steady,
                       need, profile)  # fmt: skip
    rot_a, rot_b, motion = K.predict_motion(t_ns, EXPOSURE_NS, state, log) if predict else (1.0, 0.0, 0.0)
    fr, fc = (float(FIXED[0]), float(FIXED[1])) if predict else (0.0, 0.0)
    lo, hi = np.zeros(HEIGHT, np.int32), np.zeros(HEIGHT, np.int32)
    K.spans_around_chain(points, len(points), MARGIN, motion, profile if use_profile else np.zeros(0), rot_a, rot_b,
                         fr, fc, HEIGHT, WIDTH, lo, hi, moved)  # fmt: skip
    return motion, lo, hi, (fr, fc, motion, len(points), state[K.MOTION_COUNT] >= K.MOTION_FRAMES - 1)


@pytest.mark.parametrize(("frames", "predict"), [(3, True), (1, True), (3, False)])
def test_band_stage_equals_its_steps(frames, predict) -> None:
    state, log = _motion(frames)
    need = np.zeros((2, 16))
    profile = np.full(16, np.inf)
    band = np.zeros(1, K.BAND_STATE)
    moved = np.zeros((800, 2), np.float32)
    ref_need, ref_profile, ref_moved = need.copy(), profile.copy(), moved.copy()
    last = None
    for k, (bend, measure, use_profile) in enumerate([(0.0, False, False), (3.0, True, True), (6.0, True, False)]):
        points = _outline(0.05 * (frames + k), bend)
        t_ns = T0_NS + (frames + k) * PERIOD_NS
        lo, hi = np.zeros(HEIGHT, np.int32), np.full(HEIGHT, 7, np.int32)
        args = (MARGIN, HEIGHT, WIDTH, GAIN, FLOOR, SHARE, FIXED, K.Motion(state, log, need, profile, band),
                K.Band(lo, hi, moved))  # fmt: skip
        motion = K.band_stage(points, len(points), measure, use_profile, predict, t_ns, EXPOSURE_NS, *args)
        ref_motion, ref_lo, ref_hi, last = _steps(points, measure, use_profile, predict, t_ns, state, log, ref_need,
                                                  ref_profile, last, ref_moved)  # fmt: skip
        assert motion == ref_motion and (motion > 0.0) == predict, k
        np.testing.assert_array_equal(lo, ref_lo, err_msg=f"call {k}")
        np.testing.assert_array_equal(hi, ref_hi, err_msg=f"call {k}")
        np.testing.assert_array_equal(moved[: len(points)], ref_moved[: len(points)])
        np.testing.assert_array_equal(need, ref_need)
        np.testing.assert_array_equal(profile, ref_profile)
        assert band[0].tolist() == last
    assert np.all(np.isfinite(profile)) == (frames >= 2)  # measured (twice), a profile once the model is steady
    assert need[0].max() > 0.0  # the bend was not predicted
