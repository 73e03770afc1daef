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
