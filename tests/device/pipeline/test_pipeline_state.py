"""State between frames: the time gap drives the ROI, gaps reset the prediction, unknown exposures are handled."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.finish import FrameClock, max_age_ns
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus


@pytest.fixture(scope="module")
def swing() -> SyntheticRope:
    """A rope swinging through the bottom (fast, ~5 px of tip blur at 4 ms), 119 FPS."""
    return SyntheticRope(exposure_us=4000, amplitude_rad=0.6, period_s=0.9, diameter_px=3.0, phase_rad=1.5, fps=119.0)


@pytest.fixture(scope="module")
def swing_frames(swing):
    return {f.index: f for f in (swing.render(i) for i in (0, 1, 2, 3, 6))}


def _roi_px(pipeline: Pipeline) -> int:
    return int(np.maximum(pipeline.hi - pipeline.lo + 1, 0).sum())


def _run(pipeline: Pipeline, frames, indices) -> list:
    return [pipeline.process(frames[i].image, i, frames[i].t_ns, frames[i].exposure_us) for i in indices]


def _measured(results: list) -> bool:
    """Every frame OK but the stream's first split, whose time order nothing decided (the rope swings from the
    start): that one is kept but not trusted (`order`)."""
    first, *rest = results
    return (first.status, first.reason) == (FrameStatus.IMPLAUSIBLE, "order") and all(
        r.status is FrameStatus.OK for r in rest
    )


def test_roi_follows_the_time_since_the_last_measured_frame(swing, swing_frames) -> None:
    # Frames 4 and 5 are dropped: frame 6 comes three periods after frame 3. The ROI must be predicted over that
    # gap (the rope moved three times as far), not over one guessed period.
    pipeline = Pipeline(PipelineConfig(), (swing.width, swing.height))
    results = _run(pipeline, swing_frames, (0, 1, 2, 3, 6))
    assert _measured(results), [r.message for r in results]
    assert not results[-1].full_frame  # found in the ROI predicted over the real gap
    # The same frame seen one period after frame 3 (wrong time stamp) is predicted elsewhere: the ROI differs.
    other = Pipeline(PipelineConfig(), (swing.width, swing.height))
    _run(other, swing_frames, (0, 1, 2, 3))
    frame = swing_frames[6]
    other.process(frame.image, 4, swing_frames[3].t_ns + round(1e9 / swing.fps), frame.exposure_us)
    moved = Pipeline(PipelineConfig(), (swing.width, swing.height))
    _run(moved, swing_frames, (0, 1, 2, 3))
    moved.process(frame.image, 6, frame.t_ns, frame.exposure_us)
    assert _roi_px(other) != _roi_px(moved) or not np.array_equal(other.lo, moved.lo)


@pytest.mark.parametrize("gap", ["black", "none"])
def test_a_gap_resets_the_prediction(swing, swing_frames, gap) -> None:
    """After a frame without shapes the ROI is searched afresh; the time order still uses the tips of the frames
    before the gap while they are recent (under four frame periods old: a swing is smooth over that), and starts
    again (confidence 0.5) after a longer gap."""
    for late_periods in (0, 10):
        pipeline = Pipeline(PipelineConfig(), (swing.width, swing.height))
        assert _measured(_run(pipeline, swing_frames, (0, 1, 2)))
        bad = np.zeros((swing.height, swing.width), np.uint8) if gap == "black" else None
        r = pipeline.process(bad, 3, swing_frames[3].t_ns, 4000)
        assert r.status is (FrameStatus.NO_ROPE if gap == "black" else FrameStatus.BAD_FRAME)
        frame = swing_frames[6]
        t_ns = frame.t_ns + round(late_periods * 1e9 / swing.fps)
        r = pipeline.process(frame.image, 6, t_ns, frame.exposure_us)
        assert r.full_frame  # searched afresh, not in a band predicted from frames before the gap
        if late_periods:
            assert r.order_confidence == 0.5  # history too old: nothing stale extrapolated
            # Nothing orders this split: kept but not trusted where its tips lie more than a rope width apart.
            assert r.status is FrameStatus.OK or r.reason == "order", r.message
        else:
            assert r.status is FrameStatus.OK, r.message
            assert r.order_confidence > 0.5
            tip = r.begin[-1]
            assert np.hypot(*(tip - frame.tip_begin_uv)) < np.hypot(*(tip - frame.tip_end_uv))  # the right order
        # The frame after that has history again.
        r = pipeline.process(frame.image, 7, t_ns + round(1e9 / swing.fps), frame.exposure_us)
        assert r.status is FrameStatus.OK


@pytest.mark.parametrize("exposure_us", [0, None])
def test_unknown_exposure_is_measured_without_time_order(swing, swing_frames, exposure_us) -> None:
    pipeline = Pipeline(PipelineConfig(), (swing.width, swing.height))
    results = [pipeline.process(swing_frames[i].image, i, swing_frames[i].t_ns, exposure_us) for i in (0, 1, 2, 3)]
    for r in results:
        assert r.status is FrameStatus.OK, r.message
        assert r.t_end_ns == r.t_ns
        assert r.order_confidence == 0.5
        assert "exposure unknown" in r.message
        assert all(math.isfinite(v) for v in r.begin.ravel())
    # Known again: measured normally. No frame of known exposure came before, so nothing decides its time order:
    # OK, or (its tips over a rope width apart) kept but flagged "order".
    frames = [swing_frames[i] for i in (6,)]
    r = pipeline.process(frames[0].image, 6, frames[0].t_ns, frames[0].exposure_us)
    assert r.t_end_ns == r.t_ns + 4_000_000 and r.begin is not None
    assert r.status is FrameStatus.OK or r.reason == "order", r.message


@pytest.mark.parametrize("exposure_us", [-1.0, float("nan"), float("inf"), "4 ms"])
def test_invalid_exposure_is_a_bad_frame_naming_it(swing, swing_frames, exposure_us) -> None:
    pipeline = Pipeline(PipelineConfig(), (swing.width, swing.height))
    frame = swing_frames[0]
    r = pipeline.process(frame.image, 0, frame.t_ns, exposure_us)
    assert r.status is FrameStatus.BAD_FRAME
    assert "exposure_us" in r.message and r.t_end_ns == r.t_ns
    r = pipeline.process(swing_frames[1].image, 1, swing_frames[1].t_ns, 4000)
    assert r.begin is not None and r.reason in ("", "order")  # measured (the first split: its order undecided)
    r = pipeline.process(swing_frames[2].image, 2, swing_frames[2].t_ns, 4000)
    assert r.status is FrameStatus.OK


def test_reset_tracking_searches_the_next_frame_afresh(swing, swing_frames) -> None:
    pipeline = Pipeline(PipelineConfig(), (swing.width, swing.height))
    results = _run(pipeline, swing_frames, (0, 1, 2))
    assert not results[-1].full_frame and results[-1].order_confidence > 0.5
    fixed = pipeline.fixed.copy()
    pipeline.reset_tracking()
    r = _run(pipeline, swing_frames, (3,))[0]
    assert r.status is FrameStatus.OK and r.full_frame and r.order_confidence == 0.5
    np.testing.assert_allclose(pipeline.fixed, fixed, atol=1.0)  # what does not change is kept
    assert pipeline.frames_coarse + pipeline.frames_full == 2  # the first frame and this one


def test_warm_up_builds_the_edge_tables_and_leaves_no_state(swing, swing_frames) -> None:
    config = PipelineConfig(rope_width_px=3.0)
    pipeline = Pipeline(config, (swing.width, swing.height))
    pipeline.warm_up()
    model = pipeline.splitter.model
    assert max(1, round(pipeline.traits.width() * 10)) in model._cache  # the configured width's tables are built
    assert (pipeline.locator.prev_count, pipeline.frames_full, pipeline.frames_coarse, pipeline._clock.last_t_ns) == (
        0,
        0,
        0,
        None,
    )
    # Tables are per process: another pipeline with the same smoothing and lens blur shares them.
    assert Pipeline(config, (swing.width, swing.height)).splitter.model is model
    results = _run(pipeline, swing_frames, (0, 1, 2))
    assert all(r.status is FrameStatus.OK for r in results), [r.message for r in results]


def _shapes(results) -> list:
    return [(r.status, r.begin, r.end) for r in results]


def test_results_do_not_depend_on_what_earlier_frames_left_in_the_planes(swing, swing_frames) -> None:
    # The edge stage fills its planes inside the band only; the split reads the smoothed image a little beyond it
    # (the contrast across the band, the background past the tip). Those reads must see this frame: garbage
    # written over the planes before every frame must not change a single output.
    clean = Pipeline(PipelineConfig(), (swing.width, swing.height))
    expected = _run(clean, swing_frames, (0, 1, 2, 3, 6))
    dirty = Pipeline(PipelineConfig(), (swing.width, swing.height))
    got = []
    for i in (0, 1, 2, 3, 6):
        for plane in (dirty.edges.smooth, dirty.edges.tmp):
            plane[:] = 1000.0
        got += _run(dirty, swing_frames, (i,))
    assert _measured(expected), [r.message for r in expected]
    for want, have in zip(_shapes(expected), _shapes(got), strict=True):
        assert want[0] is have[0]
        np.testing.assert_array_equal(want[1], have[1])
        np.testing.assert_array_equal(want[2], have[2])


@pytest.mark.kernel
def test_the_frame_clock_keeps_the_shortest_gap_between_frame_starts_in_its_cells() -> None:
    """`FrameClock.tick` (`K.tick_clock`, which `steady_frame` makes too): the period is the shortest gap between
    frame starts seen (a dropped frame's longer gap, a start that goes back: not taken), the time order's age
    `AGE_PERIODS` of it; unknown (None, the default period's age) until two starts were seen."""
    clock = FrameClock()
    assert (clock.period_ns, clock.max_age_ns, clock.last_t_ns) == (None, max_age_ns(None), None)
    for t_ns in (10**15, 10**15 + 8_400_000, 10**15 + 25_200_000, 10**15 + 25_000_000):
        clock.tick(t_ns)
    assert (clock.period_ns, clock.max_age_ns, clock.last_t_ns) == (8_400_000, 4 * 8_400_000, 10**15 + 25_000_000)
    clock.tick(10**15 + 33_300_000)  # 8.3 ms after the last start: the shorter gap
    assert (clock.period_ns, clock.max_age_ns) == (8_300_000, K.AGE_PERIODS * 8_300_000)
    clock.last_t_ns = None  # (`Pipeline.warm_up`'s blank frame is not the stream's)
    clock.tick(10**15 + 33_400_000)
    assert (clock.period_ns, clock.last_t_ns) == (8_300_000, 10**15 + 33_400_000)
