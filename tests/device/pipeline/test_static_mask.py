"""The static mask: its kernels against slow references, the mask file's errors, and the pipeline with a mask of a
clamp rod that otherwise joins the rope's contour to the image border."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.device.capture.mask_file import read_mask_png
from ropecam.device.capture.synthetic import SyntheticFrame, SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus
from ropecam.device.pipeline.static_mask import StaticMask
from ropecam.device.pipeline.workspace import EdgeBuffers
from ropecam.shared.errors import ConfigError


def _ro(a: np.ndarray) -> np.ndarray:
    view = a.view()
    view.flags.writeable = False
    return view


_NO_NEAR = _ro(np.zeros(0, np.uint8))  # no summary of the mask: the kernels read it everywhere


def _near(mask: np.ndarray) -> np.ndarray:
    """The mask's summary (`mark_near_blocks`)."""
    near = np.zeros(K.near_blocks(*mask.shape), np.uint8)
    assert K.mark_near_blocks(_ro(mask), near) == np.count_nonzero(near)
    return _ro(near)


def _frames(seed: int, count: int, shape: tuple[int, int] = (24, 32)) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, shape).astype(np.uint8) for _ in range(count)]


@pytest.mark.kernel
def test_learn_static_range_is_the_min_and_max_over_frames() -> None:
    frames = _frames(0, 4)
    low, high = np.full(frames[0].shape, 255, np.uint8), np.zeros(frames[0].shape, np.uint8)
    for frame in frames:
        assert K.learn_static_range(_ro(frame), low, high) == frame.size
    np.testing.assert_array_equal(low, np.min(frames, axis=0))
    np.testing.assert_array_equal(high, np.max(frames, axis=0))
    assert K.learn_static_range(_ro(frames[0][:, :-1].copy()), low, high) == -1


@pytest.mark.kernel
def test_mark_static_matches_a_slow_reference() -> None:
    frames = _frames(1, 3)
    low, high = np.min(frames, axis=0), np.max(frames, axis=0)
    mask = np.zeros(low.shape, np.uint8)
    mask[0, :5] = K.MASK_ALWAYS
    base, relative, margin = 30.0, 0.1, 4
    expected_mask = mask.copy()
    expected_low, expected_high = low.astype(int), high.astype(int)
    for r, c in np.ndindex(low.shape):
        if mask[r, c] != K.MASK_ALWAYS:
            still = expected_high[r, c] - expected_low[r, c] <= base + relative * expected_high[r, c]
            expected_mask[r, c] = K.MASK_STATIC if still else K.MASK_FREE
    count = K.mark_static(low, high, base, relative, np.int32(margin), mask)
    assert count == np.count_nonzero(expected_mask == K.MASK_STATIC) > 0
    np.testing.assert_array_equal(mask, expected_mask)
    np.testing.assert_array_equal(low, np.maximum(expected_low - margin, 0))
    np.testing.assert_array_equal(high, np.minimum(expected_high + margin, 255))


def _drop_reference(frame, mask, low, high, edge_list):  # type: ignore[no-untyped-def]
    width = frame.shape[1]
    kept = []
    for k in edge_list:
        r, c = divmod(int(k), width)
        if mask[r, c] == K.MASK_ALWAYS:
            continue
        if mask[r, c] == K.MASK_STATIC:
            window = (slice(max(r - 1, 0), r + 2), slice(max(c - 1, 0), c + 2))
            inside = (frame[window] >= low[window]) & (frame[window] <= high[window])
            if inside.all():
                continue
        kept.append(k)
    return kept


