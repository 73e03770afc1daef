"""`split_shapes_packed` (`split_shapes_local`, the blur split's usual path in one kernel call) against the same
kernels called one by one."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus

pytestmark = pytest.mark.kernel


def _shapes(monkeypatch: pytest.MonkeyPatch, fused: bool) -> list[tuple[np.ndarray, np.ndarray]]:
    """Begin/end of 14 frames of a swinging rope (the contrast, hence the local sweeps, known from frame 10)."""
    rope = SyntheticRope(exposure_us=4000, amplitude_rad=0.6, period_s=0.9, diameter_px=3.0, phase_rad=1.5, fps=119.0)
    calls = []
    real = K.split_shapes_packed

    def counted(*args):
        calls.append(1)
        return real(*args) if fused else K.FULL  # FULL: the stage redoes the steps one by one

    monkeypatch.setattr(K, "split_shapes_packed", counted)
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    out = []
    for frame in rope.frames(14):
        result = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
        assert result.status is FrameStatus.OK, result.message
        out.append((np.array(result.begin), np.array(result.end)))
    assert len(calls) >= 4  # the local path ran
    return out


def test_split_shapes_local_equals_the_kernels_one_by_one(monkeypatch) -> None:
    fused = _shapes(monkeypatch, fused=True)
    stepwise = _shapes(monkeypatch, fused=False)
    for (begin_f, end_f), (begin_s, end_s) in zip(fused, stepwise, strict=True):
        assert begin_f.shape == begin_s.shape and end_f.shape == end_s.shape
        np.testing.assert_allclose(begin_f, begin_s, atol=1e-3)
        np.testing.assert_allclose(end_f, end_s, atol=1e-3)
