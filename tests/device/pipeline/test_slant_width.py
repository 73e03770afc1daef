"""The rope's edge spacing learned on the first frames does not depend on the rope's slant to the image axes
(`BandEdgeModel.slant_bias`, `BandMeasure._width`): the edge model is that of a band across an image axis, and a
spacing read across a slanted rope (up to 0.12 px shorter at 45 degrees) made its width, contrast and sweep tables
read sweeps below the rope's width wrongly (simulated rig-soft demo: begin and end shapes 0.4-0.7 mm too close)."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.edge_model import BandEdgeModel
from ropecam.device.pipeline.edges import gaussian_weights
from ropecam.device.pipeline.pipeline import Pipeline


def _learned_spacing(angle_rad: float) -> float:
    """The edge spacing the pipeline learns on a still, straight 2.5 px rope hanging `angle_rad` from vertical."""
    rope = SyntheticRope(amplitude_rad=angle_rad, period_s=1e6, bend=0.0, phase_rad=0.0, diameter_px=2.5,
                         exposure_us=100)  # fmt: skip
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    frame = rope.render(0)
    for index in range(16):  # the width settles after 15 frames
        pipeline.process(frame.image, index, round(index / rope.fps * 1e9), frame.exposure_us)
    width = pipeline.traits.width()
    assert width is not None
    return width


def test_a_slanted_rope_gives_the_spacing_of_an_upright_one() -> None:
    upright, slanted = _learned_spacing(0.0), _learned_spacing(np.pi / 4)
    # Without the slant correction the 45 degree rope read 2.984 px against the upright one's 3.104.
    assert slanted == pytest.approx(upright, abs=0.04)


def test_slant_bias_is_zero_across_an_axis_and_shortest_at_45_degrees() -> None:
    angles, bias = BandEdgeModel(gaussian_weights(1.0).astype(np.float64), 0.4).slant_bias(3.188)
    assert angles[0] == 0.0 and angles[-1] == 45.0
    assert bias[0] == 0.0 and np.all(bias <= 0.0)
    # measured on a still 2.49 px band drawn at 45 degrees through the pipeline's operations: -0.135 px
    assert -0.18 < bias[-1] < -0.09
    assert bias[-1] == bias.min()


def _across(curve_uv: np.ndarray, point: np.ndarray, tangent: np.ndarray, normal: np.ndarray) -> float:
    """Signed distance along `normal` from `point` to the (straight) `curve_uv` where it passes `point`."""
    along, across = (curve_uv - point) @ tangent, (curve_uv - point) @ normal
    nearest = np.sort(np.argsort(np.abs(along))[:2])
    order = np.argsort(along[nearest])
    return float(np.interp(0.0, along[nearest][order], across[nearest][order]))


def test_shapes_of_a_slanted_rope_are_as_far_apart_as_its_small_sweeps() -> None:
    """A straight 2.5 px rope at 45 degrees turning about its fixed end (sweeps 0.5-3 px over the exposure; no
    lens blur, so `lens_blur_px` 0): the start and end shapes' distance across the rope against the true sweep.
    Without the slant correction they were 0.78 / 0.46 / 0.28 px too far apart for sweeps of 0.5-1 / 1-2 / 2-3 px;
    with it -0.07 / -0.03 / -0.00."""
    amplitude = 1.2
    rope = SyntheticRope(width=240, height=200, fixed_uv=(60.3, 20.6), length_px=150.0, amplitude_rad=amplitude,
                         period_s=3.0, bend=0.0, phase_rad=float(np.arccos(np.pi / 4 / amplitude)), diameter_px=2.5,
                         exposure_us=14000, fps=60.0, noise_dn=0.0, nodes=32)  # fmt: skip
    pipeline = Pipeline(PipelineConfig(lens_blur_px=0.0), (rope.width, rope.height))
    found = []
    for index in range(18):
        frame = rope.render(index)
        result = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
        if index < 15:  # the width settles
            continue
        assert result.begin is not None and result.end is not None
        begin, end = np.asarray(result.begin, float)[:, ::-1], np.asarray(result.end, float)[:, ::-1]  # (u, v)
        tangent = frame.begin_uv[-1] - frame.begin_uv[0]
        tangent /= np.hypot(*tangent)
        normal = np.array([-tangent[1], tangent[0]])
        for fraction in np.linspace(0.1, 0.5, 20):
            at_begin = frame.begin_uv[0] + fraction * (frame.begin_uv[-1] - frame.begin_uv[0])
            at_end = frame.end_uv[0] + fraction * (frame.end_uv[-1] - frame.end_uv[0])
            sweep = float((at_end - at_begin) @ normal)
            measured = _across(end, at_end, tangent, normal) - _across(begin, at_begin, tangent, normal)
            found.append((abs(sweep), measured * np.sign(sweep)))
    sweeps, errors = np.array(found).T
    for low, high in ((0.5, 1.0), (1.0, 2.0), (2.0, 3.0)):
        within = (sweeps >= low) & (sweeps < high)
        assert np.count_nonzero(within) >= 5
        assert abs(float(errors[within].mean())) < 0.2, (low, high, float(errors[within].mean()))
