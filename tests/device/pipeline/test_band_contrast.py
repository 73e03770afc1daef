"""The rope's contrast read across the band at each point of a side (`contrast_gains`), and a rope whose brightness
varies along its length measured through the whole pipeline."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus
from ropecam.device.pipeline.split import BlurSplitter
from ropecam.device.pipeline.width_tables import LOCAL_CONTRAST_MAX_BLUR_PX


def _band(contrast_of_col, rows=40, cols=120, top=15.3, width=3.0, background=30.0):
    """A still, horizontal bright rope between rows `top` and `top` + `width` (pixel r covers [r - 0.5, r + 0.5]),
    its contrast per column; its upper side as a contour (subpixel points on the edge, chain pixels, gradients
    pointing down, into the rope)."""
    r = np.arange(rows, dtype=np.float64)[:, None]
    cover = np.clip(np.minimum(r + 0.5, top + width) - np.maximum(r - 0.5, top), 0.0, 1.0)
    levels = background + cover * contrast_of_col(np.arange(cols))[None, :]
    frame = np.clip(np.rint(levels), 0, 255).astype(np.uint8)
    n = cols
    points = np.stack([np.full(n, top), np.arange(n, dtype=np.float64)], axis=1).astype(np.float32)
    chain = np.stack([np.full(n, round(top)), np.arange(n)], axis=1).astype(np.int32)
    gy = np.zeros((rows, cols), np.float32)
    gy[chain[:, 0], chain[:, 1]] = 100.0
    gx = np.zeros((rows, cols), np.float32)
    return frame, points, chain, gx, gy


def _gains(frame, points, chain, gx, gy, contrast, sweeps=None, width=3.0, stride=1, applied=True):
    """`contrast_gains` on the band's side; every point read by default (`stride` 1: the gains written whatever
    their spread). Asserts that the gains are to be applied, or not (`applied`)."""
    n = points.shape[0]
    sweeps = np.zeros(n, np.float32) if sweeps is None else sweeps
    work, out = np.zeros(n, np.float32), np.ones(n, np.float64)
    expected = float(np.float32(contrast)) * float(np.float32(width))
    count = K.contrast_gains(points, chain, n, 0, n - 1, 1, frame, gx, gy, np.float32(1.0), sweeps, np.float32(width),
                             expected, stride, work, out)  # fmt: skip
    assert count == (n if applied else 0)
    return out, work


def test_contrast_gains_read_the_rope_s_own_contrast_along_it() -> None:
    period = 80.0

    def contrast(cols):
        return 120.0 * (1.0 + 0.3 * np.sin(2.0 * np.pi * cols / period))

    frame, points, chain, gx, gy = _band(contrast)
    gains, raw = _gains(frame, points, chain, gx, gy, 120.0)
    cap = int(3.0 + 2.0)  # the side's first points (the fixed end's cap) are not read, and take the first average
    assert np.all(np.isnan(raw[:cap])) and np.all(gains[:cap] == gains[cap])
    inner = slice(cap + K.CONTRAST_POINTS, points.shape[0] - K.CONTRAST_POINTS)
    # each raw reading is the contrast at its column (to the frame's rounding)
    np.testing.assert_allclose(raw[inner] / 3.0, contrast(np.arange(points.shape[0]))[inner], rtol=0.03)
    # the gain is the frame's contrast over the local one, the readings averaged over +-CONTRAST_POINTS
    window = 2 * K.CONTRAST_POINTS + 1
    local = np.convolve(contrast(np.arange(points.shape[0])), np.ones(window) / window, mode="same")
    np.testing.assert_allclose(gains[inner], 120.0 / local[inner], rtol=0.03)
    assert gains.min() < 0.85 and gains.max() > 1.3  # the pattern is followed, not flattened
    # read every CONTRAST_STRIDE-th point first, the rope found uneven, then every point: the same gains, bit for bit
    sparse, sparse_raw = _gains(frame, points, chain, gx, gy, 120.0, stride=K.CONTRAST_STRIDE)
    assert sparse.tobytes() == gains.tobytes() and np.array_equal(sparse_raw, raw, equal_nan=True)


@pytest.mark.parametrize(("amplitude", "applied"), [(0.0, False), (0.03, False), (0.1, True), (0.3, True)])
def test_contrast_gains_are_applied_only_where_the_rope_s_brightness_varies(amplitude, applied) -> None:
    """The first readings (every `CONTRAST_STRIDE`-th point) decide: a rope whose contrast varies along the side
    (a sine of relative `amplitude`: spread amplitude / sqrt 2) by less than `MIN_SPREAD` keeps the frame's contrast
    (0 returned, nothing to apply), a more uneven one gets every point's gains."""

    def contrast(cols):
        return 120.0 * (1.0 + amplitude * np.sin(2.0 * np.pi * cols / 60.0))

    frame, points, chain, gx, gy = _band(contrast, cols=240)
    every, _ = _gains(frame, points, chain, gx, gy, 120.0)
    gains, _ = _gains(frame, points, chain, gx, gy, 120.0, stride=K.CONTRAST_STRIDE,
                      applied=applied)  # fmt: skip
    spread = np.std(every[20:-20]) / np.mean(every[20:-20])
    assert (spread > K.MIN_SPREAD) == applied
    if applied:
        assert gains.tobytes() == every.tobytes()


