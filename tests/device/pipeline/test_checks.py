"""The self-checks: each turns a constructed wrong frame into its status with its reason; a right frame stays OK."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.checks import ChecksConfig, Reason, SelfChecks, contour_area_px2, tip_corner_px
from ropecam.device.pipeline.motion import MotionModel
from ropecam.device.pipeline.result import FrameStatus
from ropecam.device.pipeline.time_order import TimeOrder
from ropecam.shared.config import from_mapping
from ropecam.shared.errors import ConfigError

FIXED = np.array([10.0, 100.0], np.float32)
WIDTH_PX = 5.0
STILL_AREA_PX2 = 200.0 * WIDTH_PX
"""A still rope's contour (200 px long) encloses length x width."""
SWEPT_AREA_PX2 = STILL_AREA_PX2 + 0.5 * 200.0 * 20.0
"""... and the band of a 20 px tip sweep about the fixed end adds half the length x the sweep."""


def _shape(tip_col: float, start: tuple[float, float] = (10.0, 100.0), length: int = 200) -> np.ndarray:
    """A straight rope hanging from `start` (row, col) to row start + length, its tip moved to `tip_col`."""
    rows = np.linspace(start[0], start[0] + length, 101)
    cols = np.linspace(start[1], tip_col, 101)
    return np.column_stack([rows, cols]).astype(np.float32)


def _check(checks: SelfChecks, **changes: object) -> tuple[FrameStatus, Reason]:
    frame = {
        "begin": _shape(90.0),
        "end": _shape(110.0),
        "fixed": FIXED,
        "stretch_begin": 1.01,
        "stretch_end": 0.99,
        "width_px": WIDTH_PX,
        "learned_width_px": WIDTH_PX,
        "order_confidence": 0.97,
        "exposure_ns": 4_000_000,
        "split": True,
        "contour_area_px2": SWEPT_AREA_PX2,
    }
    frame.update(changes)
    return checks.check(**frame)  # type: ignore[arg-type]


def test_a_right_frame_is_ok_and_its_quality_is_measured() -> None:
    checks = SelfChecks(ChecksConfig())
    assert _check(checks) == (FrameStatus.OK, Reason.NONE)
    q = checks.quality
    assert q["length_ratio"] == pytest.approx(1.01)
    assert q["width_ratio"] == pytest.approx(1.0)
    assert q["fixed_end_px"] == pytest.approx(0.0)
    assert q["tip_separation_px"] == pytest.approx(20.0)
    assert math.isnan(q["tip_motion_px"])  # no motion model yet: no prediction


@pytest.mark.parametrize(
    ("changes", "reason"),
    [
        ({"stretch_end": 1.4}, Reason.LENGTH),
        ({"stretch_begin": 0.6}, Reason.LENGTH),
        ({"stretch_begin": 0.82, "stretch_end": 0.82}, Reason.LENGTH),
        ({"stretch_begin": 1.04, "stretch_end": 0.995}, Reason.LENGTH),
        ({"width_px": 2.0 * WIDTH_PX + 1.0}, Reason.WIDTH),
        ({"begin": _shape(96.0, start=(10.0, 130.0))}, Reason.FIXED_END),
        ({"end": _shape(104.0, start=(40.0, 100.0))}, Reason.FIXED_END),
    ],
    ids=[
        "too long",
        "too short",
        "both shapes short of their faint band's end",
        "the two shapes' lengths apart",
        "too wide",
        "begin off the fixed end",
        "end off the fixed end",
    ],
)
def test_each_implausible_frame_gets_its_reason(changes: dict, reason: Reason) -> None:
    assert _check(SelfChecks(ChecksConfig()), **changes) == (FrameStatus.IMPLAUSIBLE, reason)


def test_tip_motion_against_the_motion_models_prediction() -> None:
    motion = MotionModel()
    period_ns = 8_403_361
    for k, col in enumerate((96.0, 98.0)):  # the tip moves 2 px a frame
        tips = _shape(col)
        motion.observe(tips, tips, FIXED, k * period_ns + 2_000_000, 0.0, 4_000_000)
    checks = SelfChecks(ChecksConfig())
    for _ in range(3):  # the fixed end has settled for as long as the model's history
        checks.predict(motion.state, motion.log, FIXED, 2 * period_ns, 4_000_000)
    expected = _shape(100.0)  # the motion continued: OK
    assert _check(checks, begin=expected, end=expected) == (FrameStatus.OK, Reason.NONE)
    assert checks.quality["tip_motion_px"] < 0.5
    jumped = _shape(160.0)  # 60 px off the prediction
    assert _check(checks, begin=jumped, end=jumped) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_MOTION)
    assert checks.quality["tip_motion_px"] > checks.quality["tip_motion_limit_px"]
    checks.forget()  # no prediction: the jump is not checked (one shape: no blur evidence needed either)
    assert _check(checks, begin=jumped, end=jumped, split=False) == (FrameStatus.OK, Reason.NONE)


