"""The paper's method: chain thinning and direction-free scoring against slow references, and the stage end to end
on synthetic blurred frames (the centreline baseline it falls back to: test_centerline.py)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.paper_method import PaperSegmenter
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus, Method
from ropecam.shared.errors import ConfigError

UNIQUE_TAUS = {0, 1, -1, 5, -5, 2, -2, 3, -3, 4, -4, 9, -9}
"""tau on a thinned chain: straight, the four diagonal 90-degree and the eight 135-degree connections of eq. (3)."""


def _outer_chain(mask: np.ndarray) -> np.ndarray:
    """The outer boundary of the largest component of `mask`, traced by the pipeline's kernels."""
    height, width = mask.shape
    lo, hi = np.zeros(height, np.int32), np.full(height, width - 1, np.int32)
    edges = mask.astype(np.uint8).copy()
    labels, stack, start = np.zeros(mask.shape, np.int32), np.zeros(mask.size, np.int32), np.zeros(2, np.int32)
    assert K.keep_largest_component(edges, lo, hi, 1, labels, stack, start) > 0
    chain = np.zeros((4 * mask.size, 2), np.int32)
    codes = np.zeros(4 * mask.size, np.int32)
    n = K.trace_contour(edges, lo, hi, start[0], start[1], chain, codes)
    return chain[:n].copy()


def _thin_reference(chain: np.ndarray) -> list[tuple[int, int]]:
    """Slow and obvious: merge repeats and drop any pixel whose (distinct) cyclic neighbours touch, one at a time,
    until none."""
    pts = [tuple(p) for p in chain.tolist()]
    changed = True
    while changed and len(pts) >= 3:
        changed = False
        for i in range(len(pts)):
            prev, here, nxt = pts[i - 1], pts[i], pts[(i + 1) % len(pts)]
            if here == prev or (prev != nxt and max(abs(prev[0] - nxt[0]), abs(prev[1] - nxt[1])) <= 1):
                del pts[i]
                changed = True
                break
    return pts


def _canny_loop(seed: int) -> np.ndarray:
    """The Canny edge loop of a blurred, noisy, thick curved band (as the pipeline sees a swept rope)."""
    rng = np.random.default_rng(seed)
    image = np.full((90, 120), 30.0)
    cv2.ellipse(image, (60, 45), (40, 22), float(rng.uniform(0, 180)), 0, 300, 200.0, int(rng.integers(3, 9)))
    image = cv2.GaussianBlur(image, (0, 0), 1.5) + rng.normal(0, 2.0, image.shape)
    return (cv2.Canny(np.clip(image, 0, 255).astype(np.uint8), 40, 100, L2gradient=True) > 0).astype(np.uint8)


@pytest.mark.kernel
@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_thin_chain_leaves_a_single_pixel_curve_with_unique_taus(seed) -> None:
    chain = _outer_chain(_canny_loop(seed))
    out = np.zeros_like(chain)
    index = np.zeros(len(chain), np.int32)
    m = K.thin_chain(chain, len(chain), out, index)
    assert m > 20
    thin = out[:m]
    np.testing.assert_array_equal(thin, chain[index[:m]])  # every pixel kept is an input pixel, in order
    steps = np.abs(np.diff(np.vstack([thin, thin[:1]]), axis=0)).max(axis=1)
    assert set(steps.tolist()) == {1}  # 8-connected, closed, no repeats
    gap = np.abs(np.roll(thin, 1, axis=0) - np.roll(thin, -1, axis=0)).max(axis=1)
    closed = gap.min() > 0  # an open outline is traced out and back: it turns on pixels with gap 0
    assert not np.any(gap == 1)  # no pixel's distinct neighbours touch: nothing left to drop
    tau = np.zeros(m, np.int32)
    K.apply_operator(thin, m, tau)
    if closed:
        assert set(tau.tolist()) <= UNIQUE_TAUS
    assert sorted(map(tuple, thin.tolist())) == sorted(_thin_reference(chain))