@pytest.mark.kernel
@pytest.mark.parametrize("seed", [2, 3, 4])
def test_drop_static_edges_matches_a_slow_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (24, 32)
    frame = rng.integers(0, 256, shape).astype(np.uint8)
    low = np.clip(frame.astype(int) - rng.integers(-20, 60, shape), 0, 255).astype(np.uint8)
    high = np.clip(frame.astype(int) + rng.integers(-20, 60, shape), 0, 255).astype(np.uint8)
    mask = rng.choice(np.array([K.MASK_FREE, K.MASK_ALWAYS, K.MASK_STATIC], np.uint8), shape, p=[0.3, 0.1, 0.6])
    edge_list = np.zeros(frame.size, np.int32)
    listed = rng.choice(frame.size, 200, replace=False).astype(np.int32)
    edge_list[:200] = listed
    edges = np.zeros(shape, np.uint8)
    edges.reshape(-1)[listed] = 1
    expected = _drop_reference(frame, mask, low, high, listed)
    for image, near in ((_ro(frame), _NO_NEAR), (frame.copy(), _NO_NEAR), (_ro(frame), _near(mask))):
        got_edges, got_list = edges.copy(), edge_list.copy()
        kept = K.drop_static_edges(image, _ro(mask), _ro(low), _ro(high), near, got_edges, got_list, 200)
        assert 0 < kept < 200
        assert got_list[:kept].tolist() == expected
        expected_edges = np.zeros(shape, np.uint8)
        expected_edges.reshape(-1)[expected] = 1
        np.testing.assert_array_equal(got_edges, expected_edges)
    placeholder = _ro(np.zeros((1, 1), np.uint8))
    assert (
        K.drop_static_edges(_ro(frame), placeholder, placeholder, placeholder, _NO_NEAR, edges, edge_list, 200) == 200
    )


@pytest.mark.kernel
@pytest.mark.parametrize("seed", [9, 10])
def test_mark_near_blocks_marks_every_block_next_to_a_masked_pixel(seed: int) -> None:
    """A block is marked when a pixel of it, or a neighbour on the flat array, is masked: never a block with a
    masked pixel or 2-D neighbour unmarked (the kernels skip those), and few more."""
    rng = np.random.default_rng(seed)
    height, width = 24, 40  # 960 pixels: 15 blocks, rows not aligned with them
    mask = np.zeros((height, width), np.uint8)
    for _ in range(3):
        r, c = int(rng.integers(0, height)), int(rng.integers(0, width))
        mask[r, c] = rng.choice([K.MASK_ALWAYS, K.MASK_STATIC])
    mask[height - 1, width - 1] = K.MASK_STATIC  # the last pixel: the last block and the one a row above
    near = _near(mask)
    assert near.shape == (15,)
    grown = cv2.dilate((mask != K.MASK_FREE).astype(np.uint8), np.ones((3, 3), np.uint8)).ravel()
    flat = (mask != K.MASK_FREE).ravel()
    for b in range(15):
        block = slice(b * K.NEAR_BLOCK, (b + 1) * K.NEAR_BLOCK)
        if grown[block].any():
            assert near[b] == 1
        around = np.zeros(height * width, bool)
        for shift in (-width, 0, width):
            lo, hi = max(b * 64 + shift - 1, 0), min((b + 1) * 64 - 1 + shift + 1, height * width - 1)
            if lo <= hi:
                around[lo : hi + 1] = True
        assert near[b] == int(flat[around].any())
    assert K.mark_near_blocks(_ro(mask), np.zeros(14, np.uint8)) == -1


def test_static_mask_learns_then_marks_only_still_pixels() -> None:
    buffers = EdgeBuffers.make(24, 32, np.ones(1, np.float32))
    given = np.zeros((24, 32), bool)
    given[0, 0] = True
    mask = StaticMask(buffers, frames=3, margin_dn=2, relative=0.0, mask=given)
    base = np.full((24, 32), 50, np.uint8)
    for shift in range(3):
        frame = base.copy()
        frame[10:14, 4 + 8 * shift : 8 + 8 * shift] = 200  # a block that moves: never static
        assert mask.learning
        mask.learn(frame)
    assert mask.learning  # marked on the next frame, which is not learned from
    mask.learn(np.zeros((24, 32), np.uint8))
    assert not mask.learning
    static = mask.static()
    assert static[0, 0] and static[0, 5] and not static[11, 5] and not static[11, 21]
    assert mask.static_px == static.size - 1 - 3 * 16
    np.testing.assert_array_equal(buffers.static_near, _near(buffers.static_mask))  # summarised after each write
    region = np.zeros((24, 32), bool)
    region[11, 21] = True
    mask.add_structure(region)
    np.testing.assert_array_equal(buffers.static_near, _near(buffers.static_mask))