@pytest.mark.parametrize(("step_px", "fallback", "expected"), [
    (20.0, True, Reason.FALLBACK_SWEEP),  # 9.5 px in the 4 ms exposure: 1.9 widths
    (20.0, False, Reason.NONE),  # the centreline method: one shape is its answer
    (6.0, True, Reason.NONE),  # 2.9 px: 0.6 widths
])  # fmt: skip
def test_one_shape_while_the_tip_swept_fails_as_a_fallback(step_px: float, fallback: bool, expected: Reason) -> None:
    motion = MotionModel()
    period_ns = 8_403_361
    for k in range(2):
        tips = _shape(96.0 + k * step_px)
        motion.observe(tips, tips, FIXED, k * period_ns + 2_000_000, 0.0, 4_000_000)
    checks = SelfChecks(ChecksConfig(), fallback_single=fallback)
    for _ in range(3):
        checks.predict(motion.state, motion.log, FIXED, 2 * period_ns, 4_000_000)
    middle = _shape(96.0 + 2 * step_px)
    status = FrameStatus.OK if expected is Reason.NONE else FrameStatus.IMPLAUSIBLE
    assert _check(checks, begin=middle, end=middle, split=False) == (status, expected)
    assert _check(checks, split=True)[1] is not Reason.FALLBACK_SWEEP  # two shapes: not a fallback


def test_the_one_shape_frame_after_a_fallback_sweep_failure_fails_too_once() -> None:
    # The failure clears the motion model, so the next frame has no prediction to check its one shape against
    # (simulated lab, lab-mjpeg, lab-rolling, tuning seed, set up from their first 2 s: frames 70 and 205, the band's
    # middle 3.0 px off at the tip or 1.7 px off along the body, reported OK). Once only: a rope coming to rest is
    # reported again.
    motion = MotionModel()
    period_ns = 8_403_361
    for k in range(2):
        tips = _shape(96.0 + k * 20.0)
        motion.observe(tips, tips, FIXED, k * period_ns + 2_000_000, 0.0, 4_000_000)
    checks = SelfChecks(ChecksConfig())
    for _ in range(3):
        checks.predict(motion.state, motion.log, FIXED, 2 * period_ns, 4_000_000)
    middle = _shape(136.0)
    assert _check(checks, begin=middle, end=middle, split=False)[1] is Reason.FALLBACK_SWEEP
    checks.forget()  # the pipeline clears the motion model after a failed frame
    checks.due()  # and starts the next frame
    assert _check(checks, begin=middle, end=middle, split=False) == (FrameStatus.IMPLAUSIBLE, Reason.FALLBACK_SWEEP)
    checks.due()
    assert _check(checks, begin=middle, end=middle, split=False) == (FrameStatus.OK, Reason.NONE)  # once
    # Right after only: not across a frame that got no verdict (no shapes), nor across a reset of the tracking.
    for between in ("no verdict", "reset"):
        checks.due()
        checks.predict(motion.state, motion.log, FIXED, 2 * period_ns, 4_000_000)
        assert _check(checks, begin=middle, end=middle, split=False)[1] is Reason.FALLBACK_SWEEP
        checks.forget()
        checks.due()
        if between == "reset":
            checks.restart()
        else:
            checks.due()
        assert _check(checks, begin=middle, end=middle, split=False) == (FrameStatus.OK, Reason.NONE), between
    # A one-shape method (centreline) never carries it.
    centreline = SelfChecks(ChecksConfig(), fallback_single=False)
    assert _check(centreline, begin=middle, end=middle, split=False)[1] is Reason.NONE