@pytest.mark.kernel
def test_thin_chain_drops_spurs_corners_and_spikes() -> None:
    # A 5x5 square outline traced clockwise with a one-pixel spur out of its top side, and a 4-connected corner.
    chain = np.array(
        [[0, 0], [0, 1], [0, 2], [-1, 2], [0, 2], [0, 3], [0, 4], [1, 4], [2, 4], [3, 4], [4, 4], [4, 3], [4, 2],
         [4, 1], [4, 0], [3, 0], [2, 0], [1, 0]],
        np.int32,
    )  # fmt: skip
    out = np.zeros((32, 2), np.int32)
    index = np.zeros(32, np.int32)
    m = K.thin_chain(chain, len(chain), out, index)
    assert sorted(map(tuple, out[:m].tolist())) == sorted(_thin_reference(chain))
    kept = set(map(tuple, out[:m].tolist()))
    assert (-1, 2) not in kept  # a one-pixel spur: its return pixel is a 45-degree corner, then the spur goes
    assert (0, 0) not in kept  # the 4-connected corner of the square: dropped
    assert K.thin_chain(chain, len(chain), np.zeros((4, 2), np.int32), index) == K.FULL


@pytest.mark.kernel
def test_scores_do_not_depend_on_the_direction_of_the_chain() -> None:
    chain = _outer_chain(_canny_loop(5))
    out = np.zeros_like(chain)
    index = np.zeros(len(chain), np.int32)
    m = K.thin_chain(chain, len(chain), out, index)
    scores_by_pixel = []
    for thin in (out[:m].copy(), out[:m][::-1].copy()):
        tau = np.zeros(m, np.int32)
        K.apply_operator(thin, m, tau)
        knots, scores = np.zeros(m, np.int32), np.zeros(m, np.float32)
        k = K.score_knots(thin, tau, m, 45.0, 20.0, 50.0, 100.0, 20.0, knots, scores)
        scores_by_pixel.append({tuple(thin[knots[j]]): float(scores[j]) for j in range(k)})
    assert scores_by_pixel[0] == scores_by_pixel[1]
    assert max(scores_by_pixel[0].values()) >= 2.0


def test_stages_refuse_bad_arguments() -> None:
    with pytest.raises(ValueError, match="endpoint_radius_px"):
        PaperSegmenter(100, endpoint_radius_px=0.0)
    with pytest.raises(ConfigError, match="paper_endpoint_radius_scaled"):
        PipelineConfig(paper_endpoint_radius_scaled="yes")  # type: ignore[arg-type]


def _tip_errors(frame, r) -> tuple[float, float]:
    begin, end = r.begin[-1, ::-1], r.end[-1, ::-1]
    straight = np.hypot(*(begin - frame.tip_begin_uv)) + np.hypot(*(end - frame.tip_end_uv))
    swapped = np.hypot(*(begin - frame.tip_end_uv)) + np.hypot(*(end - frame.tip_begin_uv))
    if swapped < straight:
        begin, end = end, begin
    return float(np.hypot(*(begin - frame.tip_begin_uv))), float(np.hypot(*(end - frame.tip_end_uv)))


@pytest.mark.parametrize("scaled", [True, False])
def test_paper_method_finds_the_tips_within_the_papers_errors(fast_rope, fast_frames, scaled) -> None:
    config = PipelineConfig(method="paper", paper_endpoint_radius_scaled=scaled)
    pipeline = Pipeline(config, (fast_rope.width, fast_rope.height))
    errors = []
    split = 0
    for frame in fast_frames:
        r = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
        # The first split of a stream that starts mid-swing: its time order undecided, kept but not trusted.
        assert r.status is FrameStatus.OK or (frame.index, r.reason) == (0, "order"), r.message
        assert r.method in (Method.PAPER, Method.CENTERLINE)  # the centreline where no two points are found
        if r.method is Method.PAPER:
            split += 1
            assert r.segmentation_points is not None and r.segmentation_points.shape == (2, 2)
            errors.extend(_tip_errors(frame, r))
    assert split >= len(fast_frames) - 2
    # The paper: mean 0.9-2 px, max 5-6 px (its Table 4) on integer pixels of the band's corners.
    assert np.mean(errors) < 2.0
    assert np.max(errors) < 4.0
