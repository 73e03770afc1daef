"""Canny thresholds measured on the frame's own gradient (`EdgeThresholds`), and a faint rope found with them."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.edges import EdgeDetector
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus
from ropecam.device.pipeline.thresholds import HIGH_PER_NOISE, LOW_PER_NOISE, EdgeThresholds
from ropecam.shared.errors import ConfigError


def _noise(sigma_dn: float, shape: tuple[int, int] = (60, 80)) -> np.ndarray:
    rng = np.random.default_rng(3)
    return np.clip(100.0 + rng.normal(0.0, sigma_dn, shape), 0, 255).astype(np.uint8)


def test_thresholds_follow_the_median_gradient_within_floor_and_cap() -> None:
    frame = _noise(3.0)
    detector = EdgeDetector(60, 80, 1.0, 20.0, 50.0)
    detector.detect(frame, detector.full_lo, detector.full_hi)
    median = float(np.median(detector.mag[::4, ::4]))  # the slow reference: the same planes, NumPy's median
    assert 2.0 < median < 8.0
    thresholds = EdgeThresholds(60, 80, 1.0, 20.0, 50.0, frames=1)
    measured = thresholds.measure(frame)
    assert thresholds.noise == median  # its rows-only detection gives the whole frame's values on its grid
    assert measured == pytest.approx((LOW_PER_NOISE * median, HIGH_PER_NOISE * median), rel=1e-6)
    quiet = EdgeThresholds(60, 80, 1.0, 20.0, 50.0, frames=2)
    assert quiet.measure(np.full((60, 80), 40, np.uint8)) is None and quiet.measuring
    assert quiet.measure(np.full((60, 80), 40, np.uint8)) == (4.0, 10.0)  # the floors
    loud = EdgeThresholds(60, 80, 1.0, 20.0, 50.0, frames=1)
    assert loud.measure(_noise(40.0)) == (20.0, 50.0)  # never above the configured ones


def test_warm_up_prepares_the_measurement_without_measuring() -> None:
    frame = _noise(3.0)
    warmed, cold = Pipeline(PipelineConfig(), (80, 60)), Pipeline(PipelineConfig(), (80, 60))
    warmed.warm_up()
    assert warmed.thresholds.measuring and warmed.thresholds.noise is None  # the blank frame taught nothing
    warmed.process(frame, 0, 0, 4000.0)
    cold.process(frame, 0, 0, 4000.0)
    assert warmed.thresholds.noise == cold.thresholds.noise
    assert (warmed.edges.low, warmed.edges.high) == (cold.edges.low, cold.edges.high)


def test_threshold_frames_is_validated() -> None:
    with pytest.raises(ConfigError, match="threshold_frames"):
        PipelineConfig(threshold_frames=-1)


def test_a_faint_rope_is_found_with_measured_thresholds() -> None:
    """10 DN of contrast (a 40 DN rope on a 30 DN plate, 0.5 DN noise): the fixed thresholds see no rope, the
    measured ones find it with the bright rope's accuracy."""
    rope = SyntheticRope(exposure_us=8000, amplitude_rad=0.7, period_s=0.9, rope_level=40.0, noise_dn=0.5)
    frames = list(rope.frames(5, start=2))
    worst = {}
    for threshold_frames in (0, 1):
        pipeline = Pipeline(PipelineConfig(threshold_frames=threshold_frames), (rope.width, rope.height))
        errors = []
        for frame in frames:
            result = pipeline.process(frame.image, frame.index, frame.t_ns, float(rope.exposure_us))
            # (a frame measured about a fixed end not yet confirmed, the rope already swinging, is flagged
            # `fixed_end_guess`: its tips count all the same)
            if result.status is not FrameStatus.OK and result.reason != "fixed_end_guess":
                errors.append(np.inf)
                continue
            tips = (result.begin[-1][::-1], result.end[-1][::-1])  # (row, col) -> (u, v)
            errors.append(max(np.hypot(*(tips[0] - frame.tip_begin_uv)), np.hypot(*(tips[1] - frame.tip_end_uv))))
        worst[threshold_frames] = max(errors)
    assert worst[0] == np.inf
    assert worst[1] < 0.5


def test_followed_thresholds_match_a_fresh_measurement_and_cost_one_kernel_call() -> None:
    """The sparse grid's median (`follow`) is the whole-frame measurement's within a histogram bin and a few %."""
    frame = _noise(6.0, (120, 160))
    fresh = EdgeThresholds(120, 160, 1.0, 200.0, 500.0, frames=1).measure(frame)
    follower = EdgeThresholds(120, 160, 1.0, 200.0, 500.0, frames=1, update_frames=2)
    follower.measure(_noise(1.0, (120, 160)))  # a quiet start
    assert follower.following
    for _ in range(40):  # 20 cycles: (1 - 0.25) ** 20 of the start is left
        follower.follow(frame)
    assert follower.used == pytest.approx(fresh, rel=0.1)
    with pytest.raises(ValueError, match="update_frames"):
        EdgeThresholds(10, 10, 1.0, 20.0, 50.0, frames=1, update_frames=-1)


