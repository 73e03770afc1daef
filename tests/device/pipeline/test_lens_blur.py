"""LensBlur: the band edge model of the split, of the camera blur given or read on the first frames (its reading
through a pipeline: test_edge_profile.py)."""

from __future__ import annotations

import numpy as np

from ropecam.device.pipeline.config import DEFAULT_LENS_BLUR_PX
from ropecam.device.pipeline.edge_profile import EdgeBlur
from ropecam.device.pipeline.edges import gaussian_weights
from ropecam.device.pipeline.lens_blur import BLUR_TOLERANCE_PX, LensBlur


def _weights() -> np.ndarray:
    return gaussian_weights(1.0).astype(np.float64)


def test_a_given_blur_is_used_and_never_read() -> None:
    lens = LensBlur(_weights(), 0.8, 0.5, 1.2)
    model = lens.model
    assert (model.lens_blur_px, model.sharpen_gain, model.sharpen_sigma_px) == (0.8, 0.5, 1.2)
    assert lens.estimate is None and lens.value is None and lens.measured is None
    frame, points = np.zeros((16, 16), np.uint8), np.zeros((0, 2), np.float32)
    assert not lens.read(frame, points, 0, (0.0, 0.0), 3.0, 0.0)


def test_a_blur_not_given_starts_at_the_default_and_is_read_only_when_asked() -> None:
    lens = LensBlur(_weights(), None, 0.7, 2.0)  # the sharpening goes with a given blur only
    assert (lens.model.lens_blur_px, lens.model.sharpen_gain) == (DEFAULT_LENS_BLUR_PX, 0.0)
    assert lens.estimate is not None and lens.value is None
    assert LensBlur(_weights(), None, read=False).estimate is None


def test_use_rounds_the_blur_and_keeps_the_model_within_the_tolerance() -> None:
    lens = LensBlur(_weights(), None)
    assert lens.use(EdgeBlur(1.02, 0.0, 1.0))
    assert lens.model.lens_blur_px == 1.0  # rounded to 0.05 px: pipelines share the tables
    assert not lens.use(EdgeBlur(0.99, 0.0, 3.0))  # the same model once rounded (no sharpening: sigma moot)
    assert not lens.use(EdgeBlur(1.05, 0.0, 1.0), BLUR_TOLERANCE_PX)
    assert lens.model.lens_blur_px == 1.0
    assert lens.use(EdgeBlur(1.05, 0.0, 1.0))  # without a tolerance
    assert lens.use(EdgeBlur(1.05, 0.5, 1.0), BLUR_TOLERANCE_PX)  # sharpening variance 0.5 px^2
    assert (lens.model.sharpen_gain, lens.model.sharpen_sigma_px) == (0.5, 1.0)