def test_a_one_shape_frame_without_a_prediction_takes_its_sweep_from_the_time_orders_history() -> None:
    # Three static fallbacks in a row (simulated lab-mjpeg set up from its first 2 s, tuning seed, frames 68-70): the
    # first fails ``fallback_sweep`` on the motion model's path, which the failure clears; the second fails by the
    # carry; the third had nothing to check its sweep against and was reported OK with its tip 3.04 px off. The
    # time order's history still holds the last one-shape frames' tips (at mid-exposure, as this frame's is).
    period_ns, exposure_ns = 8_403_361, 4_000_000
    order = TimeOrder()
    for k, tip_col in enumerate((96.0, 116.0)):  # two one-shape frames, the tip 20 px on each frame
        shape = _shape(tip_col)
        order.order(shape, shape, k * period_ns, k * period_ns + exposure_ns, period_ns)
    checks = SelfChecks(ChecksConfig())
    predicted, thresholds, _ = checks.buffers
    for tip_col, expected in ((136.0, Reason.FALLBACK_SWEEP), (117.0, Reason.NONE)):  # 9.5 px and 0.5 px swept
        checks.restart()  # no prediction (a flagged frame cleared the motion model), nothing carried
        checks.due(settled=False)  # a new frame
        middle = _shape(tip_col)
        assert _check(checks, begin=middle, end=middle, split=False)[1] is Reason.NONE  # nothing to check against
        t_mid_ns = 2 * period_ns + exposure_ns // 2
        assert K.predict_sweep_from_history(
            t_mid_ns, exposure_ns, 4 * period_ns, order.state, order.hist_rc, middle, predicted
        )
        assert predicted[3] == pytest.approx(abs(tip_col - 116.0) * exposure_ns / period_ns, rel=1e-6)
        assert _check(checks, begin=middle, end=middle, split=False)[1] is expected, tip_col
        assert thresholds[0]["fallback_sweep_widths"] * WIDTH_PX == pytest.approx(7.5)  # between the two sweeps
    # A sweep already there (the motion model's) stands; a history too old gives none.
    predicted[3] = 1.0
    assert not K.predict_sweep_from_history(
        2 * period_ns, exposure_ns, 4 * period_ns, order.state, order.hist_rc, middle, predicted
    )
    assert predicted[3] == 1.0
    predicted[3] = math.nan
    assert not K.predict_sweep_from_history(
        20 * period_ns, exposure_ns, 4 * period_ns, order.state, order.hist_rc, middle, predicted
    )
    assert math.isnan(predicted[3])


def test_shapes_of_different_lengths_fail_only_as_a_split() -> None:
    checks = SelfChecks(ChecksConfig())
    assert _check(checks, stretch_begin=1.015, stretch_end=0.99) == (FrameStatus.OK, Reason.NONE)  # 2.5 % apart
    one = _shape(100.0)  # one shape (a centreline) for both instants: nothing to compare
    assert _check(checks, begin=one, end=one, split=False, stretch_begin=1.05, stretch_end=1.0)[0] is FrameStatus.OK
    assert _check(checks, stretch_begin=math.nan, stretch_end=1.1)[0] is FrameStatus.OK  # Lc0 not known yet


def test_an_uncertain_time_order_fails_only_when_asked_and_decidable() -> None:
    checks = SelfChecks(ChecksConfig(min_order_confidence=0.8))
    assert _check(checks, order_confidence=0.6) == (FrameStatus.IMPLAUSIBLE, Reason.ORDER)
    assert _check(checks, order_confidence=0.6, split=False) == (FrameStatus.OK, Reason.NONE)  # one shape
    assert _check(SelfChecks(ChecksConfig()), order_confidence=0.6) == (FrameStatus.OK, Reason.NONE)  # default off


def test_a_split_whose_time_order_nothing_decided_is_not_trusted() -> None:
    # The first split of a stream that starts mid-swing (no motion prediction, no order history): tips 20 px apart.
    checks = SelfChecks(ChecksConfig())
    assert _check(checks, order_confidence=0.5, order_undecided=True) == (FrameStatus.IMPLAUSIBLE, Reason.ORDER)
    assert _check(checks, order_confidence=0.5) == (FrameStatus.OK, Reason.NONE)  # ordered (after still frames)
    near = {"begin": _shape(98.0), "end": _shape(102.0), "contour_area_px2": STILL_AREA_PX2 + 200.0}
    assert _check(checks, **near, order_undecided=True) == (FrameStatus.OK, Reason.NONE)  # within a width
    one = _shape(100.0)
    assert _check(checks, begin=one, end=one, split=False, order_undecided=True)[0] is FrameStatus.OK
    off = SelfChecks(ChecksConfig(order_unknown_widths=0.0))
    assert _check(off, order_confidence=0.5, order_undecided=True) == (FrameStatus.OK, Reason.NONE)


@pytest.mark.parametrize("exposure_ns", [0, 4_000_000], ids=["unknown exposure", "no motion prediction"])
def test_a_split_needs_evidence_of_blur(exposure_ns: int) -> None:
    checks = SelfChecks(ChecksConfig())
    # Tips 20 px apart, nothing swept: a still photo, or a first frame, read as a split.
    still = _check(checks, exposure_ns=exposure_ns, contour_area_px2=STILL_AREA_PX2)
    assert still == (FrameStatus.NO_BLUR, Reason.NO_BLUR)
    no_area = _check(checks, exposure_ns=exposure_ns, contour_area_px2=math.nan)
    assert no_area == (FrameStatus.NO_BLUR, Reason.NO_BLUR)
    assert _check(checks, exposure_ns=exposure_ns) == (FrameStatus.OK, Reason.NONE)  # the swept band is there
    assert checks.quality["blur_evidence"] == pytest.approx(1.0, abs=0.01)
    same = _shape(100.0)
    assert _check(checks, exposure_ns=exposure_ns, begin=same, end=same, contour_area_px2=STILL_AREA_PX2)[0] is (
        FrameStatus.OK
    )
    assert _check(checks, exposure_ns=exposure_ns, split=False, contour_area_px2=STILL_AREA_PX2)[0] is FrameStatus.OK


