"""Tips that move along their own axis during the exposure (#19 acc. 7): the band's end is then a ramp as long as
the sweep, both shapes' tips are read at its middle, and `restore_tip_sweep` moves them apart by the sweep of the
tips' path over the last frames."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._kernels.tip_sweep import (
    LENGTH_MISMATCH,
    restore_tip_sweep,
    shape_length,
    shift_tip,
    sweep_from_history,
    sweep_from_path,
)
from ropecam.device.pipeline._kernels.tip_sweep import MOTION_FRAMES as SWEEP_MOTION_FRAMES
from ropecam.device.pipeline.checks import ChecksConfig
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus
from ropecam.host.sim.dynamics import solve_trajectory
from ropecam.host.sim.generate import write_frameset
from ropecam.host.sim.presets import preset

FIRST_S = 0.672
"""The soft rope's whip: from 0.672 s after the release its tip moves 3-6 px along its own axis per 4 ms exposure
and 1.5 px or less across it (frames 80-88 of the 240-frame ``lab`` swing, which has the same motion)."""
FRAMES = 9


@pytest.fixture(scope="module")
def whip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`FRAMES` frames of ``rig-soft`` from `FIRST_S` (4 ms, 119 FPS), rendered in-process."""
    config = preset("rig-soft")
    config = dataclasses.replace(config, frames=FRAMES, first_exposure_s=FIRST_S)
    out = tmp_path_factory.mktemp("whip") / "set"
    write_frameset(config, solve_trajectory(config), out, 4.0)
    return out


def test_tips_moving_along_their_axis_are_moved_apart_by_the_path_sweep(whip: Path) -> None:
    frames = FrameSet(whip)
    truth = frames.truth()
    assert truth is not None
    begin_true, end_true = truth["begin_px"], truth["end_px"]
    axis = begin_true[:, -1] - begin_true[:, -4]
    axis /= np.hypot(*axis.T)[:, None]
    sweep = end_true[:, -1] - begin_true[:, -1]
    along = np.abs(np.sum(sweep * axis, axis=1))
    across = np.abs(sweep[:, 0] * axis[:, 1] - sweep[:, 1] * axis[:, 0])
    # The scene is what the test is about: from frame 3 on the tip sweeps 4-7 px along its axis and at most
    # 1.5 px across, so the band's end cannot separate the tips (read at its middle: 2-3.5 px off each).
    assert np.all(along[3:] > 4.0) and np.all(across[3:] < 1.5), (along, across)
    width, height = frames.meta["image_size"]
    pipeline = Pipeline(PipelineConfig(), (width, height))
    errors, separations = [], []
    for k, (record, image) in enumerate(frames):
        result = pipeline.process(image, record.frame, record.t_ns, record.exposure_us)
        assert result.status is FrameStatus.OK, f"frame {k}: {result.status.name} {result.message}"
        assert result.begin is not None and result.end is not None
        if k >= 3:  # the tip's path needs two frames measured before
            errors.append(np.hypot(*(result.begin[-1, ::-1] - begin_true[k, -1])))
            errors.append(np.hypot(*(result.end[-1, ::-1] - end_true[k, -1])))
            # read at the band's middle, the two tips lay within 0.5 px of each other
            separations.append(np.hypot(*(result.end[-1] - result.begin[-1])))
    assert max(errors) < 1.0, np.round(errors, 2)
    assert min(separations) > 0.8 * min(along[3:]), (np.round(separations, 2), along)