def test_the_pipeline_follows_a_noise_change_mid_stream() -> None:
    """Frames of a quiet plate, then the noise rises 6x (the lamp dimmed and the gain went up): the thresholds
    follow it within a few cycles; with `threshold_update_frames = 0` they stay at the first frame's."""
    shape = (120, 160)
    quiet = [_noise(0.8, shape) for _ in range(3)]
    rng = np.random.default_rng(5)
    loud = [np.clip(60.0 + rng.normal(0.0, 5.0, shape), 0, 255).astype(np.uint8) for _ in range(36)]
    expected = EdgeThresholds(*shape, 1.0, 20.0, 50.0, frames=1).measure(loud[0])
    lows = {}
    for update in (0, 2):  # 18 cycles: (1 - 0.25) ** 18 of the quiet level is left
        config = PipelineConfig(threshold_update_frames=update, threshold_sample_every=1)
        pipeline = Pipeline(config, (shape[1], shape[0]))
        for index, frame in enumerate(quiet + loud):
            pipeline.process(frame, index, index * 8_403_361, 4000.0)
        lows[update] = float(pipeline.edges.low)
    assert lows[0] == pytest.approx(4.0)  # the quiet plate's floor, kept
    assert lows[2] == pytest.approx(expected[0], rel=0.1)
    assert expected[0] > 2.0 * lows[0]


def test_threshold_update_frames_is_validated() -> None:
    with pytest.raises(ConfigError, match="threshold_update_frames"):
        PipelineConfig(threshold_update_frames=-2)
    with pytest.raises(ConfigError, match="threshold_sample_every"):
        PipelineConfig(threshold_sample_every=0)
    with pytest.raises(ValueError, match="sample_every"):
        EdgeThresholds(10, 10, 1.0, 20.0, 50.0, frames=1, sample_every=0)


def test_following_samples_one_frame_in_sample_every() -> None:
    """With `sample_every = 3` the thresholds follow as a follower given only every third frame: the same
    slices of the same frames, the same noise level and thresholds, nothing sampled on the other frames."""
    rng = np.random.default_rng(11)
    frames = [np.clip(80.0 + rng.normal(0.0, 1.0 + 0.4 * i, (120, 160)), 0, 255).astype(np.uint8) for i in range(30)]
    sparse = EdgeThresholds(120, 160, 1.0, 200.0, 500.0, frames=1, update_frames=2, sample_every=3)
    every = EdgeThresholds(120, 160, 1.0, 200.0, 500.0, frames=1, update_frames=2)
    sparse.measure(frames[0])
    every.measure(frames[0])
    changes = 0
    for index, frame in enumerate(frames[1:]):
        hist = sparse._hist.copy()
        followed = sparse.follow(frame)
        if index % 3:
            assert followed is None and np.array_equal(sparse._hist, hist)  # not sampled
        else:
            assert followed == every.follow(frame)
            changes += followed is not None
        assert sparse.noise == every.noise
    assert changes > 0  # the rising noise moved them


@pytest.mark.parametrize("update_frames", [0, 2])
def test_update_measures_then_follows_as_the_calls_one_by_one(update_frames: int) -> None:
    """`update` (the pipeline's one call per frame) gives what `measure` on the measured frames, then `follow` when
    following, give: the same thresholds on the same frames, the same noise level after each."""
    rng = np.random.default_rng(5)
    frames = [np.clip(80.0 + rng.normal(0.0, 1.0 + 0.4 * i, (120, 160)), 0, 255).astype(np.uint8) for i in range(24)]
    one = EdgeThresholds(120, 160, 1.0, 200.0, 500.0, frames=2, update_frames=update_frames, sample_every=3)
    steps = EdgeThresholds(120, 160, 1.0, 200.0, 500.0, frames=2, update_frames=update_frames, sample_every=3)
    changes = 0
    for frame in frames:
        want = steps.measure(frame) if steps.measuring else steps.follow(frame) if steps.following else None
        got = one.update(frame)
        assert got == want and one.noise == steps.noise and one.used == steps.used
        changes += got is not None
    # the measurement, then (following) the rising noise's
    assert changes > 1 if update_frames else changes == 1


def test_sample_slice_reads_the_frame_through_its_slot_as_the_array_kernel_does() -> None:
    """`follow`'s kernels take no array argument (`K.sample_slice`: the frame through a `FrameSlot`; `K.sample_median`):
    the same histogram as `sample_gradient_histogram` given the frame, the same median; a frame the slot was not made
    for is refused."""
    thresholds = EdgeThresholds(120, 160, 1.0, 200.0, 500.0, frames=1, update_frames=2)
    assert thresholds._table_address != 0
    frame = _noise(5.0, (120, 160))
    want = np.zeros_like(thresholds._hist)
    K.sample_gradient_histogram(frame, thresholds._weights, 3, 16, 5, thresholds._work.copy(), want)
    thresholds._slot.hold(frame)
    assert K.sample_slice(thresholds._table_address, 3, 16, 5) == 0  # (not the sample count: no int made)
    assert want.sum() > 0
    np.testing.assert_array_equal(thresholds._hist, want)
    # The median through the table too (`follow`'s cycle end): as given the histogram.
    assert K.sample_median(thresholds._table_address) == K.histogram_median(want)
    thresholds._slot.hold(_noise(5.0, (120, 161)))
    assert K.sample_slice(thresholds._table_address, 3, 16, 5) == K.INVALID
    thresholds._slot.release()
    assert K.sample_slice(thresholds._table_address, 3, 16, 5) == K.INVALID
    # `follow` takes such a frame through the array kernel instead.
    thresholds.measure(_noise(5.0, (120, 160)))
    thresholds.follow(_noise(5.0, (100, 160)))  # another size than the slot's
    assert thresholds._hist.sum() > 0