def test_a_split_whose_contour_is_no_band_round_the_rope_is_implausible() -> None:
    # Known exposure, no prediction yet, tips 10 px apart (too close for the evidence of blur to decide): a contour
    # that encloses almost nothing (a whisker run out and back along a clamp's outline) is not the rope's band.
    checks = SelfChecks(ChecksConfig())
    near = {"begin": _shape(95.0), "end": _shape(105.0)}
    assert _check(checks, **near, contour_area_px2=0.1 * STILL_AREA_PX2) == (FrameStatus.IMPLAUSIBLE, Reason.WIDTH)
    assert _check(checks, **near, contour_area_px2=STILL_AREA_PX2) == (FrameStatus.OK, Reason.NONE)
    # Off, or a frame of unknown exposure (a still photo keeps its no-blur verdicts), or one shape: not this check.
    assert _check(SelfChecks(ChecksConfig(min_band_area=0.0)), **near, contour_area_px2=0.0)[0] is FrameStatus.OK
    assert _check(checks, **near, exposure_ns=0, contour_area_px2=0.0)[1] is not Reason.WIDTH
    assert _check(checks, **near, split=False, contour_area_px2=0.0)[0] is FrameStatus.OK


def test_contour_area_is_the_shoelace_area() -> None:
    square = np.array([[0, 0], [0, 10], [10, 10], [10, 0]], np.float32)
    assert contour_area_px2(square, 4) == pytest.approx(100.0)
    assert contour_area_px2(square, 2) == 0.0


def test_disabled_checks_report_ok_but_still_measure() -> None:
    checks = SelfChecks(ChecksConfig(enabled=False))
    assert _check(checks, stretch_end=2.0) == (FrameStatus.OK, Reason.NONE)
    assert checks.quality["length_ratio"] == pytest.approx(2.0)


def test_the_checks_table_is_read_and_checked() -> None:
    from ropecam.device.pipeline.config import PipelineConfig

    config = from_mapping(PipelineConfig, {"checks": {"length_tolerance": 0.1}})
    assert config.checks.length_tolerance == 0.1
    with pytest.raises(ConfigError, match="length_tol"):
        from_mapping(PipelineConfig, {"checks": {"length_tol": 0.1}})
    with pytest.raises(ConfigError, match=r"checks\.no_blur_px"):
        ChecksConfig(no_blur_px=-1.0)


def test_the_check_kernel_speaks_the_wire_s_reasons_and_measures() -> None:
    from ropecam.device.pipeline import _kernels as K
    from ropecam.device.pipeline._kernels import checks as kernel_checks
    from ropecam.shared.protocol.quality import QUALITY_KEYS

    codes = {name: getattr(kernel_checks, f"CHECK_{name}") for name in Reason.__members__}
    assert codes == {name: int(member) for name, member in Reason.__members__.items()}
    assert K.CHECK_QUALITY.names == QUALITY_KEYS
    assert set(K.CHECK_THRESHOLDS.names) <= {f.name for f in ChecksConfig.__dataclass_fields__.values()}


def _mask_across(row: int, rows: int = 2, shape: tuple[int, int] = (260, 200)) -> np.ndarray:
    """A static mask of `rows` masked rows from `row` across the whole image (a masked plate edge), read-only."""
    mask = np.zeros(shape, np.uint8)
    mask[row : row + rows] = 1
    mask.flags.writeable = False
    return mask


def test_a_tip_that_ends_at_the_static_mask_is_not_trusted() -> None:
    # The shapes run from row 10 to row 210: a masked plate edge 2 px beyond the tips may have cut the rope there.
    checks = SelfChecks(ChecksConfig())
    assert _check(checks, mask=_mask_across(212)) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_MASKED)
    assert "static mask" in checks.message(Reason.TIP_MASKED)
    # The same mask farther than a width + 2 px beyond the tips, or along the rope's side, or none: OK.
    assert _check(checks, mask=_mask_across(220)) == (FrameStatus.OK, Reason.NONE)
    assert _check(checks, mask=_mask_across(120)) == (FrameStatus.OK, Reason.NONE)
    assert _check(checks, mask=None) == (FrameStatus.OK, Reason.NONE)
    assert _check(SelfChecks(ChecksConfig(tip_mask_widths=0.0, tip_mask_floor_px=0.0)), mask=_mask_across(212))[0] is (
        FrameStatus.OK
    )


