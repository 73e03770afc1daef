"""Canny thresholds measured on the frame's own gradient (`EdgeThresholds`), and a faint rope found with them."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
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
            if result.status is not FrameStatus.OK:
                errors.append(np.inf)
                continue
            tips = (result.begin[-1][::-1], result.end[-1][::-1])  # (row, col) -> (u, v)
            errors.append(max(np.hypot(*(tips[0] - frame.tip_begin_uv)), np.hypot(*(tips[1] - frame.tip_end_uv))))
        worst[threshold_frames] = max(errors)
    assert worst[0] == np.inf
    assert worst[1] < 0.5
