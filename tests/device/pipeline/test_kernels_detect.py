"""Kernels that run several stages in one call, against the stages' kernels called one by one."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.contour import ContourTracer
from ropecam.device.pipeline.edges import EdgeDetector, gaussian_weights

pytestmark = pytest.mark.kernel

HEIGHT, WIDTH = 48, 64
NO_MASK = K.Static(*(np.zeros((1, 1), np.uint8) for _ in range(3)), np.zeros(0, np.uint8))
"""`detect_and_trace`'s static mask and learned range when there is none (1x1)."""

_NO_MASK = np.zeros((1, 1), np.uint8)
_NO_MASK.flags.writeable = False
"""No static mask (a 1x1 placeholder)."""


def _rope_frame(seed: int) -> np.ndarray:
    """A bright bent band on a noisy dark ground."""
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0:HEIGHT, 0:WIDTH]
    axis_c = 20.0 + 0.3 * rows + 4.0 * np.sin(rows / 9.0 + seed)
    band = np.clip(3.5 - np.abs(cols - axis_c), 0.0, 1.0) * (rows > 4) * (rows < HEIGHT - 6)
    return np.clip(40.0 + 150.0 * band + rng.normal(0.0, 2.0, band.shape), 0, 255).astype(np.uint8)


def _spans(seed: int, full: bool) -> tuple[np.ndarray, np.ndarray]:
    if full:
        return np.zeros(HEIGHT, np.int32), np.full(HEIGHT, WIDTH - 1, np.int32)
    rng = np.random.default_rng(seed)
    lo = rng.integers(2, 14, HEIGHT).astype(np.int32)
    hi = rng.integers(40, WIDTH - 2, HEIGHT).astype(np.int32)
    hi[:3] = -1  # empty rows
    return lo, hi


def _buffers() -> dict[str, np.ndarray]:
    cap = 4000
    return {
        "work_spans": np.zeros((4, HEIGHT), np.int32),
        "tmp": np.zeros((HEIGHT, WIDTH), np.float32),
        "smooth": np.zeros((HEIGHT, WIDTH), np.float32),
        "gx": np.zeros((HEIGHT, WIDTH), np.float32),
        "gy": np.zeros((HEIGHT, WIDTH), np.float32),
        "mag": np.zeros((HEIGHT, WIDTH), np.float32),
        "edges": np.zeros((HEIGHT, WIDTH), np.uint8),
        "edge_stack": np.zeros(HEIGHT * WIDTH, np.int32),
        "labels": np.zeros((HEIGHT, WIDTH), np.int32),
        "stack": np.zeros(HEIGHT * WIDTH, np.int32),
        "start": np.zeros(2, np.int32),
        "chain": np.zeros((cap, 2), np.int32),
        "codes": np.zeros(cap, np.int32),
        "points": np.zeros((cap, 2), np.float32),
        "counts": np.zeros(4, np.int32),
    }


def _contour(buffers: dict[str, np.ndarray]) -> K.Contour:
    """`trace_rope`'s outputs among `buffers`."""
    return K.Contour(*(buffers[name] for name in ("labels", "stack", "start", "chain", "codes", "points", "counts")))


def _groups(buffers: dict[str, np.ndarray]) -> tuple[K.EdgeWork, K.Planes, K.Contour]:
    """`detect_and_trace`'s groups of `buffers`."""
    work = K.EdgeWork(buffers["work_spans"], buffers["tmp"], buffers["edges"], buffers["edge_stack"])
    return work, K.Planes(*(buffers[name] for name in ("smooth", "gx", "gy", "mag"))), _contour(buffers)


def _ro(a: np.ndarray) -> np.ndarray:
    view = a.view()
    view.flags.writeable = False
    return view


@pytest.mark.parametrize(
    ("seed", "full", "min_pixels"), [(0, True, 10), (1, False, 10), (2, False, 10), (3, True, 5000)]
)
def test_detect_and_trace_is_detect_edges_then_trace_rope(seed: int, full: bool, min_pixels: int) -> None:
    frame = _ro(_rope_frame(seed))
    lo, hi = (_ro(a) for a in _spans(seed, full))
    weights = _ro(gaussian_weights(1.0))
    low, high = np.float32(20.0), np.float32(50.0)
    ref = _buffers()
    count = K.detect_edges(
        frame, weights, lo, hi, low, high, ref["work_spans"], ref["tmp"], ref["smooth"], ref["gx"], ref["gy"],
        ref["mag"], ref["edges"], ref["edge_stack"],
    )  # fmt: skip
    n_ref = K.trace_rope(
        ref["edges"], lo, hi, _ro(ref["edge_stack"]), count, np.int32(min_pixels), True, _NO_MASK, _ro(ref["mag"]),
        _ro(ref["gx"]), _ro(ref["gy"]), _contour(ref),
    )  # fmt: skip
    ref["counts"][3] = count
    assert count > 0
    assert (n_ref > 0) == (min_pixels < 1000)
    writable = frame.copy()  # a frame a reader made, not a read-only buffer: Numba's safe conversion
    for image in (frame, writable):
        got = _buffers()
        n = K.detect_and_trace(image, lo, hi, weights, low, high, np.int32(min_pixels), NO_MASK, *_groups(got))
        assert n == n_ref
        for name, expected in ref.items():
            np.testing.assert_array_equal(got[name], expected, err_msg=name)