def _tip_mask_distance_reference(shape: np.ndarray, mask: np.ndarray, width_px: float, reach_px: float) -> float:
    """Slow reference of `tip_mask_distance`: every sample point from a width behind the tip to the reach beyond
    it, a width either side, in order along the line."""
    tip = shape[-1].astype(np.float64)
    back = next(
        (p.astype(np.float64) for p in shape[-2::-1] if np.hypot(*(tip - p)) >= 3.0), shape[0].astype(np.float64)
    )
    u = (tip - back) / np.hypot(*(tip - back))
    v = np.array([-u[1], u[0]])
    for along in np.arange(-int(2.0 * width_px) / 2.0, reach_px + 0.25, 0.5):
        for side in (-width_px, -0.5 * width_px, 0.0, 0.5 * width_px, width_px):
            r, c = np.floor(tip + along * u + side * v + 0.5).astype(int)
            if 0 <= r < mask.shape[0] and 0 <= c < mask.shape[1] and mask[r, c]:
                return float(along)
    return math.nan


@pytest.mark.parametrize("tip_col", [60.0, 100.0, 130.0])
@pytest.mark.parametrize("mask_row", [205, 211, 214, 230])
def test_tip_mask_distance_matches_its_reference(tip_col: float, mask_row: int) -> None:
    from ropecam.device.pipeline import _kernels as K

    shape = _shape(tip_col)
    mask = _mask_across(mask_row, rows=3)
    expected = _tip_mask_distance_reference(shape, mask, WIDTH_PX, 7.0)
    got = K.tip_mask_distance(shape, mask, WIDTH_PX, 7.0)
    assert (math.isnan(got) and math.isnan(expected)) or got == pytest.approx(expected)


def _kinked(turn_deg: float, tail_px: float = 15.0) -> np.ndarray:
    """`_shape(110.0)` whose last `tail_px` run on turned by `turn_deg` (a tip that followed noise past the end)."""
    shape = _shape(110.0).astype(np.float64)
    steps = np.hypot(*np.diff(shape, axis=0).T)
    arc_from_tip = np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]])
    keep = int(np.argmax(arc_from_tip < tail_px))
    start = shape[keep - 1]
    direction = (shape[-1] - shape[0]) / np.hypot(*(shape[-1] - shape[0]))
    angle = math.radians(turn_deg)
    turned = np.array(
        [direction[0] * math.cos(angle) - direction[1] * math.sin(angle),
         direction[0] * math.sin(angle) + direction[1] * math.cos(angle)]
    )  # fmt: skip
    tail = start + np.outer(np.arange(1, 9) * tail_px / 8.0, turned)
    return np.vstack([shape[:keep], tail]).astype(np.float32)


@pytest.mark.parametrize(
    ("turn_deg", "expected"), [(70.0, Reason.TIP_KINK), (30.0, Reason.TIP_KINK), (5.0, Reason.NONE)]
)
def test_a_tip_that_turns_sharply_at_the_free_end_is_not_trusted(turn_deg: float, expected: Reason) -> None:
    # read noise = 10, frame 25 (simulated, tuning seed): both shapes reach the true tip, then run on 15 px
    # turning 70-100 degrees with a length 3.6 % long (inside checks.length_tolerance).
    checks = SelfChecks(ChecksConfig())
    status = FrameStatus.OK if expected is Reason.NONE else FrameStatus.IMPLAUSIBLE
    assert _check(checks, end=_kinked(turn_deg)) == (status, expected)
    assert _check(SelfChecks(ChecksConfig(tip_kink_widths=0.0)), end=_kinked(turn_deg)) == (FrameStatus.OK, Reason.NONE)


def test_a_smoothly_bent_rope_passes_the_kink_check() -> None:
    from ropecam.device.pipeline import _kernels as K

    # A rope bent along a circle of 300 px radius (a strongly swinging rope) turns ~5 degrees per 5 widths.
    angles = np.linspace(0.0, 200.0 / 300.0, 101)
    bent = np.column_stack([10.0 + 300.0 * np.sin(angles), 100.0 + 300.0 * (1.0 - np.cos(angles))]).astype(np.float32)
    assert _check(SelfChecks(ChecksConfig()), end=bent)[1] is not Reason.TIP_KINK
    assert K.tip_turn_deg(bent, 25.0) == pytest.approx(math.degrees(25.0 / 300.0), abs=0.2)
    assert K.tip_turn_deg(_shape(110.0), 25.0) == pytest.approx(0.0, abs=1e-3)
    assert math.isnan(K.tip_turn_deg(_shape(110.0)[:5], 25.0))  # shorter than twice the reach