def test_contrast_gains_keep_the_frame_s_contrast_where_they_cannot_read() -> None:
    frame, points, chain, gx, gy = _band(lambda cols: np.full(cols.shape, 120.0))
    n = points.shape[0]
    # a uniform rope: gain 1 wherever read, and not applied once it is found even
    gains, _ = _gains(frame, points, chain, gx, gy, 120.0)
    np.testing.assert_allclose(gains, 1.0, atol=0.02)
    _gains(frame, points, chain, gx, gy, 120.0, stride=K.CONTRAST_STRIDE, applied=False)
    # ... unless it is evenly brighter than the frame's contrast says (a flickering light): every point's gains
    brighter, _ = _gains(frame, points, chain, gx, gy, 110.0, stride=K.CONTRAST_STRIDE)
    np.testing.assert_allclose(brighter[K.CONTRAST_POINTS : -K.CONTRAST_POINTS], 110.0 / 120.0, rtol=0.02)
    # sweeps beyond the reach: nothing read, the frame's contrast
    far = np.full(n, np.float32(K.band_contrast.REACH_WIDTHS * 3.0 + 1.0))
    _, raw = _gains(frame, points, chain, gx, gy, 120.0, sweeps=far, applied=False)
    assert np.all(np.isnan(raw))
    # ... from where the sweep passes it on
    far[:60] = 0.0
    gains, raw = _gains(frame, points, chain, gx, gy, 120.0, sweeps=far)
    assert (
        np.all(np.isfinite(raw[5:60])) and np.all(np.isnan(raw[60:])) and np.all(gains[60 + K.CONTRAST_POINTS :] == 1)
    )
    # a reading that is not the rope's (a contrast 3x the frame's): dropped
    _, raw = _gains(frame, points, chain, gx, gy, 40.0, applied=False)
    assert np.all(np.isnan(raw))
    # no frame (a split without one), no rope width (a strong lens blur): nothing read
    _gains(np.zeros((0, 0), np.uint8), points, chain, gx, gy, 120.0, applied=False)
    _gains(frame, points, chain, gx, gy, 120.0, width=0.0, applied=False)
    # sections leaving the frame are not read
    _, raw = _gains(frame[:16], points, chain, gx, gy, 120.0, applied=False)
    assert np.all(np.isnan(raw))
    work, out = np.zeros(n - 1, np.float32), np.zeros(n, np.float64)
    flat = np.zeros(n, np.float32)
    assert K.contrast_gains(points, chain, n, 0, n - 1, 1, frame, gx, gy, np.float32(1.0), flat, np.float32(3.0),
                            360.0, 1, work, out) == K.FULL  # fmt: skip


