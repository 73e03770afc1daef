"""The rope's contrast read off the band (`BandMeasure`) does not depend on the one frame that made its last
reading: a frame whose contour took a still structure in (an edge spacing of 10 px instead of 3) once froze the
contrast at a quarter of the rope's, and every later sweep read from the edge slope was 0 (a static centreline
half a sweep off, reported OK: `lab-dark`'s silent failures)."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus
from ropecam.device.pipeline.split_measure import CONTRAST_FRAMES


def _tip_errors(result, frame) -> float:
    """The worse free-tip error (px) of the frame's two shapes, in the better of the two time orders."""
    ours = (result.begin[-1, ::-1], result.end[-1, ::-1])
    truth = (frame.begin_uv[-1], frame.end_uv[-1])
    straight = max(np.hypot(*(ours[0] - truth[0])), np.hypot(*(ours[1] - truth[1])))
    swapped = max(np.hypot(*(ours[0] - truth[1])), np.hypot(*(ours[1] - truth[0])))
    return float(min(straight, swapped))


def test_a_frame_with_a_wrong_width_does_not_set_the_contrast() -> None:
    rope = SyntheticRope(
        width=200, height=170, fixed_uv=(100.3, 12.6), length_px=140.0, diameter_px=2.5, blur_px=0.5,
        amplitude_rad=0.5, period_s=0.9, phase_rad=0.0, noise_dn=1.0, exposure_us=4000,
    )  # fmt: skip
    frames = list(rope.frames(16))
    last_readings = (CONTRAST_FRAMES - 2, CONTRAST_FRAMES - 1)  # the frames of the last two contrast readings
    runs = {}
    for name in ("plain", "block"):
        # static_frames = 0: no learned mask, whose relearning after frame 10 would read the contrast again
        pipeline = Pipeline(PipelineConfig(lens_blur_px=0.5, static_frames=0), (rope.width, rope.height))
        errors = []
        for frame in frames:
            image = frame.image.copy()
            if name == "block" and frame.index in last_readings:
                image[12:40, 96:106] = image.max()  # a bright block hanging from the fixed end (no mask)
            result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
            if frame.index in last_readings and name == "block":
                assert pipeline.splitter.width > 6.0  # the contour took the block in: a wrong edge spacing
            if frame.index > last_readings[-1]:
                assert result.status is FrameStatus.OK and result.begin is not None and result.end is not None
                errors.append(_tip_errors(result, frame))
        splitter = pipeline.splitter
        assert len(splitter.measure.contrasts) == CONTRAST_FRAMES
        runs[name] = (splitter.measure.contrast_for(splitter.width), np.asarray(errors), splitter.sweep_px)
    (plain, plain_errors, plain_sweep), (block, block_errors, block_sweep) = runs["plain"], runs["block"]
    assert 140.0 < plain < 200.0  # the rendered contrast is 168 grey levels
    assert block == pytest.approx(plain, rel=0.02)
    assert block_sweep == pytest.approx(plain_sweep, abs=0.1)  # not 0: the sweep is read from the edge slope
    assert block_errors.mean() <= plain_errors.mean() + 0.05, (block_errors, plain_errors)