def _out_and_back(reach_px: float = 100.0) -> np.ndarray:
    """A centreline from the fixed end 100 px down the rope and back up the other side, ending beside the fixed end
    (the still rope's outline round a clamp, walked out and back)."""
    down = _shape(100.0, length=int(reach_px))
    back = down[::-1] + np.float32([0.0, 3.0])
    return np.vstack([down, back]).astype(np.float32)


def test_a_shape_whose_free_tip_lies_at_the_fixed_end_is_not_trusted() -> None:
    checks = SelfChecks(ChecksConfig())
    loop = _out_and_back()
    single = {"begin": loop, "end": loop, "split": False}
    assert _check(checks, **single) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_AT_FIXED_END)
    assert _check(checks, **single, exposure_ns=0)[1] is not Reason.TIP_AT_FIXED_END  # a still photo: a looped rope
    assert _check(checks, begin=_shape(100.0), end=_shape(100.0), split=False) == (FrameStatus.OK, Reason.NONE)
    short = _shape(100.0, length=12)  # a stub shorter than twice the fixed end's reach: its tip is near it anyway
    assert _check(checks, begin=short, end=short, split=False, stretch_begin=None, stretch_end=None)[0] is (
        FrameStatus.OK
    )
    motion = MotionModel()  # with a motion prediction (a steady frame) the tips are checked against it instead
    for k in range(2):
        motion.observe(_shape(100.0), _shape(100.0), FIXED, k * 8_403_361 + 2_000_000, 0.0, 4_000_000)
    for _ in range(3):
        checks.predict(motion.state, motion.log, FIXED, 2 * 8_403_361, 4_000_000)
    assert _check(checks, **single) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_MOTION)


def test_a_split_tip_far_from_its_band_corner_is_not_trusted() -> None:
    checks = SelfChecks(ChecksConfig())
    corners = np.array([[210.0, 88.0], [210.0, 112.0]], np.float32)  # the band's far corners, beside each tip
    begin, end, off = _shape(90.0), _shape(110.0), _shape(98.0)
    assert tip_corner_px(begin, end, corners) == tip_corner_px(begin, end, corners[::-1].copy())  # either pairing
    assert _check(checks, corner_px=tip_corner_px(begin, end, corners)) == (FrameStatus.OK, Reason.NONE)
    # The end tip fitted 14 px along the band's end towards the begin tip's corner (limit 1.5 widths + 2 px = 9.5 px).
    far = tip_corner_px(begin, off, corners)
    assert far == pytest.approx(14.0)
    assert _check(checks, corner_px=far, end=off) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_CORNER)
    assert _check(SelfChecks(ChecksConfig(tip_corner_widths=0.0)), corner_px=far, end=off)[0] is FrameStatus.OK
    assert _check(checks, corner_px=far, end=off, exposure_ns=0)[1] is not Reason.TIP_CORNER
    assert _check(checks, end=off) == (FrameStatus.OK, Reason.NONE)  # not measured (nan): not checked


def test_a_split_whose_two_corners_coincide_has_no_tips_read_at_them() -> None:
    """The band's far end has two corners, about a rope width apart or more; a split whose corners lie within half
    a width (one corner found twice) while its tips lie apart did not read its tips at corners (simulated `rope
    photo texture = 2`, frame 46: corners 1.0 px apart, tips 8.0 px, a steady frame: checked with a motion
    prediction too)."""
    checks = SelfChecks(ChecksConfig())
    apart = np.array([[210.0, 91.0], [210.0, 109.0]], np.float32)
    once = np.array([[210.0, 100.0], [210.0, 101.0]], np.float32)  # 1 px apart, the tips 20 px
    assert _check(checks, corners=apart) == (FrameStatus.OK, Reason.NONE)
    assert _check(checks, corners=once) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_CORNER)
    # A tip moving along the rope: the band ends in a ramp whose two corners lie about the edges' spacing apart,
    # less the smoothing's rounding (rig-soft frame 54, right: 0.97 spacings), and the tips farther apart.
    ramp = np.array([[210.0, 97.6], [210.0, 102.4]], np.float32)
    assert _check(checks, corners=ramp) == (FrameStatus.OK, Reason.NONE)
    near = {"begin": _shape(99.0), "end": _shape(103.0)}  # tips 4 px apart: within the corners' 1 px + a width
    assert _check(checks, corners=once, **near) == (FrameStatus.OK, Reason.NONE)
    assert _check(checks, corners=None) == (FrameStatus.OK, Reason.NONE)  # not known: not checked
    assert _check(checks, corners=np.full((2, 2), np.nan, np.float32)) == (FrameStatus.OK, Reason.NONE)
    assert _check(SelfChecks(ChecksConfig(tip_corner_widths=0.0)), corners=once)[0] is FrameStatus.OK
    motion = MotionModel()  # a steady frame: the motion model predicts the tips' midpoint (100), as here
    for k in range(2):
        motion.observe(_shape(90.0), _shape(110.0), FIXED, k * 8_403_361 + 2_000_000, 20.0, 4_000_000)
    for _ in range(3):
        checks.predict(motion.state, motion.log, FIXED, 2 * 8_403_361, 4_000_000)
    assert _check(checks, corners=apart) == (FrameStatus.OK, Reason.NONE)
    assert _check(checks, corners=once) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_CORNER)


