"""The band's uncertainty from the prediction's measured error (`need_profile` in `band_stage`): a smaller
band than the step-scaled one, the same measurements, and no use of it over a time gap it was not measured for."""

from __future__ import annotations

import math

import numpy as np
import pytest

import ropecam.device.pipeline.motion as motion_module
from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus


@pytest.fixture(scope="module")
def swing() -> SyntheticRope:
    """A rope swinging through the bottom (fast, ~5 px of tip blur at 4 ms), 119 FPS."""
    return SyntheticRope(exposure_us=4000, amplitude_rad=0.6, period_s=0.9, diameter_px=3.0, phase_rad=1.5, fps=119.0)


@pytest.fixture(scope="module")
def frames(swing):
    return {i: swing.render(i) for i in (0, 1, 2, 3, 4, 5, 6, 9)}


def _band_px(pipeline: Pipeline) -> int:
    return int(np.maximum(pipeline.hi - pipeline.lo + 1, 0).sum())


def _run(swing, frames, indices, monkeypatch, profile: bool):
    """Process `indices`; return per frame (result copy of the tip points, band px, retries so far)."""
    if not profile:
        monkeypatch.setattr(motion_module, "NEED_FLOOR_PX", math.inf)  # an infinite profile: the step-scaled band
    pipeline = Pipeline(PipelineConfig(), (swing.width, swing.height))
    out = []
    for i in indices:
        f = frames[i]
        r = pipeline.process(f.image, i, f.t_ns, f.exposure_us)
        # Frame 0 (the rope swinging from the start): nothing decides its time order, kept but not trusted.
        assert r.status is FrameStatus.OK or (i, r.reason) == (0, "order"), r.message
        out.append((np.array(r.begin), np.array(r.end), _band_px(pipeline), pipeline.roi_retries, r.full_frame))
    monkeypatch.undo()
    return pipeline, out


def test_measured_band_is_smaller_and_measures_the_same(swing, frames, monkeypatch) -> None:
    indices = (0, 1, 2, 3, 4, 5, 6)
    tight, with_profile = _run(swing, frames, indices, monkeypatch, profile=True)
    _, without = _run(swing, frames, indices, monkeypatch, profile=False)
    assert np.all(np.isfinite(tight._motion.profile))  # measured, and in use
    assert tight._motion.need.shape == (2, motion_module.NEED_BINS)
    for k, (a, b) in enumerate(zip(with_profile, without, strict=True)):
        np.testing.assert_array_equal(a[0], b[0], err_msg=f"frame {indices[k]}")  # the same shapes
        np.testing.assert_array_equal(a[1], b[1], err_msg=f"frame {indices[k]}")
        assert not a[4] or k == 0  # found in the band after the first frame
    assert with_profile[-1][3] == 0  # no widening
    # Frames 4-6: the profile measured on the frames before them applies (the motion model holds 3 frames).
    assert all(a[2] < 0.9 * b[2] for a, b in zip(with_profile[4:], without[4:], strict=True)), [
        (a[2], b[2]) for a, b in zip(with_profile, without, strict=True)
    ]


def test_no_measured_band_over_a_longer_gap_or_after_a_miss(swing, frames, monkeypatch) -> None:
    # Frames 7 and 8 are dropped: the error measured over one period does not hold over three.
    _, with_profile = _run(swing, frames, (0, 1, 2, 3, 4, 5, 9), monkeypatch, profile=True)
    _, without = _run(swing, frames, (0, 1, 2, 3, 4, 5, 9), monkeypatch, profile=False)
    assert with_profile[-2][2] < without[-2][2]  # frame 5: measured
    assert with_profile[-1][2] == without[-1][2]  # frame 9: the step-scaled band
    np.testing.assert_array_equal(with_profile[-1][0], without[-1][0])
    # A frame not found in its band (a black frame: no rope) forgets the measured error.
    pipeline = Pipeline(PipelineConfig(), (swing.width, swing.height))
    for i in (0, 1, 2, 3, 4):
        pipeline.process(frames[i].image, i, frames[i].t_ns, frames[i].exposure_us)
    assert np.all(np.isfinite(pipeline._motion.profile))
    pipeline.process(np.zeros_like(frames[5].image), 5, frames[5].t_ns, frames[5].exposure_us)
    assert np.all(np.isinf(pipeline._motion.profile))
