"""Pipeline: one frame in, the rope at the start and the end of the exposure out (with material points).

It keeps the frame's sequence: locate the rope's contour (`RopeLocator`), split it into the two shapes
(`BlurSplitter`), put them in time order (`TimeOrder`) and track the material points (`PointTracker`); the rope's
width, polarity and fixed end are learned over the first frames (`RopeTraits`). Once they have settled and the
last frame was found in its band, a frame is one kernel call (`SteadyFrame`). Every buffer is the workspace's
(`Workspace`), allocated once per image size.
"""

from __future__ import annotations

import time
from dataclasses import replace
from operator import attrgetter

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.checks import Reason, SelfChecks, contour_area_px2
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.contour import ContourTracer
from ropecam.device.pipeline.edges import EdgeDetector, gaussian_weights
from ropecam.device.pipeline.locate import RopeLocator
from ropecam.device.pipeline.motion import MotionModel
from ropecam.device.pipeline.result import FrameResult, FrameStatus, Method, exposure_in_ns, frame_problem
from ropecam.device.pipeline.split import BlurSplitter, SplitOutcome
from ropecam.device.pipeline.static_mask import StaticMask
from ropecam.device.pipeline.steady import SteadyFrame
from ropecam.device.pipeline.thresholds import EdgeThresholds
from ropecam.device.pipeline.time_order import DEFAULT_PERIOD_NS, TimeOrder
from ropecam.device.pipeline.tracking import PointTracker, plane_params
from ropecam.device.pipeline.traits import RopeTraits
from ropecam.device.pipeline.workspace import Workspace
from ropecam.shared.config import check_readout
from ropecam.shared.errors import ConfigError
from ropecam.shared.plane import PlaneCalibration

__all__ = ["BROKEN_OUTLINE", "Pipeline"]

BROKEN_OUTLINE = 0.15
"""Largest part of the contour's pixels walked twice (spurs of noise and texture) before it is no band outline."""

_NO_COPY = (
    "a Pipeline cannot be copied or pickled: its steady frames read a table of the raw addresses of its buffers, "
    "which a copy would share; make a new Pipeline(config, image_size) instead"
)


