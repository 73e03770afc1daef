"""ResultFinisher: a measured frame's result filled from its split (time order, material points, the motion
model's update, the plane) and checked (`SelfChecks`); FrameClock: the stream's frame period and exposures."""

from __future__ import annotations

import math

import numpy as np

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.checks import Reason, SelfChecks, contour_area_px2, folds_back, tip_corner_px
from ropecam.device.pipeline.contour import ContourTracer
from ropecam.device.pipeline.locate import RopeLocator
from ropecam.device.pipeline.motion import MotionModel
from ropecam.device.pipeline.result import FrameStatus, Method, PipelineResult, exposure_in_ns
from ropecam.device.pipeline.split import BlurSplitter, SplitOutcome
from ropecam.device.pipeline.static_mask import StaticMask
from ropecam.device.pipeline.time_order import DEFAULT_PERIOD_NS, TimeOrder
from ropecam.device.pipeline.tracking import PointTracker
from ropecam.device.pipeline.traits import RopeTraits

__all__ = ["BROKEN_OUTLINE", "FrameClock", "ResultFinisher", "max_age_ns"]

# Enum members the per-frame path reads, looked up once: reading an attribute of an Enum class costs Python 3.11 a
# 48-byte method-wrapper each time (its metaclass has a `__getattr__`), a Python allocation per frame.
_OK, _BLUR_SPLIT = FrameStatus.OK, Method.BLUR_SPLIT
_ORDER, _TIP_SHORT, _GUESS = Reason.ORDER.text, Reason.TIP_SHORT.text, Reason.FIXED_END_GUESS.text

BROKEN_OUTLINE = K.BROKEN_OUTLINE
"""Largest part of the contour's pixels walked twice (spurs of noise and texture) before it is no band outline (a
contour open at one end is joined first: `K.join_open_ends`)."""

REJOIN_REACH_PX = 20
"""How far apart (px, per axis) the two ends of a gap in a band's side may lie to be joined when the frame found no
split (`ContourTracer.rejoin_gap`): noise or texture breaks a side where the sweeping band is faint (simulated
`read noise = 10 DN`, seed 3 from 0.3 s, frames 2-4, and `rope photo texture = 2`, frames 9 and 11: gaps of 12-18 px
along one side, the outline walked out and back, the two sides 416 and 1128 px long)."""

UNDECIDED_ORDER = 0.6
"""Time order confidence below which a split of a small sweep (`UNDECIDED_SWEEP_WIDTHS`) is a coin flip."""

UNDECIDED_CONFIDENCE = 0.5
"""The time order's confidence of a split that nothing ordered (`K.order_shapes` without history)."""

UNDECIDED_SWEEP_WIDTHS = 1.25
"""Sweep (rope widths) below which a split whose time order is a coin flip (`UNDECIDED_ORDER`) reports the band's
middle line for both shapes: a wrong order there puts each shape a whole sweep off, the middle line half of it."""


def max_age_ns(period_ns: int | None) -> int:
    """The age (ns) past which the time order's history is dropped: `K.AGE_PERIODS` (four) frame periods of
    `period_ns` (None: the default period)."""
    return K.AGE_PERIODS * (period_ns or DEFAULT_PERIOD_NS)