def _scene(*shapes: np.ndarray, size: tuple[int, int] = (260, 200)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A frame of a plate at 25 DN with a 5 px wide rope at 200 DN along each of `shapes` (row, col), and the
    plate's learned range: a still 22-28 DN everywhere (read-only arrays, as the mask's)."""
    frame = np.full(size, 25, np.uint8)
    for shape in shapes:
        for r, c in _along(shape):
            frame[r - 2 : r + 3, c - 2 : c + 3] = 200
    low, high = np.full(size, 22, np.uint8), np.full(size, 28, np.uint8)
    return frame, low, high


def _along(shape: np.ndarray) -> list[tuple[int, int]]:
    """The pixels of the polyline `shape` (row, col), sampled every 0.25 px."""
    out = []
    for a, b in zip(shape[:-1].astype(np.float64), shape[1:].astype(np.float64), strict=True):
        for t in np.linspace(0.0, 1.0, max(2, int(4 * np.hypot(*(b - a))) + 1)):
            out.append(tuple(np.floor(a + t * (b - a) + 0.5).astype(int)))
    return out


def _tip_end_seen_reference(shape, frame, low, high, width_px, reach_px, still_dn, relative):  # type: ignore[no-untyped-def]
    """Slow reference of `tip_end_seen`: the sample points from a pixel behind the tip to beyond it, as
    `_tip_mask_distance_reference` takes them."""
    from ropecam.device.pipeline._kernels.checks import TIP_END_BEYOND_WIDTHS, TIP_END_CLEAR_PX

    tip = shape[-1].astype(np.float64)
    back = next(
        (p.astype(np.float64) for p in shape[-2::-1] if np.hypot(*(tip - p)) >= 3.0), shape[0].astype(np.float64)
    )
    u = (tip - back) / np.hypot(*(tip - back))
    v = np.array([-u[1], u[0]])
    on_rope = False
    for along in np.arange(-1.0, reach_px + TIP_END_BEYOND_WIDTHS * width_px + 0.25, 0.5):
        if 0.0 < along < 0.5 * width_px + TIP_END_CLEAR_PX:
            continue
        for side in (-0.5 * width_px, 0.0, 0.5 * width_px):
            r, c = np.floor(tip + along * u + side * v + 0.5).astype(int)
            if not (0 <= r < frame.shape[0] and 0 <= c < frame.shape[1]):
                return False
            value, lo, hi = int(frame[r, c]), int(low[r, c]), int(high[r, c])
            inside = lo <= value <= hi
            if along <= 0.0:
                on_rope = on_rope or not inside
            elif not inside or hi - lo > still_dn + relative * hi:
                return False
    return on_rope


@pytest.mark.parametrize(
    "change", ["none", "speck far", "rope goes on", "speck beyond", "wide range", "tip off the rope", "rope cut"]
)
def test_tip_end_seen_matches_its_reference(change: str) -> None:
    from ropecam.device.pipeline import _kernels as K

    shape = _shape(100.0)  # from (10, 100) straight down to its tip at (210, 100)
    frame, low, high = _scene(shape)
    if change == "speck far":
        frame[240:242, 100:102] = 60  # a dust speck beyond the reach that was not there while learning
    elif change == "rope goes on":
        frame[211:225, 98:103] = 200  # the rope goes on 14 px past the shape's tip
    elif change == "speck beyond":
        frame[216:218, 100:102] = 60  # a speck 6 px past the tip
    elif change == "wide range":
        high[214:220, 90:110] = 220  # the rope crossed there while the mask was learned: it shows nothing
    elif change == "tip off the rope":
        frame[196:] = 25  # the rope ends 14 px short of the shape's tip: the tip ran on over the plate
    elif change == "rope cut":
        frame[211:214] = 25  # a masked plate edge the rope's edges were dropped at ...
        frame[214:230, 98:103] = 200  # ... and the rope beyond it
    frame.flags.writeable = low.flags.writeable = high.flags.writeable = False
    expected = _tip_end_seen_reference(shape, frame, low, high, WIDTH_PX, 7.0, 8.0, 0.1)
    assert K.tip_end_seen(shape, frame, low, high, WIDTH_PX, 7.0, 8.0, 0.1) == expected
    assert expected is (change in ("none", "speck far"))


def _learned_plate(size: tuple[int, int] = (260, 200)) -> object:
    """A static mask learned over a still plate at 25 DN (every range 22-28 DN: margin 3)."""
    from ropecam.device.pipeline.static_mask import StaticMask
    from ropecam.device.pipeline.workspace import EdgeBuffers

    static = StaticMask(EdgeBuffers.make(*size, np.ones(1, np.float32)), frames=1, margin_dn=3, relative=0.1)
    static.learn(np.full(size, 25, np.uint8))
    static.learn(np.full(size, 25, np.uint8))  # marks the mask: no structure on the plain plate
    assert static.marked and (static.buffers.static_low == 22).all() and (static.buffers.static_high == 28).all()
    return static


def test_a_tip_at_the_mask_with_the_learned_scene_beyond_it_is_trusted() -> None:
    """`tip_masked` stands where the frame cannot show the rope's end (no learned scene, the rope going on under
    the mask) and is withdrawn where it shows the rope at both tips and the still scene it learned beyond them
    (a speck of dust or the plate's grain masked just past a tip)."""
    from ropecam.device.pipeline.static_mask import StaticMask
    from ropecam.device.pipeline.workspace import EdgeBuffers

    begin, end = _shape(90.0), _shape(110.0)  # `_check`'s shapes, their tips at row 210
    frame, _, _ = _scene(begin, end)
    static = _learned_plate()
    checks = SelfChecks(ChecksConfig())
    mask = _mask_across(212)
    assert _check(checks, mask=mask) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_MASKED)
    assert _check(checks, mask=mask, static=static, frame=frame) == (FrameStatus.OK, Reason.NONE)
    cut = frame.copy()
    cut[214:230, 106:113] = 200  # the end shape's rope goes on past the mask: the mask cut it
    assert _check(checks, mask=mask, static=static, frame=cut) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_MASKED)
    fresh = StaticMask(EdgeBuffers.make(260, 200, np.ones(1, np.float32)), frames=1, margin_dn=3, relative=0.1)
    assert _check(checks, mask=mask, static=fresh, frame=frame)[1] is Reason.TIP_MASKED  # nothing learned yet
    # Withdrawn, the checks after it still run: a tip that turns at its end is still refused.
    kinked = _kinked(70.0)
    frame, _, _ = _scene(begin, kinked)
    assert _check(checks, end=kinked, mask=_mask_across(222), static=static, frame=frame)[1] is Reason.TIP_KINK


