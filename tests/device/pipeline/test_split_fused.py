"""The blur split's one-call paths against the same kernels called one by one: `split_frame` (a steady frame:
segmentation points, the corner box's smoothing, the sweep, the shapes) and `split_shapes` (the shapes from the
segmentation points)."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus

pytestmark = pytest.mark.kernel

_FRAMES = 14
"""Frames of the swinging rope: the contrast (hence the local sweeps and `split_frame`) is known from frame 10."""


def _rope() -> SyntheticRope:
    return SyntheticRope(exposure_us=4000, amplitude_rad=0.6, period_s=0.9, diameter_px=3.0, phase_rad=1.5, fps=119.0)


_RUNS: dict[tuple[str, bool, bool], list[tuple]] = {}
"""`_shapes`'s results (each run is a pipeline over `_FRAMES` frames: slow without JIT)."""
_LAST_ARGS: list[tuple] = []
"""Copies of the arguments of the last `split_frame` call of the ``frame`` run."""


def _shapes(monkeypatch: pytest.MonkeyPatch, path: str, garbage: bool = False, read_only: bool = False) -> list[tuple]:
    """(sweep, begin, end) of each frame, the split made by `path`: ``frame`` (`split_frame`), ``packed`` (its
    steps before the shapes one by one, then `split_shapes`) or ``steps`` (every step one by one: both
    one-call kernels report a full buffer). With `garbage`, the edge stage's planes are overwritten before every
    frame (the split must make the smoothed image it reads beyond the band itself). With `read_only`, the frames
    are read-only arrays (a mapped capture buffer; `split_frame` takes both, a writable one through Numba's safe
    conversion)."""
    if (path, garbage, read_only) in _RUNS:
        return _RUNS[(path, garbage, read_only)]
    calls = {"split_frame": 0, "split_shapes": 0}
    for name in calls:
        real = getattr(K, name)

        def counted(*args, _real=real, _name=name):
            calls[_name] += 1
            if path == "frame" and _name == "split_frame" and not garbage and not read_only:
                _LAST_ARGS[:] = [tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args)]
            if path == "steps" or (path == "packed" and _name == "split_frame"):
                return K.FULL  # the stage then redoes the steps one by one
            return _real(*args)

        monkeypatch.setattr(K, name, counted)
    rope = _rope()
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    out = []
    for frame in rope.frames(_FRAMES):
        if garbage:
            for plane in (pipeline.edges.smooth, pipeline.edges.tmp):
                plane[:] = 1000.0
        image = frame.image
        if read_only:
            image = image.copy()
            image.flags.writeable = False
        result = pipeline.process(image, frame.index, frame.t_ns, frame.exposure_us)
        # The first split of a stream that starts mid-swing: its time order undecided, kept but not trusted.
        assert result.status is FrameStatus.OK or (frame.index, result.reason) == (0, "order"), result.message
        out.append((pipeline.splitter.sweep_px, np.array(result.begin), np.array(result.end)))
    assert calls["split_frame"] >= 3  # the steady path ran
    if path != "frame":
        assert calls["split_shapes"] >= 4  # and its fallback
    _RUNS[(path, garbage, read_only)] = out
    return out


def _assert_same(got: list[tuple], want: list[tuple], atol: float) -> None:
    for (sweep_g, begin_g, end_g), (sweep_w, begin_w, end_w) in zip(got, want, strict=True):
        assert sweep_g == pytest.approx(sweep_w, abs=1e-9)
        assert begin_g.shape == begin_w.shape and end_g.shape == end_w.shape
        np.testing.assert_allclose(begin_g, begin_w, atol=atol)
        np.testing.assert_allclose(end_g, end_w, atol=atol)


def test_split_frame_equals_its_steps(monkeypatch) -> None:
    # The same kernels in the same order on the same values: equal up to the sweep's hypot (libm vs Python's).
    _assert_same(_shapes(monkeypatch, "frame"), _shapes(monkeypatch, "packed"), atol=1e-5)


@pytest.mark.jit_only  # 13 s without JIT; the shape kernels one by one have their own reference tests
def test_split_shapes_equals_the_kernels_one_by_one(monkeypatch) -> None:
    _assert_same(_shapes(monkeypatch, "packed"), _shapes(monkeypatch, "steps"), atol=1e-3)


@pytest.mark.jit_only  # 16 s more without JIT: the equality test above runs the kernels in plain Python
def test_split_frame_makes_the_smoothed_image_it_reads(monkeypatch) -> None:
    # As test_pipeline_state's garbage test, over the frames where the steady path runs.
    _assert_same(_shapes(monkeypatch, "frame", garbage=True), _shapes(monkeypatch, "frame"), atol=0.0)


@pytest.mark.jit_only
def test_split_frame_takes_read_only_frames(monkeypatch) -> None:
    _assert_same(_shapes(monkeypatch, "frame", read_only=True), _shapes(monkeypatch, "frame"), atol=0.0)


def test_split_frame_refuses_short_arrays(monkeypatch) -> None:
    _shapes(monkeypatch, "frame")
    recorded = _LAST_ARGS[0]
    state, buffers = 12, 13  # `split_frame`'s arguments
    args = list(recorded)
    args[state] = np.zeros(len(K.FRAME_STATES) - 1)
    assert K.split_frame(*args) == K.INVALID
    args = list(recorded)
    args[buffers] = recorded[buffers]._replace(info=np.zeros(K.FRAME_INFO - 1))
    assert K.split_frame(*args) == K.INVALID
    args = list(recorded)
    for n in (-1, recorded[0].shape[0] + 1):  # the count out of the contour's buffers
        args[state] = recorded[state].copy()
        args[state][K.FRAME_STATE.n] = n
        assert K.split_frame(*args) == K.INVALID