def _centreline_errors(rope: SyntheticRope, frames: int = 18) -> tuple[float, float]:
    """Mean distance of the true centrelines' points to ours over frames 12 on (the contrast settled, the steady
    path), over the first 40 % of the rope (where it sweeps less than its width) and over all of it."""
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    errors = []
    for frame in rope.frames(frames):
        result = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
        if frame.index < 12:
            continue
        assert result.status is FrameStatus.OK, result.message
        for ours, truth in ((result.begin, frame.begin_uv), (result.end, frame.end_uv)):
            poly = np.asarray(ours)[:, ::-1].astype(np.float64)
            a, d = poly[:-1][None], np.diff(poly, axis=0)[None]
            p = truth[:, None]
            t = np.clip(((p - a) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-12), 0.0, 1.0)
            errors.append(np.min(np.hypot(*(p - (a + t[..., None] * d)).transpose(2, 0, 1)), axis=1))
    e = np.array(errors)
    return float(e[:, : e.shape[1] * 2 // 5].mean()), float(e.mean())


@pytest.mark.jit_only  # a pipeline over 2 x 18 frames
def test_an_uneven_rope_measures_nearly_as_an_even_one() -> None:
    # A 3 px rope swinging with sweeps below its width over its first part, its brightness +-30 % along it (an
    # 80 px pattern that moves with the rope). With one contrast per frame the sweep there was misread: the shapes
    # were pushed apart along one stretch and together along the next.
    rope = SyntheticRope(diameter_px=3.0, noise_dn=1.0, phase_rad=1.2)
    even_near, even_all = _centreline_errors(rope)
    near, whole = _centreline_errors(replace(rope, unevenness=0.3, unevenness_period_px=80.0))
    print(f"even rope: first 40 % {even_near:.3f} px, all {even_all:.3f}; uneven: {near:.3f}, {whole:.3f}")
    # measured: even 0.12 / 0.07 px (its readings not applied: 0.11 / 0.06 with them), uneven 0.26 / 0.16 px
    # (with the frame's contrast alone: 0.84 / 0.63 px)
    assert near < 0.35 and whole < 0.25
    # the even rope keeps its accuracy next to the fixed end (0.16 px when the cap's readings counted, 0.12 with
    # the frame's contrast alone)
    assert even_near < 0.14 and even_all < 0.09


def _split_with_and_without_the_frame(rope: SyntheticRope) -> tuple[bool, ...]:
    """Run a pipeline over 14 frames of `rope`, then its last frame's `split_shapes` again with the frame (the
    rope's contrast read along the band) and without one (the frame's contrast alone); whether each output (the
    four shape buffers, the counts and lengths) came out the same, bit for bit."""
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    pipeline.one_call = False  # each frame's split through `split_frame`, its inputs kept in its arguments
    for frame in rope.frames(14):
        result = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
    assert result.status is FrameStatus.OK, result.message
    args = pipeline.splitter.frame_call._args
    points, chain, planes, image, width, index, state, buffers = (args[i] for i in (3, 4, 5, 6, 13, 14, 15, 16))
    assert width.rope_px > 0.0
    s = K.FRAME_STATE
    outputs = []
    for frame_read in (image, np.zeros((0, 0), np.uint8)):
        status = K.split_shapes(
            points, chain, int(state[s.n]), *(int(buffers.idx[i]) for i in (0, 1, 3)), planes, frame_read,
            np.float32(1.0 / state[s.contrast]), np.float32(state[s.polarity]), width, index,
            np.float32(state[s.fixed_r]), np.float32(state[s.fixed_c]), np.zeros(0), buffers,
        )  # fmt: skip
        assert status == 2
        outputs.append((*buffers.sides.copy(), buffers.info[:6].copy()))
    return tuple(np.array_equal(a, b) for a, b in zip(*outputs, strict=True))


@pytest.mark.jit_only  # a pipeline over 14 frames
@pytest.mark.parametrize(("unevenness", "same"), [(0.0, True), (0.3, False)])
def test_an_even_rope_is_split_as_without_the_readings(unevenness, same) -> None:
    """On an evenly bright rope the readings along the band are not applied: `split_shapes` with the frame makes the
    same shapes, bit for bit, as without one (the sweeps read with the frame's contrast alone); on a rope whose
    brightness varies +-30 % along it they are applied, and the shapes move."""
    rope = SyntheticRope(diameter_px=3.0, noise_dn=1.0, phase_rad=1.2, unevenness=unevenness, unevenness_period_px=80.0)
    equal = _split_with_and_without_the_frame(rope)
    assert all(equal) if same else not all(equal[:4])


def test_the_rope_contrast_is_read_along_the_band_only_under_a_mild_lens_blur() -> None:
    """Under a lens blur whose tail reaches the background's samples (`LOCAL_CONTRAST_MAX_BLUR_PX`, 0.53 px) the
    split keeps the frame's contrast: its width tables carry no rope width for `contrast_gains` (simulated PSF 1.2
    and 2 px rows read the rope's contrast low, their centrelines 0.30 and 0.69 px off with it, 0.08 and 0.10
    without)."""
    assert 0.5 < LOCAL_CONTRAST_MAX_BLUR_PX < 0.55
    mild = BlurSplitter(2000, lens_blur_px=0.4)._constants(3.0)
    strong = BlurSplitter(2000, lens_blur_px=1.2)._constants(3.0)
    assert mild.rope_px == pytest.approx(float(mild.tables.width_px)) and mild.rope_px > 1.0
    assert mild.group.rope_px == mild.rope_px
    assert strong.rope_px == 0.0 and strong.group.rope_px == 0.0