def test_mask_png_must_exist_and_have_the_frames_size(tmp_path: Path) -> None:
    path = tmp_path / "mask.png"
    with pytest.raises(ConfigError, match=r"static_mask_png.*does not exist"):
        read_mask_png(path, (24, 32))
    cv2.imwrite(str(path), np.zeros((20, 32), np.uint8))
    with pytest.raises(ConfigError, match=r"static_mask_png: mask .*mask.png is 32x20 px, the frames are 32x24"):
        read_mask_png(path, (24, 32))
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(ConfigError, match="not a readable image"):
        read_mask_png(tmp_path / "bad.png", (24, 32))
    with pytest.raises(ConfigError, match="static_mask_png"):
        Pipeline(PipelineConfig(static_mask_png=str(path)), (32, 24))


def test_a_given_mask_of_a_clamp_rod_keeps_the_rod_out_of_the_rope(tmp_path: Path) -> None:
    """A bright rod from the top border to the fixed end joins the rope's contour to the border: the far end of
    that contour (the rod's top) must never pass for a tip. With the rod's mask given, the rope is measured.
    """
    rope = SyntheticRope(exposure_us=8000, amplitude_rad=0.7, period_s=0.9)
    frames = list(rope.frames(6, start=2))
    pivot = rope.centreline(0.0)[0]  # (u, v) of the fixed end
    col, row = round(float(pivot[0])), round(float(pivot[1]))
    mask = np.zeros((rope.height, rope.width), np.uint8)
    mask[: row - 1, col - 6 : col + 7] = 255  # the rod down to 2 px above the fixed end
    path = tmp_path / "rod.png"
    cv2.imwrite(str(path), mask)
    worst: dict[str, float] = {}
    ok: dict[str, int] = {}
    for given in ("", str(path)):
        pipeline = Pipeline(PipelineConfig(static_mask_png=given), (rope.width, rope.height))
        errors = []
        for frame in frames:
            image = frame.image.copy()
            image[: row + 1, col - 3 : col + 4] = 230  # the rod, touching the rope
            result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
            if result.status is not FrameStatus.OK:
                continue
            tips = (result.begin[-1][::-1], result.end[-1][::-1])  # (row, col) -> (u, v)
            errors.append(max(np.hypot(*(tips[0] - frame.tip_begin_uv)), np.hypot(*(tips[1] - frame.tip_end_uv))))
        worst[given] = max(errors, default=0.0)
        ok[given] = len(errors)
    # Without the mask the contour runs up the rod to the top border (ROPE_CLIPPED): no wrong OK.
    assert worst[""] < 1.0
    # The rope, not the rod, whenever it says OK. The first frames' splits (the rope nearly still) read both sides
    # off an outline that runs out and back along the rod's unmasked stub at the fixed end (tips 3-5 px off): their
    # contour encloses no band round the rope, which the `width` self-check refuses.
    assert worst[str(path)] < 1.0
    assert ok[str(path)] >= 1


