"""The structure a still rope runs into at its fixed end, found from the outline (`ropecam.device.pipeline.structure`):
the outline's geometry against slow references, and a fresh device on a clamp's first frames."""

from __future__ import annotations

import math

import cv2
import numpy as np

from ropecam.device.pipeline.structure import (
    SAME_PLACE_PX,
    across_distances,
    convex_hull,
    fill_polygon,
    grow,
    structure_points,
    zip_sides,
)


def _outline(image: np.ndarray) -> np.ndarray:
    """The outer outline of the non-zero pixels of `image` as (n, 2) float64 (row, col), one point per pixel."""
    contours, _ = cv2.findContours(image.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    points = max(contours, key=len)[:, 0, :]
    return points[:, ::-1].astype(np.float64)


def _block_and_rope(rope_rows: tuple[int, int], block: tuple[int, int, int, int]) -> np.ndarray:
    """A 60 x 200 image: a block (rows r0:r1, cols c0:c1) and a rope strip from its right side to column 180."""
    r0, r1, c0, c1 = block
    image = np.zeros((60, 200), np.uint8)
    image[r0:r1, c0:c1] = 1
    image[rope_rows[0] : rope_rows[1], c1 - 1 : 180] = 1
    return image


def test_across_distances_match_a_slow_reference() -> None:
    rng = np.random.default_rng(5)
    points = rng.uniform(0, 40, (300, 2))
    gap = 7
    expected = [
        min(
            math.dist(points[i], points[j])
            for j in range(300)
            if min(abs(i - j), 300 - abs(i - j)) >= gap and math.dist(points[i], points[j]) >= SAME_PLACE_PX
        )
        for i in range(300)
    ]
    np.testing.assert_allclose(across_distances(points, gap), expected)


def test_fill_polygon_matches_the_pixel_centres_inside() -> None:
    polygon = np.array([[2.3, 3.1], [2.6, 15.8], [11.2, 12.4], [13.7, 4.0]])
    region = fill_polygon(polygon, (20, 20))
    contour = polygon[:, ::-1].astype(np.float32).reshape(-1, 1, 2)  # OpenCV's (x, y)
    expected = np.array(
        [[cv2.pointPolygonTest(contour, (float(c), float(r)), False) > 0 for c in range(20)] for r in range(20)]
    )
    assert (region == expected).mean() > 0.99  # pixel centres on the outline itself may go either way
    assert region.sum() > 80
    # A part walked out and back (a rod's side to the border) encloses nothing.
    line = np.array([[2.0, 5.0], [12.0, 5.0], [2.0, 5.0]])
    assert fill_polygon(line, (20, 20)).sum() <= 11


def test_grow_is_a_3x3_dilation() -> None:
    region = np.zeros((9, 9), bool)
    region[4, 4] = True
    region[0, 8] = True
    grown = grow(region)
    assert grown[3:6, 3:6].all() and grown[0:2, 7:9].all()
    assert grown.sum() == 9 + 4


def test_zip_sides_stops_where_the_sides_part_or_meet() -> None:
    """Walked together from a rope's free tip, its two sides stay a width apart up to where they part (a block the
    rope leaves) or meet (the outline closed across the rope's end)."""
    block = _outline(_block_and_rope((25, 28), (16, 36, 40, 60)))
    tip = int(np.argmax(block[:, 1]))
    forward, backward, middle, _ = zip_sides(block, tip, 1.6 * 3.0 + 1.0, 1.5)
    n = len(block)
    for row, col in block[[(tip + forward) % n, (tip - backward) % n]]:
        assert 23 <= row <= 30 and 57 <= col <= 62, (row, col)  # at the block's right side
    assert 2.0 <= middle <= 4.0
    rope = np.zeros((60, 200), np.uint8)
    rope[28:31, 20:180] = 1
    plain = _outline(rope)
    forward, backward, _, _ = zip_sides(plain, int(np.argmax(plain[:, 1])), 1.6 * 3.0 + 1.0, 1.5)
    assert forward + backward >= len(plain) - 12  # up to the other end's cap


def test_structure_points_are_the_outline_beyond_the_rope() -> None:
    """The outline of a 12-row block with a 3 px rope leaving its right side: the structure is the block's outline,
    its hull the block; a plain rope, or a blob without a rope, has none."""
    image = _block_and_rope((25, 28), (16, 36, 40, 60))
    points = _outline(image)
    ends = (int(np.argmin(points[:, 1])), int(np.argmax(points[:, 1])))
    found = structure_points(points, ends, 4.0)
    assert found is not None
    structure, exit_a, exit_b = found
    assert (points[structure, 1] <= 62).all() and structure.sum() >= 50
    for row, col in points[[exit_a, exit_b]]:
        assert 23 <= row <= 30 and 57 <= col <= 62, (row, col)
    region = fill_polygon(convex_hull(np.concatenate([points[structure], points[[exit_a, exit_b]]])), image.shape)
    assert region[17:35, 41:59].all()  # the block's inside
    assert not region[:, 66:].any()  # not the rope beyond its exit
    rope = np.zeros((60, 200), np.uint8)
    rope[28:31, 20:180] = 1
    points = _outline(rope)
    assert structure_points(points, (int(np.argmin(points[:, 1])), int(np.argmax(points[:, 1]))), 4.0) is None
    blob = np.zeros((60, 200), np.uint8)
    blob[10:50, 20:180] = 1
    points = _outline(blob)
    assert structure_points(points, (0, len(points) // 2), 4.0) is None


def test_a_loop_of_the_ropes_own_sides_is_not_the_structure() -> None:
    """A short edge across the rope's band beyond the block (an MJPEG block's step in the rope's brightness) closes
    a loop of the rope's sides that the trace runs round apart from the rope's walk: the sides are at the same place
    as the rope's, the edge across the band lies 1.5 px from both. The region stays the block's (before: the hull
    reached the edge across the band, 40 px along the rope, and the mask cut the rope there)."""
    image = _block_and_rope((24, 28), (16, 36, 40, 60))
    outline = _outline(image)
    top, bottom = float(outline[:, 0][outline[:, 1] == 120].min()), float(outline[:, 0][outline[:, 1] == 120].max())
    cols = np.arange(61.0, 101.0)
    loop = np.concatenate(
        [
            np.stack([np.full(cols.size, top), cols], axis=1),
            [[0.5 * (top + bottom), 100.5]],
            np.stack([np.full(cols.size, bottom), cols[::-1]], axis=1),
        ]
    )
    at = int(np.argmin(outline[:, 1]))  # on the block's far side
    points = np.concatenate([outline[: at + 1], loop, outline[at + 1 :]])
    ends = (int(np.argmin(points[:, 1])), int(np.argmax(points[:, 1])))
    found = structure_points(points, ends, 4.0)
    assert found is not None
    structure, exit_a, exit_b = found
    assert (points[structure, 1] <= 62).all(), points[structure & (points[:, 1] > 62)]
    region = fill_polygon(convex_hull(np.concatenate([points[structure], points[[exit_a, exit_b]]])), image.shape)
    assert region[17:35, 41:59].all()
    assert not region[:, 66:].any()


def test_convex_hull_matches_opencv() -> None:
    rng = np.random.default_rng(7)
    points = rng.uniform(0, 50, (200, 2))
    hull = convex_hull(points)
    expected = cv2.convexHull(points.astype(np.float32))[:, 0, :]
    assert len(hull) == len(expected)
    assert {tuple(np.round(p, 4)) for p in hull} == {tuple(np.round(p, 4)) for p in expected.astype(np.float64)}


def test_a_fresh_device_measures_a_still_rope_in_a_clamp_before_the_mask_is_learned() -> None:
    """A rope released from near horizontal, fixed in a clamp block (drawn over its end), nothing given: on the
    first frames the static mask cannot tell the still clamp from the still rope, and the rope's outline runs round
    the clamp (before: `LOST_TRACK`, "the two shapes differ in length", or a centreline out and back). The clamp is
    found from the outline and masked: every first frame measures the rope from the clamp's middle to its tips."""
    from ropecam.device.capture.synthetic import SyntheticRope
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.device.pipeline.result import FrameStatus

    rope = SyntheticRope(
        width=260, height=120, fixed_uv=(60.3, 30.6), length_px=150.0, diameter_px=3.0, amplitude_rad=1.45,
        period_s=1.2, bend=0.0, phase_rad=0.0,
    )  # fmt: skip
    learn = PipelineConfig().static_frames
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    pivot = np.array(rope.fixed_uv)
    ok = 0
    for frame in rope.frames(learn):
        image = frame.image.copy()
        image[24:38, 49:72] = 120  # the clamp, 23 x 14 px, centred on the fixed end
        result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
        assert pipeline.static_mask.learning
        if result.status is not FrameStatus.OK:
            continue
        ok += 1
        for shape, tip in ((result.begin, frame.tip_begin_uv), (result.end, frame.tip_end_uv)):
            assert np.hypot(*(shape[-1][::-1] - tip)) < 1.0, (frame.index, result.message)
            assert np.hypot(*(shape[0][::-1] - pivot)) < 3.0, frame.index
    assert ok >= learn - 1
    assert pipeline.static_mask.structure_px > 0


def test_a_fresh_device_finds_the_clamp_of_a_rope_already_swinging_in_the_learned_mask() -> None:
    """A rope already swinging when the stream starts, fixed in a shaded clamp block with two bolts, nothing given,
    and a first outline that shows no clamp (its search made to find nothing here: on the simulated clamp rows started
    mid-swing, seed 3 from 0.15 s and seed 5 from 0.4 s, it finds nothing). The still structures of the first
    `EARLY_FRAMES` frames (`StaticMask.early`) hold the clamp's outline but for the stretch the rope swept where it
    leaves the clamp; the clamp is found there at the rope's end (`FixedEndFinder.learned_structure`) and filled,
    and every later frame measures the rope from the clamp's middle to its tips (without it: the band's edge
    broken by the clamp's unmasked edge pieces, `LOST_TRACK`, on every frame, the learned mask's too)."""
    from ropecam.device.capture.synthetic import SyntheticRope
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.device.pipeline.result import FrameStatus
    from ropecam.device.pipeline.static_mask import EARLY_FRAMES

    rope = SyntheticRope(
        width=360, height=200, fixed_uv=(180.3, 30.6), length_px=150.0, diameter_px=3.0, amplitude_rad=1.1,
        period_s=0.6, bend=0.0, phase_rad=0.5 * math.pi,
    )  # fmt: skip
    learn = PipelineConfig().static_frames
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    pipeline.traits.fixed_end.structure = lambda *args: None  # the first outline shows no clamp
    pivot = np.array(rope.fixed_uv)
    after = []
    for frame in rope.frames(learn + 12):
        image = frame.image.copy()
        image[24:38, 169:192] = 190  # the clamp, 23 x 14 px, centred on the fixed end: a bright rim,
        image[25:37, 170:191] = 120  # a grey face
        image[29:33, 173:177] = image[29:33, 184:188] = 60  # and two dark bolts
        result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
        if frame.index < EARLY_FRAMES - 1:  # (a frame is learned from before it is measured)
            continue
        after.append(result.status)
        if result.status is FrameStatus.OK:
            for shape, tip in ((result.begin, frame.tip_begin_uv), (result.end, frame.tip_end_uv)):
                assert np.hypot(*(shape[-1][::-1] - tip)) < 1.5, (frame.index, result.message)
                assert np.hypot(*(shape[0][::-1] - pivot)) < 3.0, frame.index
    assert pipeline.static_mask.structure_px > 0
    # The frame the clamp is found on, and the one the mask is marked on, may have no time order yet.
    assert after.count(FrameStatus.OK) >= len(after) - 2, after


def test_a_still_structure_at_the_free_tip_of_a_rope_already_swinging_is_not_taken_for_its_clamp() -> None:
    """A rope already swinging when the stream starts, no clamp, nothing given, and a still block just beyond its
    free tip on the first frames (no rope reaches it). The still structures of the first `EARLY_FRAMES` frames
    hold the block at the outline's moving end; taken for the clamp (`FixedEndFinder.learned_structure`), it made
    the tip the fixed end, "confirmed", and frames were reported OK a rope length off (simulated `contrast = 30 DN`
    from 0.3 s, seed 3, frame 1: a faint tip band read as still). The end that moved while the other stayed is the
    free tip: nothing there is taken, and every frame measured OK is right."""
    from ropecam.device.capture.synthetic import SyntheticRope
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.device.pipeline.result import FrameStatus
    from ropecam.device.pipeline.static_mask import EARLY_FRAMES

    rope = SyntheticRope(
        width=360, height=200, fixed_uv=(180.3, 30.6), length_px=150.0, diameter_px=3.0, amplitude_rad=1.1,
        period_s=0.6, bend=0.0, phase_rad=0.5 * math.pi,
    )  # fmt: skip
    frames = list(rope.frames(14))
    tip = frames[EARLY_FRAMES - 1].tip_end_uv
    pivot = np.array(rope.fixed_uv)
    out = (tip - pivot) / np.hypot(*(tip - pivot))
    centre = pivot + out * (rope.length_px + 9.0)  # beyond the tip's reach
    r, c = round(float(centre[1])), round(float(centre[0]))
    pipeline = Pipeline(PipelineConfig(), (rope.width, rope.height))
    statuses = []
    for frame in frames:
        image = frame.image.copy()
        image[r - 5 : r + 6, c - 5 : c + 6] = 150  # the still block, 11 x 11 px
        result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
        statuses.append(result.status)
        if result.status is FrameStatus.OK:
            for shape, tip_uv in ((result.begin, frame.tip_begin_uv), (result.end, frame.tip_end_uv)):
                assert np.hypot(*(shape[-1][::-1] - tip_uv)) < 1.5, (frame.index, result.message)
                assert np.hypot(*(shape[0][::-1] - pivot)) < 3.0, frame.index
    assert np.hypot(*(pipeline.fixed[::-1] - pivot)) < 3.0
    assert statuses.count(FrameStatus.OK) >= len(statuses) - 3, statuses