def test_smooth_box_takes_both_kinds_of_frame() -> None:
    """A read-only frame (a mapped capture buffer) and a writable one (a frame a reader made) give the same values:
    the writable one goes through Numba's safe mutable-to-read-only conversion to the one signature."""
    frame = _ro(_rope_frame(7))
    weights = _ro(gaussian_weights(1.0))
    lo, hi = (_ro(a) for a in _spans(7, False))
    outputs = []
    for fn, image in ((K.smooth_box, frame), (K.smooth_box, frame.copy())):
        work = (np.zeros(HEIGHT, np.int32), np.zeros(HEIGHT, np.int32))
        tmp, smooth = np.zeros((HEIGHT, WIDTH), np.float32), np.full((HEIGHT, WIDTH), -1.0, np.float32)
        count = fn(image, weights, lo, hi, 0, HEIGHT - 1, 0, 20, *work, tmp, smooth)
        outputs.append((count, smooth))
    assert outputs[0][0] > 0
    for count, smooth in outputs[1:]:
        assert count == outputs[0][0]
        np.testing.assert_array_equal(smooth, outputs[0][1])


def test_detect_and_trace_refuses_short_counts_and_bad_spans() -> None:
    frame = _ro(_rope_frame(4))
    lo, hi = (_ro(a) for a in _spans(4, True))
    weights = _ro(gaussian_weights(1.0))
    buffers = _buffers()
    args = _groups(buffers)
    short = _groups({**buffers, "counts": np.zeros(3, np.int32)})
    low, high, min_px = np.float32(20.0), np.float32(50.0), np.int32(10)
    assert K.detect_and_trace(frame, lo, hi, weights, low, high, min_px, NO_MASK, *short) == K.INVALID
    bad_lo = _ro(np.zeros(HEIGHT - 1, np.int32))
    assert K.detect_and_trace(frame, bad_lo, hi, weights, low, high, min_px, NO_MASK, *args) == K.INVALID
    assert buffers["counts"].tolist() == [0, 0, 0, K.INVALID]


def test_tracer_detect_and_trace_equals_detect_then_trace() -> None:
    frames = [_ro(_rope_frame(seed)) for seed in (5, 6)]
    spans = [tuple(_ro(a) for a in _spans(seed, full)) for seed, full in ((5, False), (6, True))]
    one = (EdgeDetector(HEIGHT, WIDTH, 1.0, 20.0, 50.0), ContourTracer(HEIGHT, WIDTH, 4000, 10))
    fused = (EdgeDetector(HEIGHT, WIDTH, 1.0, 20.0, 50.0), ContourTracer(HEIGHT, WIDTH, 4000, 10))
    for frame, (lo, hi) in zip(frames, spans, strict=True):
        edges, tracer = one
        edges.detect(frame, lo, hi)
        n = tracer.trace(edges.edges, lo, hi, edges.mag_ro, edges.gx_ro, edges.gy_ro, edges.stack_ro, edges.count)
        assert n > 0
        assert fused[1].detect_and_trace(fused[0], frame, lo, hi) == n
        assert fused[0].frame is frame
        for name in ("edges", "gx", "gy", "mag", "smooth", "count"):
            np.testing.assert_array_equal(getattr(fused[0], name), getattr(edges, name), err_msg=name)
        assert fused[0].spans[0] is lo and fused[0].spans[1] is hi
        for name in ("chain", "codes", "points", "count", "component_px", "contacts", "on_border"):
            np.testing.assert_array_equal(getattr(fused[1], name), getattr(tracer, name), err_msg=name)
    with pytest.raises(ValueError, match="frame shape"):
        fused[1].detect_and_trace(fused[0], _ro(np.zeros((HEIGHT, WIDTH + 1), np.uint8)), lo, hi)