def _seal(edges: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, int, int]:
    height, width = edges.shape
    listed = np.zeros(height * width, np.int32)
    flat = np.flatnonzero(edges.ravel())
    listed[: len(flat)] = flat
    lo = np.zeros(height, np.int32)
    hi = np.full(height, width - 1, np.int32)
    results = []
    for near in (_NO_NEAR, _near(mask) if mask.shape == edges.shape else _NO_NEAR):
        out, got = edges.copy(), listed.copy()
        count = K.seal_cut_ends(_ro(mask), near, _ro(lo), _ro(hi), out, got, len(flat))
        assert sorted(got[:count]) == sorted(np.flatnonzero(out.ravel()))  # the list is the map's edges
        results.append((out, got[:count].tolist()))
    assert results[0][1] == results[1][1]  # the same with the mask's summary
    np.testing.assert_array_equal(results[0][0], results[1][0])
    return results[0][0], len(results[0][1]), len(flat)


def test_seal_cut_ends_closes_a_rope_cut_at_a_clamp() -> None:
    """The mask dropped a clamp's outline: the rope's two sides end at the mask 4 px apart and are joined (its
    outline closed across the clamp's exit, one component); a line that runs along the mask, or ends away from
    it, is left as it is."""
    edges = np.zeros((30, 40), np.uint8)
    mask = np.zeros(edges.shape, np.uint8)
    mask[2:12, 10:30] = K.MASK_ALWAYS  # the clamp (its edges already dropped)
    edges[12:28, 18] = 1  # the rope's sides leaving it
    edges[12:28, 22] = 1
    edges[13, 2:9] = 1  # a scratch along the mask's side: not cut, not joined
    edges[20, 30:36] = 1  # a fragment ending away from the mask
    out, count, before = _seal(edges, mask)
    assert count == before + 3
    assert out[12, 19:22].all()
    labels = cv2.connectedComponents(out, connectivity=8)[1]
    assert labels[12, 18] == labels[12, 22] != labels[13, 2]


def test_seal_cut_ends_needs_a_mask_and_a_close_partner() -> None:
    edges = np.zeros((30, 40), np.uint8)
    edges[12:28, 18] = 1
    edges[12:28, 26] = 1  # 8 px apart: a rod's stub, not a rope
    mask = np.zeros(edges.shape, np.uint8)
    mask[2:12, 10:30] = K.MASK_ALWAYS
    for given in (mask, np.zeros((1, 1), np.uint8)):
        out, count, before = _seal(edges, given)
        assert count == before
        np.testing.assert_array_equal(out, edges)


def _seal_reference(mask, lo, hi, edges, listed):  # type: ignore[no-untyped-def]
    """`seal_cut_ends` as its rule reads, pixel by pixel in Python: the edges and list it leaves."""
    height, width = edges.shape
    edges, listed = edges.copy(), list(listed)
    if mask.shape != edges.shape:
        return edges, listed
    cut = set()
    for k in listed:
        r, c = divmod(int(k), width)
        if not (1 <= r <= height - 2 and 1 <= c <= width - 2):
            continue
        near = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if (dr, dc) != (0, 0)]
        masked = any(mask[r + dr, c + dc] != K.MASK_FREE for dr, dc in near)
        ends = [(dr, dc) for dr, dc in near if edges[r + dr, c + dc] != 0 or (r + dr) * width + c + dc in cut]
        touching = len(ends) == 2 and max(abs(ends[0][0] - ends[1][0]), abs(ends[0][1] - ends[1][1])) <= 1
        if masked and (len(ends) == 1 or touching):
            cut.add(int(k))
    if len(cut) < 2:
        return edges, listed
    reach = K.SEAL_REACH_PX

    def nearest(r: int, c: int) -> int:
        best, best_d = -1, 4 * reach * reach + 1
        for rr in range(max(r - reach, 1), min(r + reach + 1, height - 1)):
            for cc in range(max(c - reach, 1), min(c + reach + 1, width - 1)):
                d = (rr - r) ** 2 + (cc - c) ** 2
                if rr * width + cc in cut and 4 <= d < best_d:
                    best, best_d = rr * width + cc, d
        return best

    for k in [int(k) for k in listed]:
        if k not in cut:
            continue
        r, c = divmod(k, width)
        other = nearest(r, c)
        if other <= k or nearest(*divmod(other, width)) != k:
            continue
        r2, c2 = divmod(other, width)
        steps = max(abs(r2 - r), abs(c2 - c))
        for s in range(1, steps):
            pr = int(np.floor(r + (r2 - r) * s / steps + 0.5))
            pc = int(np.floor(c + (c2 - c) * s / steps + 0.5))
            if not (1 <= pr <= height - 2 and 1 <= pc <= width - 2 and lo[pr] <= pc <= hi[pr]):
                continue
            if edges[pr, pc] == 0 and pr * width + pc not in cut:
                edges[pr, pc] = 1
                listed.append(pr * width + pc)
    return edges, listed