def _straight_path() -> tuple[np.ndarray, int, int, np.ndarray, np.ndarray, int, np.ndarray]:
    """A motion model whose tips' midpoint moves along +col by 2 px per ms (8 px per 4 ms exposure), on a straight
    rope along col from the fixed end (10, 50): the fixed end, the period and exposure (ns), the model's state and
    log after two frames, the third frame's start (ns), and a shape (row, col) from col 60 to 132 (72 px)."""
    fixed = np.array([10.0, 50.0], np.float32)
    period, exposure = 8_000_000, 4_000_000
    state = np.zeros(MOTION_STATE_SIZE, np.int64)
    log = np.zeros((K.MOTION_FRAMES + 1, 2))
    for k in range(2):
        mid = np.array([[10.0, 100.0 + 16.0 * k]], np.float32)
        K.observe_motion(mid, mid, fixed, k * period + exposure // 2, 8.0, exposure, state, log)
    cols = np.arange(60.0, 132.1, 2.0)
    shape = np.stack([np.full_like(cols, 10.0), cols], axis=1).astype(np.float32)
    return fixed, period, exposure, state, log, 2 * period, shape


def test_restore_tip_sweep_moves_collapsed_tips_and_their_history() -> None:
    assert SWEEP_MOTION_FRAMES == K.MOTION_FRAMES
    fixed, period, exposure, state, log, t_ns, a = _straight_path()
    b = a.copy()
    sweep = sweep_from_path(fixed, t_ns + exposure // 2, exposure, 4 * period, state, log, 10.0, 132.0)
    assert sweep == pytest.approx((0.0, 8.0), abs=1e-6)
    order_state = np.zeros(K.ORDER_STATE_SIZE, np.int64)
    hist = np.zeros((K.HISTORY, 2))
    order_state[:2] = (t_ns, t_ns + exposure)
    order_state[K.ORDER_COUNT] = 2
    # A path far beyond the last frame's sweep (2 x 1 px + 4) is no path (the model was read about another fixed
    # end): nothing moves.
    jumped = log.copy()
    jumped[K.MOTION_FRAMES, 0] = 1.0
    assert not restore_tip_sweep(a.copy(), b.copy(), fixed, t_ns, t_ns + exposure, 4 * period, exposure, state,
                                 jumped, order_state, hist, -1.0)  # fmt: skip
    assert restore_tip_sweep(a, b, fixed, t_ns, t_ns + exposure, 4 * period, exposure, state, log, order_state, hist,
                             72.0)  # fmt: skip
    assert a[-1].tolist() == pytest.approx([10.0, 128.0]) and b[-1].tolist() == pytest.approx([10.0, 136.0])
    assert hist[:2].ravel().tolist() == pytest.approx([10.0, 128.0, 10.0, 136.0])
    assert np.all(np.diff(a[:, 1]) > 0) and np.all(np.diff(b[:, 1]) > 0)  # neither shape folds back
    assert a[:20].tolist() == b[:20].tolist() and a[0, 1] == 60.0  # far from the tip nothing moved
    # Tips the band's corners already put apart stay where they are.
    c, d = a.copy(), b.copy()
    assert not restore_tip_sweep(c, d, fixed, t_ns, t_ns + exposure, 4 * period, exposure, state, log,
                                 order_state, hist, -1.0)  # fmt: skip
    assert c.tolist() == a.tolist() and d.tolist() == b.tolist()
    # Without a frame in the motion model there is no path: nothing moves.
    e, f = np.repeat(a[:1], 3, axis=0), np.repeat(a[:1], 3, axis=0)
    state[K.MOTION_COUNT] = 0
    assert not restore_tip_sweep(e, f, fixed, t_ns, t_ns + exposure, 4 * period, exposure, state, log,
                                 order_state, hist, -1.0)  # fmt: skip


def test_tips_apart_across_but_not_along_a_sliding_path_are_moved() -> None:
    # A tip sliding along its own axis while the rope sweeps a little sideways (simulated late swing, tuning seed,
    # frames 13 and 47: 3.4 / 2.5 px along, 2.8-2.9 px across): the band's corners show the sideways part only,
    # and the tips lie apart by more than `COLLAPSED` of the whole sweep. Along the axis they are collapsed.
    fixed, period, exposure, state, log, t_ns, a = _straight_path()  # the path slides 8 px along +col
    order_state = np.zeros(K.ORDER_STATE_SIZE, np.int64)
    hist = np.zeros((K.HISTORY, 2))
    args = (fixed, t_ns, t_ns + exposure, 4 * period, exposure, state, log, order_state, hist, -1.0)
    b = a.copy()
    b[:, 0] += np.float32(5.0)  # 5 px across (more than 0.6 x 8), 0 along
    c, d = a.copy(), b.copy()
    assert restore_tip_sweep(c, d, *args)
    # to the midpoint -/+ half the path's sweep (8 px along, and across the midpoint's own step from the model's)
    s_r, s_c = sweep_from_path(fixed, t_ns + exposure // 2, exposure, 4 * period, state, log, 12.5, 132.0)
    assert s_c == pytest.approx(8.0) and abs(s_r) < 0.3 * s_c
    assert c[-1].tolist() == pytest.approx([12.5 - s_r / 2, 132.0 - s_c / 2], abs=1e-4)
    assert d[-1].tolist() == pytest.approx([12.5 + s_r / 2, 132.0 + s_c / 2], abs=1e-4)
    # Apart along the axis by the path's slide: they stand.
    c, d = a.copy(), b.copy()
    d[-3:, 1] += np.float32(8.0)
    kept = d.copy()
    assert not restore_tip_sweep(c, d, *args)
    assert d.tolist() == kept.tolist()
    # In the reverse order along the axis by as much, or farther apart across than the whole sweep and a rope
    # width: measured apart, they stand (review of session 17: each was moved ~12 px).
    for shift_r, shift_c in ((0.0, -8.0), (16.0, 0.0)):
        c, d = a.copy(), a.copy()
        d[-3:, 0] += np.float32(shift_r)
        d[-3:, 1] += np.float32(shift_c)
        kept = d.copy()
        assert not restore_tip_sweep(c, d, *args), (shift_r, shift_c)
        assert d.tolist() == kept.tolist()
    # A rope across the path (its tips' axis along rows, the tips 7 px apart along the path, more than 0.6 of its
    # 10.6 px): the path does not slide along the rope, nothing moves.
    rows = np.arange(-62.0, 10.1, 2.0)
    c = np.stack([rows, np.full_like(rows, 132.0)], axis=1).astype(np.float32)
    d = c.copy()
    d[:, 1] += np.float32(7.0)
    assert not restore_tip_sweep(c, d, *args)


def test_without_the_motion_model_the_time_orders_history_gives_the_path() -> None:
    # After a frame without shapes (or a flagged one) the motion model is cleared, but the time order keeps the
    # last frames' tips (simulated lab-rolling, tuning seed, frame 170 after a lost frame: tips 1.0 px apart against
    # a 10.3 px sweep, 3.7 / 6.5 px off): the line from the last frame's tip at mid-exposure to this frame's
    # midpoint gives the sweep.
    fixed, period, exposure, state, log, _, a = _straight_path()
    state[K.MOTION_COUNT] = 0
    t_ns = 3 * period  # one frame lost in between
    order_state = np.zeros(K.ORDER_STATE_SIZE, np.int64)
    hist = np.zeros((K.HISTORY, 2))
    # The last measured frame (at period): its tips 8 px apart along +col around col 116, then this frame's own two
    # samples (taken by the time order before the restore), which the path must not read.
    order_state[:4] = (period, period + exposure, t_ns, t_ns + exposure)
    hist[:4] = ((10.0, 112.0), (10.0, 120.0), (10.0, 132.0), (10.0, 132.0))
    order_state[K.ORDER_COUNT] = 4
    mid_c = 116.0 + 2.0 * (t_ns - period) / 1e6  # 2 px per ms
    sweep = sweep_from_history(t_ns + exposure // 2, exposure, 4 * period, order_state, hist, 10.0, mid_c)
    assert sweep == pytest.approx((0.0, 8.0, 8.0), abs=1e-6)
    # One sample of the last frame (a one-shape frame, at its mid-exposure): its own sweep is 0.
    one = order_state.copy()
    one[:3] = (period + exposure // 2, t_ns, t_ns + exposure)
    one[K.ORDER_COUNT] = 3
    single = np.array([(10.0, 116.0), (10.0, 132.0), (10.0, 132.0), (0, 0), (0, 0), (0, 0)])
    assert sweep_from_history(t_ns + exposure // 2, exposure, 4 * period, one, single, 10.0, mid_c) == pytest.approx(
        (0.0, 8.0, 0.0), abs=1e-6
    )
    # Older than the age limit: no path.
    assert np.isnan(sweep_from_history(t_ns + exposure // 2, exposure, period, order_state, hist, 10.0, mid_c)[0])
    # The collapsed tips (both at the midpoint) are moved apart by it, and the history's samples of this frame with
    # them.
    shift = mid_c - a[-1, 1]
    a[:, 1] += np.float32(shift)
    b = a.copy()
    assert restore_tip_sweep(a, b, fixed, t_ns, t_ns + exposure, 4 * period, exposure, state, log, order_state, hist,
                             -1.0)  # fmt: skip
    assert a[-1].tolist() == pytest.approx([10.0, mid_c - 4.0]) and b[-1].tolist() == pytest.approx([10.0, mid_c + 4.0])
    assert hist[2:4].ravel().tolist() == pytest.approx([10.0, mid_c - 4.0, 10.0, mid_c + 4.0])


def test_collapsed_tips_of_shapes_the_length_check_flags_stay_where_they_are() -> None:
    # A shape that runs on to the band's far end (paper-soft 15 ms, simulated: 15-18 px too long, the other right,
    # the tips together) makes the shapes' lengths disagree by more than the length self-check accepts: the
    # midpoint is not the tip at mid-exposure, and moving the tips would only hide the mismatch from the check.
    assert ChecksConfig().length_mismatch == LENGTH_MISMATCH
    fixed, period, exposure, state, log, t_ns, a = _straight_path()
    length0 = 100.0  # 3 px accepted
    order_state = np.zeros(K.ORDER_STATE_SIZE, np.int64)
    hist = np.zeros((K.HISTORY, 2))
    for lift, moves in ((2.0, True), (3.0, False)):
        b = a.copy()
        b[10:20, 0] += lift  # a detour of 2 (hypot(lift, 2) - 2) px: 1.7 / 3.2 px longer
        assert shape_length(b) - shape_length(a) == pytest.approx(2.0 * (np.hypot(lift, 2.0) - 2.0), rel=1e-5)
        c, d = a.copy(), b.copy()
        got = restore_tip_sweep(c, d, fixed, t_ns, t_ns + exposure, 4 * period, exposure, state, log, order_state,
                                hist, length0)  # fmt: skip
        assert got is moves, lift
        assert (c.tolist() != a.tolist()) is moves
        # Lc0 not known yet: not checked
        assert restore_tip_sweep(a.copy(), b.copy(), fixed, t_ns, t_ns + exposure, 4 * period, exposure, state, log,
                                 order_state, hist, -1.0)  # fmt: skip


def test_shift_tip_spreads_the_move_over_the_last_arc() -> None:
    shape = np.stack([np.zeros(11), np.arange(0.0, 22.0, 2.0)], axis=1).astype(np.float32)
    shift_tip(shape, 0.0, -3.0)  # back by 3 px: spread over the last 9 px of arc
    assert shape[-1].tolist() == pytest.approx([0.0, 17.0])
    assert shape[:6].tolist() == np.stack([np.zeros(6), np.arange(0.0, 12.0, 2.0)], axis=1).tolist()
    assert np.all(np.diff(shape[:, 1]) > 0)


MOTION_STATE_SIZE = K.MOTION_FRAMES + 2