class FrameClock:
    """A stream's frame period (the shortest time between frame starts seen) and each frame's exposure in ns.

    The period is kept in int64 cells (`K.CLOCK_CELLS`, ``cells``) that a kernel updates from each frame's start
    (`tick`; a steady frame's `steady_frame` call ticks them itself): the arithmetic on ns times makes no Python int
    per frame. `period_ns`, `max_age_ns` and `last_t_ns` read them on demand.
    """

    __slots__ = ("_exposure_key", "_exposure_value", "cells")

    def __init__(self, cells: np.ndarray | None = None) -> None:
        self.cells = np.zeros(len(K.CLOCK_CELLS), np.int64) if cells is None else cells
        """The clock's `K.CLOCK_CELLS` (int64; the pipeline's are in its workspace, where `steady_frame` reads
        them)."""
        self.cells[:] = 0
        self.cells[K.CLOCK.max_age_ns] = max_age_ns(None)
        self._exposure_key: float | None = None  # the last float exposure_us and what `exposure_in_ns` made of it
        self._exposure_value: tuple[int, str] = (0, "")

    @property
    def period_ns(self) -> int | None:
        """The frame period (ns; None until two frames were seen)."""
        return int(self.cells[K.CLOCK.period_ns]) or None

    @property
    def max_age_ns(self) -> int:
        """`max_age_ns` of `period_ns`."""
        return int(self.cells[K.CLOCK.max_age_ns])

    @property
    def last_t_ns(self) -> int | None:
        """The start of the last frame (ns; None before the first, or after it was set to None)."""
        return int(self.cells[K.CLOCK.last_t_ns]) if self.cells[K.CLOCK.seen] else None

    @last_t_ns.setter
    def last_t_ns(self, t_ns: int | None) -> None:
        self.cells[K.CLOCK.seen] = t_ns is not None
        self.cells[K.CLOCK.last_t_ns] = t_ns or 0

    def tick(self, t: int) -> None:
        """Take the start `t` (ns) of a frame: a gap from the last start shorter than the period is the new period
        (`K.tick_clock`)."""
        K.tick_clock(self.cells, t)

    def exposure(self, exposure_us: float | None) -> tuple[int, str]:
        """Return the exposure `exposure_us` in ns and what is wrong with it (`exposure_in_ns`)."""
        if type(exposure_us) is float and exposure_us == self._exposure_key:
            return self._exposure_value  # the usual case: the same exposure every frame
        exposure_ns, exposure_problem = exposure_in_ns(exposure_us)
        if type(exposure_us) is float:
            self._exposure_key, self._exposure_value = exposure_us, (exposure_ns, exposure_problem)
        return exposure_ns, exposure_problem