@pytest.mark.kernel
@pytest.mark.parametrize("seed", [5, 6, 7, 8])
def test_seal_cut_ends_matches_a_slow_reference(seed: int) -> None:
    """Random short lines (ends next to masked pixels, on the image border, crossing each other) against the rule
    pixel by pixel: the same edge map and list."""
    rng = np.random.default_rng(seed)
    height, width = 28, 36
    edges = np.zeros((height, width), np.uint8)
    for _ in range(14):
        r, c = int(rng.integers(0, height)), int(rng.integers(0, width))
        dr, dc = int(rng.integers(-1, 2)), int(rng.integers(-1, 2))
        for _ in range(int(rng.integers(1, 7))):
            if 0 <= r < height and 0 <= c < width:
                edges[r, c] = 1
            r, c = r + dr, c + dc
    mask = np.zeros(edges.shape, np.uint8)
    for _ in range(4):
        r, c = int(rng.integers(0, height - 4)), int(rng.integers(0, width - 4))
        mask[r : r + int(rng.integers(1, 5)), c : c + int(rng.integers(1, 5))] = rng.choice(
            [K.MASK_ALWAYS, K.MASK_STATIC]
        )
    lo = rng.integers(0, 4, height).astype(np.int32)
    hi = (width - 1 - rng.integers(0, 4, height)).astype(np.int32)
    flat = rng.permutation(np.flatnonzero(edges.ravel())).astype(np.int32)  # any order, as the hysteresis lists
    listed = np.zeros(height * width, np.int32)
    listed[: len(flat)] = flat
    expected_edges, expected_list = _seal_reference(mask, lo, hi, edges, flat)
    for near in (_NO_NEAR, _near(mask)):
        out, got = edges.copy(), listed.copy()
        count = K.seal_cut_ends(_ro(mask), near, _ro(lo), _ro(hi), out, got, len(flat))
        np.testing.assert_array_equal(out, expected_edges)
        assert got[:count].tolist() == expected_list


def test_a_rope_cut_by_a_clamp_mask_is_measured_from_the_fixed_end(tmp_path: Path) -> None:
    """A clamp block round the fixed end and its rod to the top border, given as a mask: the mask drops the
    clamp's outline, so the rope's edges end at the clamp. The outline is sealed across the clamp's exit; the
    shapes are the rope from the fixed end (extended through the clamp along the rope) to its tips at the start
    and the end of the exposure, never round the clamp, up the rod or twice along the rope."""
    rope = SyntheticRope(exposure_us=8000, amplitude_rad=0.7, period_s=0.9)
    frames = list(rope.frames(5, start=2))
    pivot = rope.centreline(0.0)[0]  # (u, v) of the fixed end
    col, row = round(float(pivot[0])), round(float(pivot[1]))
    half = 9  # the clamp block: 19 x 19 px round the fixed end
    mask = np.zeros((rope.height, rope.width), np.uint8)
    mask[: row + half + 3, col - half - 2 : col + half + 3] = 255  # the block and the rod, 2 px grown
    path = tmp_path / "clamp.png"
    cv2.imwrite(str(path), mask)
    config = PipelineConfig(static_mask_png=str(path), fixed_end_uv=(float(pivot[0]), float(pivot[1])))
    pipeline = Pipeline(config, (rope.width, rope.height))
    for frame in frames:
        image = frame.image.copy()
        image[: row + half + 1, col - 3 : col + 4] = 230  # the rod
        image[row - half : row + half + 1, col - half : col + half + 1] = 200  # the clamp over the rope's end
        result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
        assert result.status is FrameStatus.OK
        for shape, tip in ((result.begin, frame.tip_begin_uv), (result.end, frame.tip_end_uv)):
            assert np.hypot(*(shape[-1][::-1] - tip)) < 1.0
            assert np.hypot(*(shape[0][::-1] - pivot)) < 2.5
            length = float(np.hypot(*np.diff(shape.astype(np.float64), axis=0).T).sum())
            assert abs(length - rope.length_px) < 0.03 * rope.length_px