def test_one_shape_short_of_the_band_s_far_end_is_not_trusted() -> None:
    """One shape (the blur split's static fallback) of a stream ends where the band does: its tip farther than a
    rope width + 2 px (7 px here) from the contour's farthest point from the fixed end was read inside the band
    (simulated lab through the paper's camera at 9 ms, fresh device, frame 59: OK, 11.4 px short)."""
    from ropecam.device.pipeline import _kernels as K

    checks = SelfChecks(ChecksConfig())
    still = _shape(100.0)
    contour = np.array([[10.0, 98.0], [212.0, 98.0], [212.5, 100.0], [212.0, 102.0], [10.0, 102.0]], np.float32)
    far = np.full((1, 2), np.nan, np.float32)
    assert K.contour_far_end(contour, 5, FIXED, far) and far[0].tolist() == [212.5, 100.0]
    one = {"end": still, "split": False, "stretch_end": 1.01}
    assert _check(checks, begin=still, corners=far, **one) == (FrameStatus.OK, Reason.NONE)  # 2.5 px from it
    short = _shape(100.0, length=190)  # the static centreline's cap read 10 px inside the band
    one["end"] = short
    assert _check(checks, begin=short, corners=far, **one) == (FrameStatus.IMPLAUSIBLE, Reason.TIP_SHORT)
    assert _check(checks, begin=short, corners=far, exposure_ns=0, **one)[1] is not Reason.TIP_SHORT  # a photo
    assert _check(SelfChecks(ChecksConfig(tip_short_widths=0.0)), begin=short, corners=far, **one)[0] is FrameStatus.OK
    assert _check(SelfChecks(ChecksConfig(), fallback_single=False), begin=short, corners=far, **one)[0] is (
        FrameStatus.OK
    )  # the centreline method's one shape is its answer
    assert _check(checks, begin=short, corners=None, **one) == (FrameStatus.OK, Reason.NONE)  # not known
    assert not K.contour_far_end(contour, 0, FIXED, far) and np.isnan(far).all()