class Pipeline:
    """Measure the rope in each frame.

    Parameters
    ----------
    config
        Pipeline settings.
    image_size
        (width, height) of every frame; frames of another size get status BAD_FRAME.
    readout_us
        The camera's rolling-shutter readout time (microseconds, 0 = global shutter): every result's
        ``readout_ns``, the time row r of a shape was seen being ``t_ns + r / height * readout_ns`` (begin) and
        ``t_end_ns + r / height * readout_ns`` (end).
    plane
        The plane calibration (`ropecam.shared.plane.read_plane_file`) or None: its origin projected into the
        image is the fixed end (unless the config gives `fixed_end_uv`).

    Raises
    ------
    ConfigError
        The plane origin projects outside the image; `readout_us` is negative.
    """

    def __init__(
        self,
        config: PipelineConfig,
        image_size: tuple[int, int],
        readout_us: int = 0,
        plane: PlaneCalibration | None = None,
    ) -> None:
        width, height = (int(v) for v in image_size)
        if width < 8 or height < 8:
            raise ValueError(f"image_size must be at least 8x8, got {image_size}")
        check_readout("readout_us", readout_us, None)
        self.readout_ns = int(readout_us) * 1000
        """Every result's ``readout_ns`` (0: global shutter)."""
        self.plane = plane
        if plane is not None:
            if tuple(plane.image_size) != (width, height):
                raise ConfigError(
                    f"{plane.source}: calibrated for {plane.image_size[0]}x{plane.image_size[1]} images, the frames "
                    f"are {width}x{height}; expected a plane calibration of this camera at this resolution"
                )
            plane.check_image((width, height))
            if config.fixed_end_uv is None:
                config = replace(config, fixed_end_uv=plane.origin_uv())
        self.config = config
        self.shape = (height, width)
        cap = config.max_contour
        weights = gaussian_weights(config.smooth_sigma_px)
        fraction = np.array(config.material_points_m, np.float64) / config.rope_length_m
        self.workspace = ws = Workspace.make(height, width, cap, weights, fraction)
        """Every buffer of the per-frame path, by stage (its arrays cannot be replaced: `steady_frame`'s table
        holds their addresses)."""
        self.edges = EdgeDetector(height, width, config.smooth_sigma_px, config.canny_low, config.canny_high, ws.edges)
        self.tracer = ContourTracer(height, width, cap, config.min_contour_px, buffers=ws.contour)
        given = None
        if config.static_mask_png:
            from ropecam.device.capture.mask_file import read_mask_png  # a file read once, at construction

            given = read_mask_png(config.static_mask_png, self.shape)
        self.static_mask = StaticMask(
            ws.edges, config.static_frames, config.static_margin_dn, config.static_relative, given
        )
        """The static structures whose edges are dropped (learned over the first `static_frames` frames)."""
        self.thresholds = EdgeThresholds(
            height,
            width,
            config.smooth_sigma_px,
            config.canny_low,
            config.canny_high,
            config.threshold_frames,
            update_frames=config.threshold_update_frames,
        )
        """The Canny thresholds measured on the first `threshold_frames` frames (at most `canny_low`/`high`), then
        followed every `threshold_update_frames` frames."""
        self.splitter = BlurSplitter(
            cap, config.method, config.static_ratio, config.corner_scale_px,
            config.paper_endpoint_radius_px, config.output_step_px, config.tip_cap, config.smooth_sigma_px,
            config.lens_blur_px, output_smoothing_px=config.output_smoothing_px, buffers=ws.split,
        )  # fmt: skip
        self.splitter.paper.radius_scaled = config.paper_endpoint_radius_scaled
        self.tracker = PointTracker(
            config.material_points_m, config.rope_length_m, config.length0_px, config.length0_frames, ws.track
        )
        if plane is not None:
            self.tracker.plane = plane_params(plane)
        self.traits = RopeTraits(config, self.shape, ws.fixed_end, self.splitter.model.edge_spacing)
        self.fixed = ws.fixed_end.fixed
        """The fixed end (row, col) float32 (`RopeTraits.fixed_end`)."""
        self._motion = MotionModel(ws.motion)
        self.checks = SelfChecks(config.checks)
        """The self-checks that turn an implausible frame into a status with a reason (`SelfChecks`)."""
        self._time_order = TimeOrder(ws.order)
        self.locator = RopeLocator(
            config.roi_margin_px, self.edges, self.tracer, self._motion, self.traits.fixed_end, config.canny_low,
            ws.roi,
        )  # fmt: skip
        self.one_call = True
        """Make a steady frame in one kernel call (`steady_frame`); False: with the calls one by one (the same
        results; the tools that time or record single kernels set it)."""
        self._steady = SteadyFrame(
            ws, config.roi_margin_px, self.edges, self.tracer, self.splitter, self.tracker, self.locator, self.traits
        )
        self._exposure_key: float | None = None  # the last float exposure_us and what `exposure_in_ns` made of it
        self._exposure_value: tuple[int, str] = (0, "")
        self._u8 = np.dtype(np.uint8)
        self._strides = (width, 1)
        self._period_ns: int | None = None  # the shortest time between frame starts seen: the frame period
        self._last_frame_t_ns: int | None = None
        self._unclean_frames = 0  # frames without an OK result while the static mask was being learned

    def __copy__(self) -> Pipeline:
        raise TypeError(_NO_COPY)

    def __deepcopy__(self, memo: dict[int, object]) -> Pipeline:
        raise TypeError(_NO_COPY)

    def __reduce_ex__(self, protocol: object) -> tuple[object, ...]:
        raise TypeError(_NO_COPY)

    # What the locator keeps and counts (tests and tools read them here).
    lo = property(attrgetter("locator.lo"), doc="The first column of each row of the last band searched.")
    hi = property(attrgetter("locator.hi"), doc="The last column of each row of the last band searched.")
    frames_roi = property(attrgetter("locator.frames_roi"), doc="Frames found in the band predicted for them.")
    frames_coarse = property(attrgetter("locator.frames_coarse"), doc="Frames found around the coarse search's cells.")
    frames_full = property(attrgetter("locator.frames_full"), doc="Frames searched whole.")
    roi_retries = property(attrgetter("locator.roi_retries"), doc="Widenings of a band the rope ran out of.")

    # ----------------------------------------------------------------------------------------------------------
    def process(self, frame: object, index: int, t_ns: int, exposure_us: float | None) -> FrameResult:
        """Measure one frame.

        Parameters
        ----------
        frame
            (height, width) uint8 image; anything else gives status BAD_FRAME (never an exception).
        index
            Frame number.
        t_ns
            Start of the exposure in integer nanoseconds.
        exposure_us
            Exposure time in microseconds; 0 or None when unknown (then ``t_end_ns == t_ns``, the shapes get no
            time order (confidence 0.5) and the ROI follows the tip's frame-to-frame steps). A negative or
            non-finite value gives status BAD_FRAME.

        Returns
        -------
        FrameResult
            Arrays in it are views into the pipeline's buffers, valid until the next call.
        """
        start_ns = time.perf_counter_ns()
        t = int(t_ns)
        last = self._last_frame_t_ns
        if last is not None and t > last:
            gap_ns = t - last
            period = self._period_ns
            self._period_ns = gap_ns if period is None or gap_ns < period else period
        self._last_frame_t_ns = t
        if type(exposure_us) is float and exposure_us == self._exposure_key:
            exposure_ns, exposure_problem = self._exposure_value  # the usual case: the same exposure every frame
        else:
            exposure_ns, exposure_problem = exposure_in_ns(exposure_us)
            if type(exposure_us) is float:
                self._exposure_key, self._exposure_value = exposure_us, (exposure_ns, exposure_problem)
        result = FrameResult(int(index), t, t + exposure_ns, FrameStatus.BAD_FRAME)
        result.readout_ns = self.readout_ns
        if type(frame) is np.ndarray and frame.dtype is self._u8 and frame.shape == self.shape:
            problem = exposure_problem  # the usual case, without building the messages of `frame_problem`
        else:
            problem = frame_problem(frame, self.shape) or exposure_problem
        if problem:
            result.message = problem
            self._forget(roi=True)
        else:
            assert isinstance(frame, np.ndarray)
            image = frame if frame.strides == self._strides else np.ascontiguousarray(frame)
            if self.thresholds.measuring:
                measured = self.thresholds.measure(image)
                if measured is not None:
                    self._set_thresholds(*measured)
            elif self.thresholds.following:
                followed = self.thresholds.follow(image)
                if followed is not None:
                    self._set_thresholds(*followed)
            if self.static_mask.learning:
                self.static_mask.learn(image)
                if not self.static_mask.learning and self._unclean_frames > 0:
                    self._relearn()
            motion = self._motion
            self.checks.predict(motion.state, motion.log, self.fixed, t, exposure_ns, self.traits.settled is not None)
            self._measure(image, result, exposure_ns)
            if result.status is not FrameStatus.OK:
                self._forget(roi=result.status is FrameStatus.NO_ROPE)
                if self.static_mask.learning:
                    self._unclean_frames += 1
            elif exposure_ns == 0:
                result.message = "exposure unknown (0): no time order, the ROI follows the tip steps only"
        result.pipeline_us = (time.perf_counter_ns() - start_ns) / 1000.0
        return result

    def warm_up(self) -> None:
        """Prepare everything a stream's first frames would otherwise pay for, before the stream starts.

        Runs a blank frame (every buffer touched, the kernels' dispatch ready; it finds no rope and leaves no
        state) and, when the config gives `rope_width_px`, builds the edge model's tables for that width (10-20 ms,
        once per process: `edge_model.shared_model`). A measured width is known only from the first frames; its
        tables are then built on the frame that first needs them.
        """
        height, width = self.shape
        loc = self.locator
        counters = (loc.frames_full, loc.frames_coarse, loc.frames_roi, loc.roi_retries)
        # A blank frame teaches nothing.
        learn_frames, self.static_mask.frames = self.static_mask.frames, 0
        measure_frames, self.thresholds.frames = self.thresholds.frames, 0
        self.process(np.zeros((height, width), np.uint8), 0, 0, 0.0)
        self.static_mask.frames, self.thresholds.frames = learn_frames, measure_frames
        loc.frames_full, loc.frames_coarse, loc.frames_roi, loc.roi_retries = counters
        self._last_frame_t_ns = None  # the blank frame's time is not the stream's
        width_px = self.traits.width()
        if width_px is not None:
            self.splitter.model.tables(width_px)

    def reset_tracking(self) -> None:
        """Forget the region of interest and the motion: the next frame is searched whole, as the first one.
        What does not change between frames (fixed end, width, polarity, Lc0) is kept; the time order starts
        again too (after a gap in the frames, `_forget`, it goes on from the recent tips)."""
        self._forget(roi=True)
        self._time_order.clear()

    def _set_thresholds(self, low: float, high: float) -> None:
        """Use the Canny thresholds `low`/`high` from now on (the kernels' argument lists made again)."""
        self.edges.set_thresholds(low, high)
        self.tracer.forget_args()
        self.locator.set_canny_low(low)
        self._steady.unbind()

    def _relearn(self) -> None:
        """Learn the rope's traits (fixed end, width, polarity, Lc0) again, with the static mask now known: the
        first frames failed (a clamp, rod or plate edge joined to the rope's contour), so what they taught is
        suspect."""
        self.traits.restart()
        self.tracker.restart()
        self.reset_tracking()

    def _forget(self, roi: bool) -> None:
        """Drop the state that predicts this frame from the last one after a frame without shapes (a gap): the
        tips, steps and sweeps (and with `roi`, the region of interest), so the next frame starts afresh instead
        of extrapolating stale motion. What does not change between frames (fixed end, width, polarity, Lc0)
        is kept, and so is the time-order history, which `TimeOrder.order` drops itself when it is over four frame
        periods old."""
        self._motion.clear()
        self.splitter.sweep_px = 0.0
        if roi:
            self.locator.forget()

    # ----------------------------------------------------------------------------------------------------------
    def _measure(self, image: NDArray[np.uint8], result: FrameResult, exposure_ns: int) -> None:
        if self.locator.prev_count > 0 and self.traits.settled is not None and self.one_call:
            args = self._steady.args()
            if args is not None:
                self._measure_steady(image, result, exposure_ns, args)
                return
        n, used_roi = self.locator.locate(image, result.t_ns, exposure_ns)
        self._measure_contour(image, result, exposure_ns, n, used_roi)

    def _measure_steady(self, image: NDArray[np.uint8], result: FrameResult, exposure_ns: int, args: list) -> None:
        """Measure a steady frame in one kernel call (`SteadyFrame`), then go on from where the call stopped as
        `RopeLocator.locate` and `_measure_contour` go on after those calls: the same state and result as the
        calls one by one."""
        stop, n, gap_ns, motion_px, status, tracked = self._steady.run(
            args, image, result.t_ns, result.t_end_ns, exposure_ns, self.max_age_ns()
        )
        if stop == K.STEADY_AFTER_CONTOUR:
            n, used_roi = self.locator.locate_in_band(image, motion_px, gap_ns, n)
            self._measure_contour(image, result, exposure_ns, n, used_roi)
            return
        # The contour lies whole in the band and off the image border: `locate_in_band` and `_measure_contour`
        # up to the split.
        self.locator.found_in_band(gap_ns)
        result.full_frame = False
        self._keep_contour(result, n)
        width_px, fixed_rc, _, polarity = self.traits.settled  # type: ignore[misc]  # `SteadyFrame.args` checked it
        outcome = self.splitter.adopt_frame(status, n, fixed_rc)
        if outcome is False:  # a buffer too small for the one-call split: the split step by step
            e = self.edges
            outcome = self.splitter.split(
                self.tracer.points, self.tracer.chain, n, fixed_rc, width_px, e.gx, e.gy, e.edges, e.mag,
                e.smooth, polarity, edge_stage=e, frame=image,
            )  # fmt: skip
        self._finish(result, outcome, exposure_ns, tracked)

    def _measure_contour(
        self, image: NDArray[np.uint8], result: FrameResult, exposure_ns: int, n: int, used_roi: bool
    ) -> None:
        """Measure the frame from its contour (`n` points in the tracer, found in the band predicted from the last
        frame when `used_roi`)."""
        result.full_frame = not used_roi
        if n == 0:
            self.locator.forget()
            result.status = FrameStatus.NO_ROPE
            result.message = "no edge component large enough to be the rope"
            return
        self._keep_contour(result, n)
        points = self.tracer.points
        traits = self.traits
        settled = traits.settled
        if settled is not None:
            width_px, fixed_rc, exclude, polarity = settled
            measure = False
        else:
            width_px = traits.width()
            if traits.find_fixed_end(points, n, width_px):
                self._time_order.clear()  # its history was measured relative to the wrong end
            measure = traits.measuring_width
            exclude = 3.0 * (width_px or 4.0) + 10.0
            fixed_rc = (float(self.fixed[0]), float(self.fixed[1]))
            polarity = traits.polarity()
        tracer = self.tracer
        clipped = tracer.on_border != 0 and tracer.border_contacts(fixed_rc, exclude) > 0  # the trace counts them
        e = self.edges
        outcome = self.splitter.split(
            points, tracer.chain, n, fixed_rc, None if measure else width_px, e.gx, e.gy, e.edges, e.mag, e.smooth,
            polarity, edge_stage=e, frame=image,
        )  # fmt: skip
        if settled is None:
            traits.learn(measure, self.splitter.width_measured, self.splitter.polarity_used)
        if clipped:
            # The free end is out of view: no tip, no split; give the visible centreline for what it is worth.
            outcome = self.splitter.static(fixed_rc)
            result.status = FrameStatus.ROPE_CLIPPED
            result.message = "the rope touches the image border: it is leaving the field of view"
            if outcome is not None:
                result.method = outcome.method
                result.begin = result.end = outcome.shape_a
                result.rope_width_px = outcome.width_px
                result.order_confidence = 1.0
            return
        self._finish(result, outcome, exposure_ns)

    def _keep_contour(self, result: FrameResult, n: int) -> None:
        """The frame's contour (`n` points) is the one the next frame's band is built around."""
        self.locator.keep(n, result.t_ns)
        result.fixed_end = self.fixed

    def _finish(
        self,
        result: FrameResult,
        outcome: SplitOutcome | None,
        exposure_ns: int,
        tracked: tuple[int, float, float, float] | None = None,
    ) -> None:
        """Fill `result` from the split's `outcome`: the shapes in time order and the material points (with
        `tracked`, the results of a `track_frame` call made on them already), or why there are none."""
        if outcome is None:
            result.status = FrameStatus.LOST_TRACK
            result.message = self.splitter.failure
            return
        n = self.locator.prev_count
        revisits = K.count_revisits(self.tracer.chain_ro, np.int32(n), self.edges.edges)
        if revisits > BROKEN_OUTLINE * n:
            # A faint far side on a textured plate broke the band's edge: the contour went out along each piece
            # and back (a tree walk), and any two "sides" read from it are guesses.
            result.status = FrameStatus.LOST_TRACK
            result.message = (
                f"the band's edge is broken: the contour walks {100.0 * revisits / n:.0f} % of its pixels twice "
                f"(more than {100.0 * BROKEN_OUTLINE:.0f} %), it is not the band's outline"
            )
            return
        result.method = outcome.method
        result.rope_width_px = outcome.width_px
        result.segmentation_points = outcome.segmentation_points
        tracker = self.tracker
        result.material_arc_m = tracker.arc_m
        a, b = outcome.shape_a, outcome.shape_b
        if tracked is not None:
            swap, confidence, stretch_begin, stretch_end = tracked
        elif tracker.length0_settled_px >= 0.0:
            # Time order, material points and the motion model's update in one kernel call (`track_frame`: as
            # `TimeOrder.order`, `PointTracker.track_shapes` and `MotionModel.observe` in turn); a negative `swap`
            # (an empty shape, a shape longer than the tracker's scratch) has written nothing.
            order, motion = self._time_order, self._motion
            try:
                swap, confidence, stretch_begin, stretch_end = K.track_frame(
                    a, b, a is b, result.t_ns, result.t_end_ns, self.max_age_ns(), order.state, order.hist_rc,
                    self.fixed, float(self.splitter.sweep_px), exposure_ns, motion.state, motion.log,
                    tracker.fraction_ro, tracker.length0_settled_px, tracker.out, tracker.lengths_px, tracker.work,
                )  # fmt: skip
            except TypeError:  # not the splitter's writable float32 buffers
                swap = -1
        else:
            swap = -1
        if swap >= 0:
            result.begin, result.end = (b, a) if swap else (a, b)
            result.order_confidence = confidence
            result.material_begin, result.material_end = tracker.out_slots
            result.stretch_begin, result.stretch_end = stretch_begin, stretch_end
        else:
            # The first frames (Lc0 still being measured) or shapes `track_frame` does not take: step by step.
            begin, end, confidence = self._time_order.order(a, b, result.t_ns, result.t_end_ns, self._period_ns)
            result.begin, result.end, result.order_confidence = begin, end, confidence
            (result.material_begin, result.stretch_begin, result.material_end, result.stretch_end) = (
                tracker.track_shapes(begin, end)
            )
            t_mid_ns = result.t_ns + exposure_ns // 2
            self._motion.observe(begin, end, self.fixed, t_mid_ns, float(self.splitter.sweep_px), exposure_ns)
        if tracker.plane is not None:  # by arc length on the plane (metres), not in pixels
            tracker.place_on_plane(result.begin, result.end)
        result.status = FrameStatus.OK
        self._check(result, outcome, exposure_ns)

    def _check(self, result: FrameResult, outcome: SplitOutcome, exposure_ns: int) -> None:
        """Run the self-checks on a measured frame (`SelfChecks.check`): a failed one sets the status, the reason
        and the message; a split without blur is replaced by the static centreline."""
        begin, end = result.begin, result.end
        if begin is None or end is None or len(begin) == 0 or len(end) == 0:
            return
        traits = self.traits
        learned_px = traits.settled[0] if traits.settled is not None else traits.width()
        used_px = outcome.width_px
        if outcome.method is Method.BLUR_SPLIT:
            # The split reports the rope's width (`EdgeTables.width_px`), the traits the edges' spacing: compare
            # the spacings (a thin rope's edges lie up to 3x its width apart, and its width read from them swings
            # by 2x for a 0.1 px change of spacing).
            used_px = self.splitter.width
        checks = self.checks
        split = outcome.shape_a is not outcome.shape_b
        # The contour's area only where it is the evidence: a split of unknown exposure or without a prediction.
        area = 0.0
        if split and checks.needs_area(exposure_ns):
            area = contour_area_px2(self.tracer.points, self.locator.prev_count)
        status, reason = checks.check(
            begin, end, self.fixed, result.stretch_begin, result.stretch_end, used_px, learned_px,
            result.order_confidence, exposure_ns, split, area,
        )  # fmt: skip
        result.quality = checks.quality
        if status is FrameStatus.OK:
            return
        result.status, result.reason, result.message = status, reason.text, checks.message(reason)
        if reason is Reason.NO_BLUR or (split and not exposure_ns):
            # Without a known exposure only a split that passes every check shows blur: never report another.
            static = self.splitter.static((float(self.fixed[0]), float(self.fixed[1])))
            if static is None:
                result.begin = result.end = result.material_begin = result.material_end = None
                return
            result.method, result.segmentation_points = static.method, None
            result.begin = result.end = static.shape_a
            (result.material_begin, result.stretch_begin, result.material_end, result.stretch_end) = (
                self.tracker.track_shapes(static.shape_a, static.shape_a)
            )

    def max_age_ns(self) -> int:
        """The age (ns) past which the time order's history is dropped: four frame periods."""
        return 4 * (self._period_ns or DEFAULT_PERIOD_NS)