def _with_cable(image: np.ndarray, col: int) -> np.ndarray:
    """`image` with a still bright cable from the top border to the bottom one at column `col` (3 px wide)."""
    out = image.copy()
    out[:, col - 1 : col + 2] = 200
    return out


def test_a_fresh_device_learns_a_static_cable_and_never_takes_it_for_the_rope() -> None:
    """A still cable from the top border to the bottom one, longer than the rope, beside the swing: a fresh
    device (every key at its default) learns it as static over its first `static_frames` frames and measures the
    rope from then on, to a pixel whenever it says OK (the cable's structure marked static does not end the
    rope's free tips "at the mask"). The first frame measured with the mask may find the rope's still top cut
    (its length then fails the self-check): a status, never a wrong OK."""
    rope = SyntheticRope(width=240, height=200, fixed_uv=(150.3, 20.6), length_px=120.0, amplitude_rad=0.5)
    learn = PipelineConfig().static_frames
    assert learn > 0  # the default learns
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    ok = 0
    for frame in rope.frames(learn + 5):
        result = pipeline.process(_with_cable(frame.image, 30), frame.index, frame.t_ns, float(rope.exposure_us))
        if frame.index < learn or result.status is not FrameStatus.OK:
            continue
        ok += 1
        tips = (result.begin[-1][::-1], result.end[-1][::-1])  # (row, col) -> (u, v)
        assert np.hypot(*(tips[0] - frame.tip_begin_uv)) < 1.0
        assert np.hypot(*(tips[1] - frame.tip_end_uv)) < 1.0
    assert not pipeline.static_mask.learning
    assert pipeline.static_mask.static()[:, 27:34].any(axis=1).mean() > 0.9  # the cable's edges, on nearly every row
    assert ok >= 4


def test_a_larger_structure_away_from_a_configured_fixed_end_is_never_the_rope() -> None:
    """A plate's edge from the top border to the bottom one (one edge, longer than the rope's outline), 180 px
    from the configured fixed end (a plane calibration's origin): before the static mask is learned it is the
    largest edge component, yet the rope is the structure attached to its fixed end. Every frame, the first ones
    included, measures the rope to a pixel (the lab scene through the paper's camera measured the plate edge its
    tip lies across instead: ROPE_CLIPPED, tips 300+ px off, on its first 10 frames)."""
    rope = SyntheticRope(width=340, height=420, fixed_uv=(120.3, 20.6), length_px=120.0, amplitude_rad=0.5)
    assert PipelineConfig().static_frames >= 4  # the frames below come before the mask is learned
    pipeline = Pipeline(PipelineConfig(fixed_end_uv=rope.fixed_uv), (rope.width, rope.height))
    for frame in rope.frames(4):
        image = frame.image.copy()
        image[:, 300:] = np.minimum(image[:, 300:].astype(np.int16) + 60, 255).astype(np.uint8)  # the plate
        result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
        assert result.status is FrameStatus.OK, (frame.index, result.status, result.message)
        assert np.hypot(*(result.begin[-1][::-1] - frame.tip_begin_uv)) < 1.0
        assert np.hypot(*(result.end[-1][::-1] - frame.tip_end_uv)) < 1.0


