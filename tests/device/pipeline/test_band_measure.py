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
from ropecam.device.pipeline.result import FrameStatus, Method
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
            # One reading per split (the split once read it up to three times a frame, and settled after four)
            assert len(pipeline.splitter.measure.contrasts) == min(frame.index + 1, CONTRAST_FRAMES)
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


@pytest.mark.parametrize("static_frames", [0, 8])
def test_a_contrast_no_8bit_rope_has_is_not_kept(static_frames: int) -> None:
    # A lens blur read across a clamp's edges (1.15 px for the rope's 0.5) makes the edge model read the rope's
    # edge spacing as a rope of a fraction of a pixel: its contrast over that width was 1516 grey levels, the
    # sweep from the edge slope 0, and a sweeping rope's centreline was reported OK (`clamp on`'s silent frames).
    rope = SyntheticRope(
        width=160, height=150, fixed_uv=(80.3, 12.6), length_px=120.0, diameter_px=2.5, blur_px=0.5,
        amplitude_rad=0.5, period_s=0.9, phase_rad=0.0, noise_dn=1.0, exposure_us=4000,
    )  # fmt: skip
    pipeline = Pipeline(PipelineConfig(lens_blur_px=1.15, static_frames=static_frames), (rope.width, rope.height))
    measure = pipeline.splitter.measure
    for frame in rope.frames(static_frames + 2):
        pipeline.process(frame.image, frame.index, frame.t_ns, float(rope.exposure_us))
        if frame.index == static_frames - 1:  # the mask is learned: the frames that taught this are suspect
            assert measure.contrast_rejected
    assert measure.contrasts
    width = pipeline.splitter.width
    assert measure.model.tables(width).width_px < 1.0  # the premise: not the rope's 2.5 px
    assert np.isnan(measure.contrast_for(width))
    assert not measure.contrast_settled
    if static_frames:  # read again once the mask is known (`Stages.relearn`)
        assert len(measure.contrasts) < CONTRAST_FRAMES


def test_a_decoded_dark_ropes_steeper_edges_split_its_small_sweeps(monkeypatch: pytest.MonkeyPatch) -> None:
    """A 2 px dark rope on a bright plate through a camera's gamma 2.2 and its unsharp mask (as the simulated
    `lab-dark`), swinging from rest (sweeps of 0-5 px), decoded by the pipeline: the still rope's edge slope over
    its contrast, read near the fixed end, stands above the edge model's (`BandMeasure.ratio_gain` > 1). Read with
    the model's own heights every small sweep is still and falls back to the band's middle, half a sweep off; the
    decision read with the gain splits them, and their tips are placed better. A bright rope in linear frames
    keeps the model's heights (gain 1)."""
    from ropecam.device.pipeline import split_measure

    from .test_edge_profile import _decoded_dark_rope

    rope, frames, images = _decoded_dark_rope(0.4, 3)
    runs = {}
    for cap in (split_measure.MAX_RATIO_GAIN, 1.0):  # 1.0: no gain, the model's own heights
        monkeypatch.setattr(split_measure, "MAX_RATIO_GAIN", cap)
        pipeline = Pipeline(PipelineConfig(gamma=2.2), (rope.width, rope.height))
        splits, errors = 0, {}
        for frame, image in zip(frames, images, strict=True):
            result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
            sweep = float(np.hypot(*(frame.end_uv[-1] - frame.begin_uv[-1])))
            if sweep >= 2.0 and result.begin is not None and result.end is not None:
                splits += result.method is Method.BLUR_SPLIT
                errors[frame.index] = _tip_errors(result, frame)
        runs[cap] = (pipeline.splitter.measure.ratio_gain, splits, errors)
    (gain, splits, errors), (no_gain, splits_before, errors_before) = runs.values()
    assert gain > 1.05 and no_gain == 1.0, (gain, no_gain)
    both = sorted(set(errors) & set(errors_before))
    assert len(both) >= 8, (errors, errors_before)
    assert splits > splits_before, (splits, splits_before)
    error = float(np.mean([errors[i] for i in both]))
    error_before = float(np.mean([errors_before[i] for i in both]))
    assert error < error_before - 0.1, (error, error_before, errors, errors_before)
    bright = Pipeline(PipelineConfig(lens_blur_px=0.5), (200, 170))
    still = SyntheticRope(
        width=200, height=170, fixed_uv=(100.3, 12.6), length_px=140.0, diameter_px=2.5, blur_px=0.5,
        amplitude_rad=0.5, period_s=0.9, phase_rad=0.0, noise_dn=1.0, exposure_us=4000,
    )  # fmt: skip
    for frame in still.frames(CONTRAST_FRAMES):
        bright.process(frame.image, frame.index, frame.t_ns, 4000.0)
    assert len(bright.splitter.measure.contrasts) == CONTRAST_FRAMES
    assert bright.splitter.measure.ratio_gain == 1.0


def test_a_frames_outline_joined_across_a_gap_is_read_for_the_contrast_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """`ResultFinisher._rejoined` splits the joined outline, and the frame's own contour again when it keeps no two
    shapes: each split reads the contrast while it is learned. The frame keeps the one reading of its own split, so
    that the first `CONTRAST_FRAMES` readings are as many frames (`lab-dark`, tuning seed, default config: frame 0
    made 3 of them, its own, the lens blur's second split, and the joined outline's) and what they give is as
    before the attempt. Here the "join" leaves the contour as it is (the attempt's splits are then as the frame's)."""
    from ropecam.device.pipeline.contour import ContourTracer

    rope = SyntheticRope(
        width=200, height=170, fixed_uv=(100.3, 12.6), length_px=140.0, diameter_px=2.5, blur_px=0.5,
        amplitude_rad=0.5, period_s=0.9, phase_rad=0.0, noise_dn=1.0, exposure_us=4000,
    )  # fmt: skip
    pipeline = Pipeline(PipelineConfig(lens_blur_px=0.5, static_frames=0), (rope.width, rope.height))
    measure = pipeline.splitter.measure
    for frame in rope.frames(3):
        pipeline.process(frame.image, frame.index, frame.t_ns, 4000.0)
        readings, contrast = list(measure.contrasts), measure.contrast_px
        assert 0 < len(readings) < CONTRAST_FRAMES
        monkeypatch.setattr(ContourTracer, "rejoin_gap", lambda self, detector, reach_px: self.count)
        for split_twice in (False, True):  # the joined outline kept, or not (the frame's contour split again)
            if split_twice:
                monkeypatch.setattr(type(pipeline.splitter), "split", _one_shape(type(pipeline.splitter).split))
            pipeline._finisher._rejoined()
            assert measure.contrasts == readings and measure.slopes[: len(readings)] == measure.slopes
            assert measure.contrast_px == contrast
        monkeypatch.undo()


def _one_shape(split):
    """`BlurSplitter.split` whose first call's outcome is given as None (no two shapes on the joined outline)."""
    calls = []

    def wrapped(self, *args, **kwargs):
        outcome = split(self, *args, **kwargs)
        calls.append(1)
        return None if len(calls) == 1 else outcome

    return wrapped
