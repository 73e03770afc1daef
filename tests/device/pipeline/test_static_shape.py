"""`static_shape` (the blur split's static fallback in one call) against the kernels it calls, one by one, in the
order the stage once called them from Python."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import Method

pytestmark = pytest.mark.kernel


def _copy(value: object) -> object:
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, tuple) and hasattr(value, "_fields"):
        return type(value)(*(_copy(v) for v in value))
    return value


def _captured(monkeypatch: pytest.MonkeyPatch) -> list[tuple]:
    """Copies of the arguments of every `static_shape` call of a pipeline over a slowly swinging rope (its frames
    near the turning points are static), with the pipeline's outcome's shape."""
    calls: list[tuple] = []
    real = K.static_shape

    def spy(*args):
        calls.append(tuple(_copy(a) for a in args))
        return real(*args)

    monkeypatch.setattr(K, "static_shape", spy)
    rope = SyntheticRope(exposure_us=4000, amplitude_rad=0.3, period_s=2.0, diameter_px=3.0, phase_rad=1.4, fps=119.0)
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    methods = [pipeline.process(f.image, f.index, f.t_ns, f.exposure_us).method for f in rope.frames(12)]
    monkeypatch.undo()
    assert Method.STATIC_FALLBACK in methods
    return calls


def _one_by_one(args: tuple) -> tuple[int, np.ndarray, np.ndarray]:
    """The centreline as the kernels one by one make it (the stage's Python sequence before `static_shape`):
    the status, the shape and the segmentation points."""
    points, chain, n, gx, gy, smooth, polarity, width, fixed, fixed_r, fixed_c, buffers = args
    if n < 8:
        return K.NOT_FOUND, np.empty((0, 2), np.float32), buffers.seg
    K.turning_angles(points, n, np.int32(max(3, round(width.width64_px))), buffers.turn)
    min_dist = np.float32(2.0 * width.width64_px + 2.0)
    if K.find_caps(buffers.turn, points, n, np.int32(max(4, n // 8)), min_dist, buffers.idx) < 0:
        return K.NOT_FOUND, np.empty((0, 2), np.float32), buffers.seg
    e1, e2 = np.int32(buffers.idx[0]), np.int32(buffers.idx[1])
    if fixed:
        d1 = np.hypot(points[e1, 0] - fixed_r, points[e1, 1] - fixed_c)
        d2 = np.hypot(points[e2, 0] - fixed_r, points[e2, 1] - fixed_c)
        if d2 < d1:
            e1, e2 = e2, e1
    side_a, out_a = buffers.sides[0], buffers.sides[2]
    direction = np.int32(-1 if (e2 - e1 + n) % n > 0.7 * n else 1)
    count = K.offset_by_gradient(
        points, chain, n, e1, e2, direction, gx, gy, polarity, width.width_px, np.float32(0.0), side_a
    )
    if count < 2:
        return K.NOT_FOUND, np.empty((0, 2), np.float32), buffers.seg
    count = K.extend_to_band_end(
        side_a, np.int32(count), points, n, smooth, width.width_px, width.cap_px, width.skip_px, width.span_px,
        width.blur_px, np.float32(0.0), np.float32(0.0),
    )  # fmt: skip
    if fixed:
        through = np.int32(1 if width.through_fixed else 0)
        count = K.anchor_start(side_a, np.int32(count), fixed_r, fixed_c, width.skip_px, width.span_px, through)
    buffers.seg[0] = points[e2]
    buffers.seg[1] = points[e2]
    count = K.resample_polyline(side_a, np.int32(count), width.out_step_px, out_a)
    if width.smoothing_px > 0.0 and count >= 3:
        K.smooth_polyline(out_a, np.int32(count), width.smoothing_px, buffers.scratch[0], side_a)
        return count, side_a[:count].copy(), buffers.seg
    return count, out_a[:count].copy(), buffers.seg


def test_static_shape_equals_the_kernels_one_by_one(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _captured(monkeypatch)
    assert len(calls) >= 2
    for args in calls:
        for fixed in (True, False):  # with the fixed end the pipeline knew, and without one
            ours = _copy((*args[:8], fixed, *args[9:]))
            theirs = _copy((*args[:8], fixed, *args[9:]))
            count = K.static_shape(*ours)
            expected, shape, seg = _one_by_one(theirs)
            assert count == expected
            buffers = ours[-1]
            got = buffers.sides[0 if buffers.info[4] else 2][:count]
            assert buffers.info[0] == count
            np.testing.assert_array_equal(got, shape)
            np.testing.assert_array_equal(buffers.seg, seg)


def test_static_shape_has_none_for_a_short_contour(monkeypatch: pytest.MonkeyPatch) -> None:
    args = _captured(monkeypatch)[0]
    assert K.static_shape(*args[:2], np.int32(7), *args[3:]) == K.NOT_FOUND