def test_the_learned_mask_marks_structures_not_the_plain_plate() -> None:
    """A still scratch on a plain noisy plate, with the rope swinging over it: after learning, the scratch's
    pixels are static and the plain plate far from it is not (the `tip_masked` check reads the mask)."""
    rope = SyntheticRope(width=240, height=200, fixed_uv=(120.3, 20.6), length_px=120.0, amplitude_rad=0.5)
    pipeline = Pipeline(PipelineConfig(static_frames=6), (rope.width, rope.height))
    for frame in rope.frames(7):  # learned from the first 6, marked on the 7th
        image = frame.image.copy()
        image[170:172, 20:80] = 90  # the scratch, below the swing
        pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
    static = pipeline.static_mask.static()
    assert static[169:173, 25:75].all(axis=0).sum() >= 40  # across the scratch, along most of it
    plate = np.zeros_like(static)
    plate[120:160, 180:230] = True  # plain plate, away from the rope and the scratch
    assert not static[plate].any()
    assert static.mean() < 0.05


def test_an_outline_whose_fixed_end_lies_on_the_border_is_never_ok() -> None:
    """A bright rod from the top border down to the rope's fixed end joins the rope's outline to the border, and
    a fresh device's first frames (before the mask is learned) may take the rod's top for the fixed end: such an
    outline is reported ROPE_CLIPPED, never OK with the rope measured from the border."""
    rope = SyntheticRope(width=240, height=200, fixed_uv=(120.3, 20.6), length_px=120.0, amplitude_rad=0.5)
    pipeline = Pipeline(PipelineConfig(static_frames=0), (rope.width, rope.height))
    statuses = []
    for frame in rope.frames(4):
        image = frame.image.copy()
        image[:22, 117:124] = 230  # the rod, touching the rope's fixed end
        result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
        statuses.append(result.status)
        if result.status is FrameStatus.OK:
            assert result.fixed_end is not None and result.fixed_end[0] > 2.0  # not on the top border
    assert FrameStatus.ROPE_CLIPPED in statuses


def test_a_fresh_device_measures_a_rope_held_by_a_clamp_on_a_rod() -> None:
    """A clamp block over the fixed end and its rod to the top border, nothing given (every key at its default):
    no frame is a wrong OK, and once the static mask is learned the rope is measured from the clamp to its tips,
    to a pixel (the traits, the contrast and the lens blur learned again without the clamp's edges)."""
    rope = SyntheticRope(width=240, height=200, fixed_uv=(120.3, 30.6), length_px=120.0, amplitude_rad=0.5)
    learn = PipelineConfig().static_frames
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    pivot = np.array(rope.fixed_uv)
    ok_after = 0
    for frame in rope.frames(learn + 6):
        image = frame.image.copy()
        image[:31, 118:123] = 150  # the rod, into the clamp's top
        image[25:37, 110:131] = 120  # the clamp, 21 x 12 px, centred on the fixed end
        result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
        if result.status is not FrameStatus.OK:
            continue
        tips = (result.begin[-1][::-1], result.end[-1][::-1])  # (row, col) -> (u, v)
        errors = (np.hypot(*(tips[0] - frame.tip_begin_uv)), np.hypot(*(tips[1] - frame.tip_end_uv)))
        assert max(errors) < 3.0, f"frame {frame.index}: a wrong OK"
        if frame.index > learn:
            ok_after += 1
            assert max(errors) < 1.0
            # From the clamp: the rope hangs out of its bottom, and its axis runs on up the rod, so the end stays
            # where the rope leaves the clamp (6 px below the fixed end; `hidden_end` needs the clamp's far edge).
            assert np.hypot(*(result.begin[0][::-1] - pivot)) < 8.0
    assert ok_after >= 4