class ResultFinisher:
    """Fill a frame's result from its split and run the self-checks on it: the pipeline's last steps.

    Parameters
    ----------
    splitter, tracker, time_order, motion, checks, traits, tracer, locator
        The pipeline's stages whose results and state the last steps read and update.
    fixed
        The fixed end (row, col) float32 (`RopeTraits.fixed_end`).
    clock
        The stream's clock (the pipeline's): the frame period that ages the time order's history.
    static_mask
        The learned static mask (None: a ``tip_masked`` verdict always stands).
    """

    def __init__(
        self,
        splitter: BlurSplitter,
        tracker: PointTracker,
        time_order: TimeOrder,
        motion: MotionModel,
        checks: SelfChecks,
        traits: RopeTraits,
        tracer: ContourTracer,
        locator: RopeLocator,
        fixed: np.ndarray,
        clock: FrameClock,
        static_mask: StaticMask | None = None,
    ) -> None:
        self.clock = clock
        self.static_mask = static_mask
        """The learned static mask: its scene tells a tip at the mask from a rope the mask cut (`SelfChecks.check`)."""
        self.splitter, self.tracker, self.time_order, self.motion = splitter, tracker, time_order, motion
        self.checks, self.traits, self.tracer, self.locator, self.fixed = checks, traits, tracer, locator, fixed
        self._far_end = np.full((1, 2), np.nan, np.float32)
        """The contour's farthest point from the fixed end (`K.contour_far_end`) of a one-shape frame."""
        self.short_only = False
        """Whether the last checked frame failed ``tip_short`` alone (every other check passed: OK but for it)."""
        self.after_still = False
        """Whether the last frame that reached the self-checks was a single shape (a still rope): the time order of
        a split right after it has no motion to go by."""
        self.rejoined = False
        """Whether the last frame's shapes were read from its outline with a gap in a side joined (`_rejoined`)."""

    def finish(
        self,
        result: PipelineResult,
        outcome: SplitOutcome | None,
        exposure_ns: int,
        revisits: int | None = None,
        tracked: tuple[int, float, float, float] | None = None,
    ) -> None:
        """Fill `result` from the split's `outcome`: the shapes in time order and the material points (with
        `tracked`, the results of a `track_frame` call made on them already), or why there are none; the contour's
        pixels walked twice `revisits` (None: counted here when needed). The frame period is the clock's."""
        rejected = ""
        self.short_only = False
        self.rejoined = False
        if not exposure_ns and (outcome is None or self._still(outcome)):
            # Unknown exposure (a still photo) and no split, or one without blur between its tips: the rope is
            # the static centreline, which follows the contour whole where a split's two sides may pair across a
            # loop of the rope.
            rejected = self.splitter.failure if outcome is None else ""
            outcome = self.splitter.static((float(self.fixed[0]), float(self.fixed[1]))) or outcome
        if outcome is None and exposure_ns > 0:
            outcome = self._rejoined()
            revisits = None
        if outcome is None:
            result.status = FrameStatus.LOST_TRACK
            result.message = self.splitter.failure
            return
        n = self.locator.prev_count
        # Two shapes read from the outline's two sides, of a known exposure (without one, a split needs evidence of
        # blur anyway, `checks.no_blur`, and a still photo's looped rope walks its crossings twice).
        split = outcome.shape_a is not outcome.shape_b and exposure_ns > 0
        if not split:
            revisits = 0
        elif revisits is None:
            revisits = K.count_revisits(self.tracer.chain_ro, np.int32(n), self.locator.edges.edges)
        if revisits > BROKEN_OUTLINE * n:
            rejoined = self._rejoined()
            if rejoined is not None and rejoined.shape_a is not rejoined.shape_b:
                outcome, n = rejoined, self.locator.prev_count
                revisits = K.count_revisits(self.tracer.chain_ro, np.int32(n), self.locator.edges.edges)
        if revisits > BROKEN_OUTLINE * n:
            # A faint far side on a textured plate broke the band's edge: the contour went out along each piece
            # and back (a tree walk), and any two "sides" read from it are guesses.
            result.status = FrameStatus.LOST_TRACK
            result.message = (
                f"the band's edge is broken: the contour walks {100.0 * revisits / n:.0f} % of its pixels twice "
                f"(more than {100.0 * BROKEN_OUTLINE:.0f} %), it is not the band's outline"
            )
            return
        self._take_outcome(result, outcome)
        tracker = self.tracker
        a, b = outcome.shape_a, outcome.shape_b
        # The split's fitted tips against its segmentation points (``tip_corner``), before the tracking may move the
        # tips along the sweep (`restore_tip_sweep`; `check` adds the tips as reported). Tips within a rope width
        # of each other are a band's end read as a ramp (a tip moving along its own axis: simulated rig-soft's
        # whip, 0.672 s, frame 5: tips 1.7 px apart, a corner 12.8 px on, both tips right after the restore): the
        # restore decides those, not this check. Only where the check runs: no motion prediction (`needs_area`).
        corners = outcome.segmentation_points
        corner_px = math.nan
        if (
            split
            and tracked is None
            and self.checks.needs_area(exposure_ns)
            and corners is not None
            and len(corners) == 2
            and _tip_gap_px(a, b) > float(outcome.width_px)
        ):
            corner_px = tip_corner_px(a, b, corners)
        if tracked is not None:
            swap, confidence, stretch_begin, stretch_end = tracked
        elif tracker.length0_settled_px >= 0.0:
            # Time order, material points and the motion model's update in one kernel call (`track_frame`: as
            # `TimeOrder.order`, `PointTracker.track_shapes` and `MotionModel.observe` in turn); a negative `swap`
            # (an empty shape, a shape longer than the tracker's scratch) has written nothing.
            order, motion = self.time_order, self.motion
            try:
                swap, confidence, stretch_begin, stretch_end = K.track_frame(
                    a, b, a is b, result.t_ns, result.t_end_ns, self.clock.max_age_ns, order.group, self.fixed,
                    float(self.splitter.sweep_px), exposure_ns, motion.group, tracker.length0_settled_px, tracker.group,
                    float(outcome.width_px),
                )  # fmt: skip
            except TypeError:  # not the splitter's writable float32 buffers
                swap = -1
        else:
            swap = -1
        if swap >= 0:
            self._take_tracked(result, outcome, swap, confidence, stretch_begin, stretch_end)
        else:
            # The first frames (Lc0 still being measured) or shapes `track_frame` does not take: step by step.
            begin, end, confidence = self.time_order.order(a, b, result.t_ns, result.t_end_ns, self.clock.period_ns)
            result.begin, result.end, result.order_confidence = begin, end, confidence
            (result.material_begin, result.stretch_begin, result.material_end, result.stretch_end) = (
                tracker.track_shapes(begin, end)
            )
            t_mid_ns = result.t_ns + exposure_ns // 2
            self.motion.observe(begin, end, self.fixed, t_mid_ns, float(self.splitter.sweep_px), exposure_ns)
        self._conclude(result, outcome, exposure_ns, corner_px=corner_px)
        if rejected and result.status is FrameStatus.OK:
            result.status, result.reason = FrameStatus.NO_BLUR, Reason.NO_BLUR.text
            result.message = f"{self.checks.message(Reason.NO_BLUR)} (the split: {rejected})"
        if result.status is _OK and exposure_ns > 0 and self.checks.config.enabled:
            self._refuse_guess(result)

    def _refuse_guess(self, result: PipelineResult) -> None:
        """``fixed_end_guess``: an OK frame of known exposure measured about a fixed end that is only a guess on a
        contour (`FixedEndFinder.confirmed` false: not given, held by no structure, no end yet seen staying while
        the other moved) is not reported OK unless it shows a rope at rest (`FixedEndFinder.still`, and its two
        shapes' tips within a rope width): a rope already swinging when the stream starts may have had its fixed
        end guessed at the free tip, and its shapes then run from the tip (simulated `read noise = 10 DN` from 0.4 s,
        tuning seed, frame 0: OK with both tips 404 px off). The frame is otherwise a measured one
        (`measured_all_the_same`): once the end is confirmed (the next frame, where the free end has moved) the
        frames are measured as before, about the other end if the guess was wrong (`FixedEndFinder.find`)."""
        finder = self.traits.fixed_end
        if finder.confirmed:
            return
        begin, end = result.begin, result.end
        still = finder.still
        if still and begin is not None and end is not None and begin is not end and len(begin) and len(end):
            still = _tip_gap_px(begin, end) <= (self.traits.width() or 4.0)
        if not still:
            result.status, result.reason = FrameStatus.IMPLAUSIBLE, _GUESS
            result.message = self.checks.message(Reason.FIXED_END_GUESS)

    def measured_all_the_same(self, result: PipelineResult) -> bool:
        """Whether `result`, flagged, was measured as an OK frame is (its rope, ROI and motion are right, and the
        pipeline's state goes on as after an OK frame): a split whose time order nothing decided (``order``), or
        one shape that only ``tip_short`` flagged (its contour is the band's; its centreline's tip is not)."""
        return result.reason == _ORDER or result.reason == _GUESS or (result.reason == _TIP_SHORT and self.short_only)

    def refuse_fold(self, result: PipelineResult, lengths_seen: int) -> None:
        """After `finish` of a frame of known exposure measured before Lc0 is known (the tracker had seen
        `lengths_seen` lengths before it): an OK shape that runs out along the rope and back or crosses itself
        (`folds_back`) is a `length` status, and its length is taken back from the Lc0 estimate. The `length` check
        needs Lc0, which the first shapes are still measuring (simulated lab-hard with its gamma, frame 0: out
        400 px and back 260, OK with its tip 260 px off). Streams only: a still photo's rope may lie in loops. No
        status with the self-checks off (`checks.enabled`)."""
        begin, end = result.begin, result.end
        # (a one-shape frame only `tip_short` flagged passed every other check: its fold is withdrawn from Lc0 too)
        # (nor is one flagged only as measured about a guessed fixed end, `_refuse_guess`)
        flagged = result.status is not FrameStatus.OK and not self.short_only and result.reason != _GUESS
        if flagged or begin is None or end is None:
            return
        if not (folds_back(begin, result.rope_width_px) or folds_back(end, result.rope_width_px)):
            return
        tracker = self.tracker
        tracker.withdraw(tracker.lengths_seen - lengths_seen)
        if self.checks.config.enabled:
            result.status, result.reason = FrameStatus.IMPLAUSIBLE, Reason.LENGTH.text
            result.message = (
                "the rope's length is implausible: before Lc0 is known, a shape runs out and back along itself (its "
                "tip lies on its own earlier part)"
            )

    def finish_tracked(
        self,
        result: PipelineResult,
        outcome: SplitOutcome,
        exposure_ns: int,
        swap: int,
        confidence: float,
        stretch_begin: float,
        stretch_end: float,
        checked: int = -1,
        placed: int = -1,
    ) -> None:
        """`finish` of a frame of known exposure (`exposure_ns` > 0) whose split made two shapes that are the
        band's outline, and whose `track_frame` call was made (`steady_frame` returned STEADY_DONE): its results
        `swap`, `confidence`, `stretch_begin`, `stretch_end` are taken as they are (no tuple made per frame).
        `checked` is the code of the `check_frame` call `steady_frame` made on the shapes (-1: none, `check` makes
        it here); `placed` 1 when it placed their material points on the plane (-1: placed here, if on a plane)."""
        self.rejoined = False
        self._take_outcome(result, outcome)
        self._take_tracked(result, outcome, swap, confidence, stretch_begin, stretch_end)
        self._conclude(result, outcome, exposure_ns, checked, placed)

    def _take_outcome(self, result: PipelineResult, outcome: SplitOutcome) -> None:
        result.method = outcome.method
        result.rope_width_px = outcome.width_px
        result.segmentation_points = outcome.segmentation_points
        result.material_arc_m = self.tracker.arc_m

    def _take_tracked(
        self, result: PipelineResult, outcome: SplitOutcome, swap: int, confidence: float, stretch_begin: float,
        stretch_end: float,
    ) -> None:  # fmt: skip
        """Take `track_frame`'s results on the outcome's shapes (in the tracker's buffers)."""
        if swap:
            result.begin, result.end = outcome.shape_b, outcome.shape_a
        else:
            result.begin, result.end = outcome.shape_a, outcome.shape_b
        result.order_confidence = confidence
        result.material_begin, result.material_end = self.tracker.out_slots
        result.stretch_begin, result.stretch_end = stretch_begin, stretch_end

    def _conclude(
        self, result: PipelineResult, outcome: SplitOutcome, exposure_ns: int, checked: int = -1, placed: int = -1,
        corner_px: float = math.nan,
    ) -> None:  # fmt: skip
        """The shapes on the plane (when calibrated; done already when `placed` is 1), status OK, then the
        self-checks (made already when `checked` is a `check_frame` code, not -1). The first split after a still
        rope (`after_still`) of a sweep below `UNDECIDED_SWEEP_WIDTHS` rope widths whose time order is a coin flip
        (confidence below `UNDECIDED_ORDER`: the still frames give no motion to go by) reports the band's middle
        line instead (its confidence kept). `corner_px`: the split's tips from its segmentation points, as
        `check` takes it."""
        self.short_only = False  # (every frame's, `finish_tracked`'s too: `_take_verdict` sets it)
        after_still, self.after_still = self.after_still, outcome.shape_a is outcome.shape_b
        if (
            after_still
            and outcome.method is _BLUR_SPLIT
            and result.order_confidence < UNDECIDED_ORDER
            and outcome.sweep_px < UNDECIDED_SWEEP_WIDTHS * outcome.width_px
        ):
            static = self._use_static(result)
            if static is not None:
                outcome, placed, checked = static, 1, -1
        if placed < 0 and self.tracker.plane is not None:  # by arc length on the plane (metres), not in pixels
            self.tracker.place_on_plane(result.begin, result.end)
        result.status = _OK
        if checked < 0:  # (`steady_frame` withdrew a tip_masked the frame disproves, as `check` does)
            self.check(result, outcome, exposure_ns, corner_px)
        else:
            status, reason = self.checks.verdict(checked)
            self._take_verdict(result, outcome, exposure_ns, status, reason)

    def _rejoined(self) -> SplitOutcome | None:
        """The split of the frame's contour with a gap in one of its sides joined (`ContourTracer.rejoin_gap`): two
        shapes, or None (no such gap, the joined outline no ring, or still no split, or a single shape: the
        contour, the splitter's state and its failure then as they were). A cold path, for a frame that found no
        split or whose outline was broken: the joined contour becomes the frame's (the locator keeps it for the
        next band). The default method only: the paper's and the centreline methods stay the references they
        were."""
        tracer, edges, traits = self.tracer, self.locator.edges, self.traits
        if self.splitter.method != "blur_split":
            return None
        n = self.locator.prev_count
        saved = (tracer.chain[:n].copy(), tracer.codes[:n].copy(), tracer.points[:n].copy(), tracer.count)
        failure = self.splitter.failure
        if tracer.rejoin_gap(edges, REJOIN_REACH_PX) == 0:
            return None
        readings = len(self.splitter.measure.contrasts)  # the frame's own split read the contrast already
        if traits.settled is not None:
            width_px, fixed_rc, _, polarity = traits.settled
        else:
            width_px, polarity = traits.width(), traits.polarity()
            fixed_rc = (float(self.fixed[0]), float(self.fixed[1]))
        m = tracer.count
        args = (fixed_rc, width_px, edges.gx, edges.gy, edges.edges, edges.mag, edges.smooth, polarity)
        outcome = self.splitter.split(tracer.points, tracer.chain, m, *args, edge_stage=edges, frame=edges.frame)
        if outcome is not None and outcome.shape_a is not outcome.shape_b:
            self.splitter.measure.keep_readings(readings)
            self.locator.prev_count = m
            self.rejoined = True
            return outcome
        # No two shapes on the joined contour: the frame's own contour back, and its split made again (the
        # splitter's state as the frame left it).
        tracer.chain[:n], tracer.codes[:n], tracer.points[:n] = saved[0], saved[1], saved[2]
        tracer.count = saved[3]
        self.splitter.split(tracer.points, tracer.chain, n, *args, edge_stage=edges, frame=edges.frame)
        self.splitter.measure.keep_readings(readings)
        self.splitter.failure = failure
        return None

    def _still(self, outcome: SplitOutcome) -> bool:
        """Whether `outcome` is a split without blur between its tips (closer than ``checks.no_blur_px``)."""
        a, b = outcome.shape_a, outcome.shape_b
        return a is not b and len(a) > 0 and len(b) > 0 and _tip_gap_px(a, b) <= self.checks.config.no_blur_px

    def check(
        self, result: PipelineResult, outcome: SplitOutcome, exposure_ns: int, corner_px: float = math.nan
    ) -> None:
        """Run the self-checks on a measured frame (`SelfChecks.check`): a failed one sets the status, the reason
        and the message; a split without blur is replaced by the static centreline. `corner_px` is how far the
        split's fitted tips lay from its segmentation points before the tracking moved them (`tip_corner_px`;
        nan: not checked)."""
        begin, end = result.begin, result.end
        if begin is None or end is None or len(begin) == 0 or len(end) == 0:
            return
        traits = self.traits
        learned_px = traits.settled[0] if traits.settled is not None else traits.width()
        checks = self.checks
        split = outcome.shape_a is not outcome.shape_b
        # The contour's area only where it is the evidence: a split of unknown exposure or without a prediction.
        area = 0.0
        if split and checks.needs_area(exposure_ns):
            area = contour_area_px2(self.tracer.points, self.locator.prev_count)
        used_px = self._check_width(outcome)
        corners = outcome.segmentation_points
        if split and corners is not None and not math.isnan(corner_px):
            # ... and the tips as reported: a restore that moved them off the corners is not trusted either
            # (simulated paper-soft 15 ms, tuning seed, frame 48: tips 7 px apart as fitted, moved to 16.9, the end
            # tip 3.8 px off).
            corner_px = max(corner_px, tip_corner_px(begin, end, corners))
        # A split that found no history to be ordered by keeps its own pairing with confidence 0.5 and leaves the
        # time order's history unordered (the next frame orders both): nothing decided which shape came first.
        undecided = (
            split
            and exposure_ns > 0
            and result.order_confidence == UNDECIDED_CONFIDENCE
            and not self.time_order.state[K.ORDER_ORDERED]
        )
        if not split and exposure_ns > 0:
            # One shape: the band's far end it should reach (``tip_short``), from the contour it was read on.
            K.contour_far_end(self.tracer.points_ro, self.locator.prev_count, self.fixed, self._far_end)
            corners = self._far_end
            if checks.checks_sweep:
                # A motion model cleared by a flagged frame (``fallback_sweep`` clears it) gives no sweep: the time
                # order's history still holds the last frames' tips, and this shape's tip is the tip at
                # mid-exposure (simulated lab-mjpeg set up from its first 2 s, tuning seed, frame 70: the third of
                # three static fallbacks after two flagged ones, the tip 10.7 px on from frame 69's, a sweep of
                # 4.7 px, its tip 3.04 px off and reported OK).
                K.predict_sweep_from_history(
                    result.t_ns + exposure_ns // 2, exposure_ns, self.clock.max_age_ns,
                    self.time_order.state, self.time_order.hist_rc, begin, checks.buffers[0],
                )  # fmt: skip
        status, reason = checks.check(
            begin, end, self.fixed, result.stretch_begin, result.stretch_end, used_px, learned_px,
            result.order_confidence, exposure_ns, split, area, self.locator.edges.static_mask_ro,
            corner_px, corners if split or exposure_ns > 0 else None, undecided, self.static_mask,
            self.locator.edges.frame,
        )  # fmt: skip
        self._take_verdict(result, outcome, exposure_ns, status, reason)

    def _take_verdict(
        self, result: PipelineResult, outcome: SplitOutcome, exposure_ns: int, status: FrameStatus, reason: Reason
    ) -> None:
        """Give `result` the self-checks' measures and, when one failed, its `status` and `reason` (a split without
        blur, or of an unknown exposure, is replaced by the static centreline or dropped)."""
        checks = self.checks
        result.quality = checks.quality
        if status is _OK:
            return
        self.short_only = reason is Reason.TIP_SHORT
        split = outcome.shape_a is not outcome.shape_b
        result.status, result.reason, result.message = status, reason.text, checks.message(reason)
        if reason is Reason.NO_BLUR and self.rejoined:
            # A gap was joined only because the split of a blurred band failed: a joined outline without blur is
            # no band (simulated lab-hard through the paper's camera at 1 ms, tuning seed, frame 40: NO_BLUR with
            # a centreline 309 px off). The frame stays lost, as it was.
            result.status, result.reason = FrameStatus.LOST_TRACK, ""
            result.message = "a band's side joined across a gap shows no blur: not the rope's band"
            result.begin = result.end = result.material_begin = result.material_end = None
            return
        if reason is Reason.NO_BLUR or (split and not exposure_ns):
            static = self._use_static(result)
            if static is None:
                # Without a known exposure only a split that passes every check shows blur: never report another.
                result.begin = result.end = result.material_begin = result.material_end = None
            elif exposure_ns > 0 and self._short(static.shape_a, self._check_width(outcome)):
                # The static centreline given instead is one shape too: it must reach the band's far end (simulated
                # lab-hard through the paper's camera at 9 ms, fresh device, tuning seed, frame 28: NO_BLUR with a
                # centreline 58 px off, its tip 10.7 px from the contour's far end).
                result.status, result.reason = FrameStatus.IMPLAUSIBLE, Reason.TIP_SHORT.text
                result.message = checks.message(Reason.TIP_SHORT)

    def _check_width(self, outcome: SplitOutcome) -> float:
        """The width the self-checks compare where no width is learned yet: the split reports the rope's width
        (`EdgeTables.width_px`), the traits the edges' spacing, so for a blur split the spacing (a thin rope's edges
        lie up to 3x its width apart, and its width read from them swings by 2x for a 0.1 px change of spacing)."""
        return self.splitter.width if outcome.method is _BLUR_SPLIT else outcome.width_px

    def _short(self, shape: np.ndarray, width_px: float) -> bool:
        """``tip_short`` of one shape of this frame's contour (`K.tip_short`: its tip against the contour's far end,
        the learned width or else `width_px`)."""
        traits = self.traits
        learned_px = traits.settled[0] if traits.settled is not None else traits.width()
        K.contour_far_end(self.tracer.points_ro, self.locator.prev_count, self.fixed, self._far_end)
        return bool(K.tip_short(shape, self._far_end, learned_px or width_px, self.checks.buffers[1]))

    def _use_static(self, result: PipelineResult) -> SplitOutcome | None:
        """Give `result` the static centreline of the frame's contour (one shape for both instants, its material
        points, on the plane when calibrated) and return its outcome; None when there is none."""
        static = self.splitter.static((float(self.fixed[0]), float(self.fixed[1])))
        if static is None:
            return None
        result.method, result.segmentation_points = static.method, None
        result.begin = result.end = static.shape_a
        (result.material_begin, result.stretch_begin, result.material_end, result.stretch_end) = (
            self.tracker.track_shapes(static.shape_a, static.shape_a)
        )
        if self.tracker.plane is not None:
            self.tracker.place_on_plane(static.shape_a, static.shape_a)
        return static


def _tip_gap_px(begin: np.ndarray, end: np.ndarray) -> float:
    """Distance between the free tips (last points, row/col) of two shapes."""
    return float(np.hypot(*(end[-1] - begin[-1])))