def test_a_clipped_centreline_is_the_rope_only_from_its_fixed_end_and_no_longer_than_it() -> None:
    """A ROPE_CLIPPED frame gives its visible centreline only when it can be the rope's: from the fixed end (not
    along a plate edge the tip joins, 300+ px away) and no longer than the rope (not the rope and then the plate
    edge down to the border)."""
    from ropecam.device.pipeline.pipeline import _rope_from

    fixed = (90.0, 400.0)
    rope = np.array([[90.0, 400.0], [90.0, 760.0]], np.float32)
    assert _rope_from(rope, fixed, 16.0, 364.0)
    assert _rope_from(rope, fixed, 16.0, -1.0)  # length unknown
    assert not _rope_from(rope[::-1], fixed, 16.0, 364.0)  # starts at the far end
    down_the_plate = np.array([[90.0, 400.0], [90.0, 740.0], [511.0, 730.0]], np.float32)
    assert not _rope_from(down_the_plate, fixed, 16.0, 364.0)
    assert not _rope_from(rope[:0], fixed, 16.0, 364.0)


def test_a_tip_beside_masked_dust_is_measured_when_the_frame_shows_its_end(
    swinging_rope: SyntheticRope, dusty_frames: list[tuple[SyntheticFrame, np.ndarray]]
) -> None:
    """Dust all over the plate is learned as static, so every free tip ends within reach of the mask. Where the
    frame shows the rope at the tips and the plate as learned beyond them, the frames are OK and right (the
    `tip_masked` verdict withdrawn, on steady frames inside `steady_frame`); without that evidence (the finisher
    and the steady frame given no static mask) every one is flagged, as before."""
    rope = swinging_rope
    statuses = {}
    for evidence in (True, False):
        pipeline = Pipeline(PipelineConfig(static_frames=6), (rope.width, rope.height))
        if not evidence:
            pipeline._finisher.static_mask = pipeline._steady.static_mask = None
        statuses[evidence] = []
        for frame, image in dusty_frames[:14]:
            result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
            if frame.index <= 6:  # learning, and the frame that marks the mask (its tips on the first sweep's edge)
                continue
            statuses[evidence].append((result.status, result.reason))
            if result.status is FrameStatus.OK:
                assert np.hypot(*(result.begin[-1][::-1] - frame.tip_begin_uv)) < 1.0
                assert np.hypot(*(result.end[-1][::-1] - frame.tip_end_uv)) < 1.0
        assert pipeline.static_mask.static().mean() > 0.5  # the dust and its neighbourhood
    assert statuses[False] == [(FrameStatus.IMPLAUSIBLE, "tip_masked")] * 7
    assert statuses[True] == [(FrameStatus.OK, "")] * 7


def test_a_rope_cut_by_a_masked_band_stays_tip_masked(tmp_path: Path, swinging_rope: SyntheticRope) -> None:
    """A given mask across the rope's lower part drops its edges there: the shapes end at the mask with the rope
    going on beyond it. The frame shows the rope past the tips, so the `tip_masked` verdict stands (learned
    scene or not)."""
    rope = swinging_rope
    mask = np.zeros((rope.height, rope.width), np.uint8)
    mask[100:104] = 255
    path = tmp_path / "band.png"
    cv2.imwrite(str(path), mask)
    for learn in (6, 0):
        pipeline = Pipeline(PipelineConfig(static_frames=learn, static_mask_png=str(path)), (rope.width, rope.height))
        for frame in rope.frames(10):
            result = pipeline.process(frame.image, frame.index, frame.t_ns, float(rope.exposure_us))
            assert (result.status, result.reason) == (FrameStatus.IMPLAUSIBLE, "tip_masked"), (learn, frame.index)
            assert result.begin[-1][0] < 104.0  # the shapes end at the mask, 20 px short of the tips
