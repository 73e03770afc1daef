"""Pipeline: one frame in, the rope at the start and the end of the exposure out (with material points).

It owns every buffer (allocated once per image size) and keeps the little state that links frames: the region of
interest around the last rope, the fixed end, the rope width, Lc0 and the previous shapes used to put the two
shapes of a frame in time order.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import i32, ro
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.contour import ContourTracer
from ropecam.device.pipeline.edges import EdgeDetector, gaussian_weights
from ropecam.device.pipeline.motion import MotionModel
from ropecam.device.pipeline.result import FrameResult, FrameStatus
from ropecam.device.pipeline.split import BlurSplitter
from ropecam.device.pipeline.split_outcome import SplitOutcome
from ropecam.device.pipeline.time_order import DEFAULT_PERIOD_NS, TimeOrder
from ropecam.device.pipeline.tracking import PointTracker
from ropecam.device.pipeline.workspace import COARSE_BLOCK, RoiBuffers, Workspace, expose, steady_constants

__all__ = ["Pipeline"]

_FIXED_END_FRAMES = 10
_WIDTH_FRAMES = 15
"""Frames whose measured rope width (median) is used afterwards, when the config gives none."""
_POLARITY_FRAMES = 5
"""Frames whose polarity votes decide the polarity afterwards, when the config says auto."""
_ROI_RETRIES = 2
"""Times a band is widened around a contour that runs out of it before the next way of searching is tried."""
_COARSE_MIN_CELLS = 8
"""Smallest group of active cells the coarse search keeps (a hot pixel makes a cross of 5; a rope of the
smallest accepted contour, 40 px, about 20)."""
_COARSE_DILATE = 2
"""Cells added around the kept cells."""


_NO_COPY = (
    "a Pipeline cannot be copied or pickled: its steady frames read a table of the raw addresses of its buffers, "
    "which a copy would share; make a new Pipeline(config, image_size) instead"
)


@expose("workspace.roi", RoiBuffers)
class Pipeline:
    """Measure the rope in each frame.

    Parameters
    ----------
    config
        Pipeline settings.
    image_size
        (width, height) of every frame; frames of another size get status BAD_FRAME.
    """

    def __init__(self, config: PipelineConfig, image_size: tuple[int, int]) -> None:
        width, height = (int(v) for v in image_size)
        if width < 8 or height < 8:
            raise ValueError(f"image_size must be at least 8x8, got {image_size}")
        self.config = config
        self.shape = (height, width)
        cap = config.max_contour
        weights = gaussian_weights(config.smooth_sigma_px)
        fraction = np.array(config.material_points_m, np.float64) / config.rope_length_m
        self.workspace = ws = Workspace.make(height, width, cap, weights, fraction)
        """Every buffer of the per-frame path, by stage (its arrays cannot be replaced: `steady_frame`'s table
        holds their addresses)."""
        self.edges = EdgeDetector(
            height, width, config.smooth_sigma_px, config.canny_low, config.canny_high, buffers=ws.edges
        )
        self.tracer = ContourTracer(height, width, cap, config.min_contour_px, buffers=ws.contour)
        self.splitter = BlurSplitter(
            cap, config.method, config.static_ratio, config.corner_scale_px,
            config.paper_endpoint_radius_px, config.output_step_px, config.tip_cap, config.smooth_sigma_px,
            config.lens_blur_px, output_smoothing_px=config.output_smoothing_px, buffers=ws.split,
        )  # fmt: skip
        self.tracker = PointTracker(
            config.material_points_m, config.rope_length_m, config.length0_px, config.length0_frames, ws.track
        )
        self.splitter.paper.radius_scaled = config.paper_endpoint_radius_scaled
        # Read-only views made once (a view per kernel call costs microseconds of Python), int32 constants.
        self._lo_ro, self._hi_ro, self._grow_lo_ro, self._grow_hi_ro = (
            ro(a) for a in (self.lo, self.hi, self.grow_lo, self.grow_hi)
        )
        self._height32, self._width32 = np.int32(height), np.int32(width)
        # The last frame's contour, which the next frame's band is built around: the tracer's own buffer (no copy
        # per frame). Valid because nothing traces between the end of a frame and the band building at the start
        # of the next one (`_locate` builds the band first); `prev_count` = 0 marks it stale.
        self.prev_points = self.tracer.points
        self._prev_points_ro = self.tracer.points_ro
        self.prev_count = 0
        self._need_gap_ns = 0  # the time gap over which the motion model's band error (profile) was measured
        self.fixed = ws.fixed_end.fixed
        self.turn_cap = ws.fixed_end.turn
        self._fixed_known = config.fixed_end_uv is not None
        self._fixed_frames = 0
        self._first_ends: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None
        if config.fixed_end_uv is not None:
            self.fixed[:] = (config.fixed_end_uv[1], config.fixed_end_uv[0])
        self._widths: list[float] = []
        self._polarity = {"auto": 0.0, "bright": 1.0, "dark": -1.0}[config.polarity]
        self._polarity_votes: list[float] = []
        self._width_cache: float | None = None
        self._steady: tuple[float | None, tuple[float, float], float, float] | None = None
        """(width, fixed end (row, col), border exclusion radius, polarity) once none of them changes any more."""
        self._exposure_key: float | None = None  # the last float exposure_us and what `_exposure_ns` made of it
        self._exposure_value: tuple[int, str] = (0, "")
        self._u8 = np.dtype(np.uint8)
        self._strides = (width, 1)
        self._time_order = TimeOrder(ws.order)
        self._period_ns: int | None = None  # the shortest time between frame starts seen: the frame period
        self._last_frame_t_ns: int | None = None
        self._motion = MotionModel(ws.motion)
        motion = self._motion
        self._band_args = (
            config.roi_margin_px, height, width, *motion.need_args, self.fixed, motion.state, motion.log, motion.need,
            motion.profile, motion.band, self.lo, self.hi, self.moved,
        )  # fmt: skip
        """`band_stage`'s arguments after the frame's (Python ints and floats for its int64/float64 scalars)."""
        self._roi_t_ns: int | None = None
        self._steady_out = ws.steady_out
        self.one_call = True
        """Make a steady frame in one kernel call (`steady_frame`); False: with the calls one by one (the same
        results; the tools that time or record single kernels set it)."""
        self._steady_bound: tuple | None = None
        """(the split's steady key and the rope width's tables, Lc0, `steady_frame`'s argument list) of the last
        steady frame: its table holds the addresses of the workspace's buffers and of those tables."""
        self.frames_full = 0
        self.frames_coarse = 0
        self.frames_roi = 0
        self.roi_retries = 0
        # A cell is active when its mean differs from a neighbour's by canny_low / 8 grey levels: the step over
        # which the Sobel magnitude of a sharp edge reaches the low threshold.
        self._coarse_step = i32(max(1, round(COARSE_BLOCK * COARSE_BLOCK * config.canny_low / 8.0)))

    def __copy__(self) -> Pipeline:
        raise TypeError(_NO_COPY)

    def __deepcopy__(self, memo: dict[int, object]) -> Pipeline:
        raise TypeError(_NO_COPY)

    def __reduce_ex__(self, protocol: object) -> tuple[object, ...]:
        raise TypeError(_NO_COPY)

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
            exposure_ns, exposure_problem = _exposure_ns(exposure_us)
            if type(exposure_us) is float:
                self._exposure_key, self._exposure_value = exposure_us, (exposure_ns, exposure_problem)
        result = FrameResult(int(index), t, t + exposure_ns, FrameStatus.BAD_FRAME)
        if type(frame) is np.ndarray and frame.dtype is self._u8 and frame.shape == self.shape:
            problem = exposure_problem  # the usual case, without building the messages of `_check_frame`
        else:
            problem = self._check_frame(frame) or exposure_problem
        if problem:
            result.message = problem
            self._forget(roi=True)
        else:
            assert isinstance(frame, np.ndarray)
            image = frame if frame.strides == self._strides else np.ascontiguousarray(frame)
            self._measure(image, result, exposure_ns)
            if result.status is not FrameStatus.OK:
                self._forget(roi=result.status is FrameStatus.NO_ROPE)
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
        counters = (self.frames_full, self.frames_coarse, self.frames_roi, self.roi_retries)
        self.process(np.zeros((height, width), np.uint8), 0, 0, 0.0)
        self.frames_full, self.frames_coarse, self.frames_roi, self.roi_retries = counters
        self._last_frame_t_ns = None  # the blank frame's time is not the stream's
        width_px = self._width()
        if width_px is not None:
            self.splitter.model.tables(width_px)

    def reset_tracking(self) -> None:
        """Forget the region of interest and the motion: the next frame is searched whole, as the first one.
        What does not change between frames (fixed end, width, polarity, Lc0) is kept; the time order starts
        again too (after a gap in the frames, `_forget`, it goes on from the recent tips)."""
        self._forget(roi=True)
        self._time_order.clear()

    def _forget(self, roi: bool) -> None:
        """Drop the state that predicts this frame from the last one after a frame without shapes (a gap): the
        tips, steps and sweeps (and with `roi`, the region of interest), so the next frame starts afresh instead
        of extrapolating stale motion. What does not change between frames (fixed end, width, polarity, Lc0)
        is kept, and so is the time-order history, which `_order` drops itself when it is over four frame
        periods old."""
        self._motion.clear()
        self.splitter.sweep_px = 0.0
        if roi:
            self.prev_count = 0
            self._roi_t_ns = None

    def _check_frame(self, frame: object) -> str:
        if not isinstance(frame, np.ndarray):
            return f"frame is a {type(frame).__name__}, expected a numpy array"
        if frame.dtype != np.uint8:
            return f"frame dtype is {frame.dtype}, expected uint8"
        if frame.ndim != 2:
            return f"frame has shape {frame.shape}, expected 2-D {self.shape}"
        if frame.shape != self.shape:
            return f"frame shape is {frame.shape}, expected {self.shape}"
        return ""

    # ----------------------------------------------------------------------------------------------------------
    def _measure(self, image: NDArray[np.uint8], result: FrameResult, exposure_ns: int) -> None:
        if self.prev_count > 0 and self._steady is not None and self.one_call:
            args = self._steady_frame_args()
            if args is not None:
                self._measure_steady(image, result, exposure_ns, args)
                return
        n, used_roi = self._locate(image, result.t_ns, exposure_ns)
        self._measure_contour(image, result, exposure_ns, n, used_roi)

    def _steady_frame_args(self) -> list | None:
        """`steady_frame`'s argument list when this frame can be one kernel call: the split took its steady path
        on the last frame with this pipeline's buffers, and Lc0 is settled (so `track_frame` runs). Made once per
        rope width and Lc0 (its table holds the addresses of the workspace's buffers, which cannot be replaced,
        and of the width's tables); `_measure_steady` sets the per-frame slots. None otherwise."""
        call = self.splitter.steady_call()
        length0_px = self.tracker.length0_settled_px
        if call is None or length0_px < 0.0:
            return None
        key, width_tables = call
        bound = self._steady_bound
        if bound is not None and bound[0] is key and bound[1] is width_tables and bound[2] == length0_px:
            return bound[3]
        self._steady_bound = None
        e, tracer = self.edges, self.tracer
        width_px, fixed_rc, _, polarity = self._steady  # type: ignore[misc]  # `_measure` checked it
        # The split's steady path was taken with what this pipeline passes it (`_measure_contour`): the
        # workspace's buffers, which `steady_frame` passes it too.
        ours = (tracer.points, tracer.chain, e.gx, e.gy, e.mag, e.smooth, e, fixed_rc)
        if not (all(k is o for k, o in zip(key[:8], ours, strict=True)) and key[8] == width_px and key[9] == polarity):
            return None
        motion, config = self._motion, self.config
        gain, floor_px, floor_share = motion.need_args
        constants = steady_constants(
            margin_px=config.roi_margin_px, height=self.shape[0], width=self.shape[1], gain=gain, floor_px=floor_px,
            floor_share=floor_share, low=e.low, high=e.high, min_pixels=tracer.min_pixels, length0_px=length0_px,
        )  # fmt: skip
        table = self.workspace.steady_table(width_tables)
        args = [None, 0, False, False, False, 0, 0, 0, 0, 0.0, table, constants]
        self._steady_bound = (key, width_tables, length0_px, args)
        return args

    def _measure_steady(self, image: NDArray[np.uint8], result: FrameResult, exposure_ns: int, args: list) -> None:
        """Measure a steady frame in one kernel call (`steady_frame`: `band_stage`, `detect_and_trace`,
        `split_frame`, `track_frame`), then go on from where the call stopped as `_locate` and `_measure_contour`
        go on after those calls: the same state and result as the calls one by one."""
        t_ns = result.t_ns
        gap_ns = t_ns - self._roi_t_ns  # type: ignore[operator]  # set whenever prev_count > 0
        model, splitter = self._motion, self.splitter
        args[0] = image
        args[1] = self.prev_count
        args[2] = model.owed
        args[3] = 2 * gap_ns <= 3 * self._need_gap_ns
        args[4] = self._fixed_known
        args[5] = t_ns
        args[6] = exposure_ns
        args[7] = result.t_end_ns
        args[8] = 4 * (self._period_ns or DEFAULT_PERIOD_NS)
        args[9] = splitter.sweep_px  # `split_frame`'s last sweep (`SplitSteady._run_frame`)
        stop = K.steady_frame(*args)
        if stop < 0:
            raise RuntimeError(f"steady_frame refused its arguments (status {stop})")
        motion_px, points, status, swap, confidence, stretch_begin, stretch_end = self._steady_out.tolist()
        n = self.tracer.adopt(self.edges, image, self._lo_ro, self._hi_ro, int(points))
        if stop == K.STEADY_AFTER_CONTOUR:
            n, used_roi = self._locate_in_band(image, motion_px, gap_ns, n)
            self._measure_contour(image, result, exposure_ns, n, used_roi)
            return
        # The contour lies whole in the band and off the image border: `_locate_in_band` and `_measure_contour`
        # up to the split.
        self._found_in_band(gap_ns)
        result.full_frame = False
        self._keep_contour(result, n)
        width_px, fixed_rc, _, polarity = self._steady  # type: ignore[misc]  # `_steady_frame_args` checked it
        outcome = splitter.adopt_frame(int(status), n, fixed_rc)
        if outcome is False:  # a buffer too small for the steady path: the split step by step
            e = self.edges
            outcome = splitter.split(
                self.tracer.points, self.tracer.chain, n, fixed_rc, width_px, e.gx, e.gy, e.edges, e.mag, e.smooth,
                polarity, edge_stage=e, frame=image,
            )  # fmt: skip
        tracked = (int(swap), confidence, stretch_begin, stretch_end) if stop == K.STEADY_DONE else None
        self._finish(result, outcome, exposure_ns, tracked)

    def _measure_contour(
        self, image: NDArray[np.uint8], result: FrameResult, exposure_ns: int, n: int, used_roi: bool
    ) -> None:
        """Measure the frame from its contour (`n` points in the tracer, found in the band predicted from the last
        frame when `used_roi`)."""
        result.full_frame = not used_roi
        if n == 0:
            self.prev_count = 0
            result.status = FrameStatus.NO_ROPE
            result.message = "no edge component large enough to be the rope"
            return
        self._keep_contour(result, n)
        points = self.tracer.points
        steady = self._steady
        if steady is not None:
            width_px, fixed_rc, exclude, polarity = steady
            measure = False
        else:
            width_px = self._width()
            fixed = self._fixed_end(points, n, width_px)
            measure = self.config.rope_width_px is None and len(self._widths) < _WIDTH_FRAMES
            exclude = 3.0 * (width_px or 4.0) + 10.0
            fixed_rc = (float(fixed[0]), float(fixed[1]))
            polarity = self._polarity_now()
        tracer = self.tracer
        clipped = tracer.on_border != 0 and tracer.border_contacts(fixed_rc, exclude) > 0  # the trace counts them
        e = self.edges
        outcome = self.splitter.split(
            points,
            self.tracer.chain,
            n,
            fixed_rc,
            None if measure else width_px,
            e.gx,
            e.gy,
            e.edges,
            e.mag,
            e.smooth,
            polarity,
            edge_stage=e,
            frame=image,
        )
        if steady is None:
            self._learn(measure)
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
        result.method = outcome.method
        result.rope_width_px = outcome.width_px
        result.segmentation_points = outcome.segmentation_points
        tracker = self.tracker
        result.material_arc_m = tracker.arc_m
        a, b = outcome.shape_a, outcome.shape_b
        if tracked is not None:
            swap, confidence, stretch_begin, stretch_end = tracked
        elif tracker.length0_settled_px >= 0.0:
            # Time order, material points and the motion model's update in one kernel call (`track_frame`: the
            # same as `_order`, `PointTracker.track_shapes` and `MotionModel.observe` in turn); a negative `swap`
            # (an empty shape, a shape longer than the tracker's scratch) has written nothing.
            order, motion = self._time_order, self._motion
            try:
                swap, confidence, stretch_begin, stretch_end = K.track_frame(
                    a, b, a is b, result.t_ns, result.t_end_ns, 4 * (self._period_ns or DEFAULT_PERIOD_NS),
                    order.state, order.hist_rc, self.fixed, float(self.splitter.sweep_px), exposure_ns, motion.state,
                    motion.log, tracker.fraction_ro, tracker.length0_settled_px, tracker.out, tracker.lengths_px,
                    tracker.work,
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
            begin, end, confidence = self._order(outcome, result.t_ns, result.t_end_ns)
            result.begin, result.end, result.order_confidence = begin, end, confidence
            (result.material_begin, result.stretch_begin, result.material_end, result.stretch_end) = (
                tracker.track_shapes(begin, end)
            )
            t_mid_ns = result.t_ns + exposure_ns // 2
            self._motion.observe(begin, end, self.fixed, t_mid_ns, float(self.splitter.sweep_px), exposure_ns)
        result.status = FrameStatus.OK

    def _locate(self, image: NDArray[np.uint8], t_ns: int, exposure_ns: int) -> tuple[int, bool]:
        """Find the rope's contour: in the band predicted from the last contour, else around the cells where a
        coarse look (block sums) sees intensity steps, else in the whole frame; a band the contour runs out of
        is widened around what was found (up to `_ROI_RETRIES` times) before the next way is tried.

        Returns (contour points, found in the band predicted from the last frame).
        """
        if self.prev_count > 0:
            model = self._motion
            # The measured error holds for the time gap it was measured over: a longer one (a dropped frame) gets
            # the step-scaled uncertainty, which grows with the gap.
            gap_ns = t_ns - self._roi_t_ns  # type: ignore[operator]  # set whenever prev_count > 0
            # One kernel call (the arguments after the frame's made once): the last band's error measured on the
            # last contour when it was found in that band (`owed`), the prediction, the band.
            motion = K.band_stage(
                self._prev_points_ro, self.prev_count, model.owed, 2 * gap_ns <= 3 * self._need_gap_ns,
                self._fixed_known, t_ns, exposure_ns, *self._band_args,
            )  # fmt: skip
            n = self.tracer.detect_and_trace(self.edges, image, self._lo_ro, self._hi_ro)
            return self._locate_in_band(image, motion, gap_ns, n)
        return self._locate_elsewhere(image)

    def _locate_in_band(self, image: NDArray[np.uint8], motion_px: float, gap_ns: int, n: int) -> tuple[int, bool]:
        """`_locate` after the first search of the band predicted with uncertainty `motion_px` over `gap_ns` from
        the last frame, which found `n` contour points."""
        n = self._search(image, self.config.roi_margin_px + max(8, math.ceil(2.0 * motion_px)), n)
        if n > 0:
            self._found_in_band(gap_ns)
            return n, True
        self._motion.forget_need()
        return self._locate_elsewhere(image)

    def _found_in_band(self, gap_ns: int) -> None:
        """The contour was found in the band predicted over `gap_ns`: the next band measures its error on it."""
        self.frames_roi += 1
        self._motion.owed = True
        self._need_gap_ns = gap_ns

    def _keep_contour(self, result: FrameResult, n: int) -> None:
        """The frame's contour (`n` points) is the one the next frame's band is built around."""
        self.prev_count = n  # `prev_points` is the tracer's buffer: these n points
        self._roi_t_ns = result.t_ns
        result.fixed_end = self.fixed

    def _locate_elsewhere(self, image: NDArray[np.uint8]) -> tuple[int, bool]:
        """`_locate` without a band: around the coarse look's cells, else in the whole frame."""
        kept = K.coarse_spans(
            ro(image), i32(COARSE_BLOCK), self._coarse_step, i32(_COARSE_MIN_CELLS), i32(_COARSE_DILATE),
            self.coarse_sums, self.coarse_labels, self.coarse_stack, self.lo, self.hi,
        )  # fmt: skip
        if kept > 0:
            first = self.tracer.detect_and_trace(self.edges, image, self._lo_ro, self._hi_ro)
            n = self._search(image, self.config.roi_margin_px + 8, first)
            if n > 0:
                self.frames_coarse += 1
                return n, False
        self.frames_full += 1
        return self.tracer.detect_and_trace(self.edges, image, self.edges.full_lo_ro, self.edges.full_hi_ro), False

    def _search(self, image: NDArray[np.uint8], grow: int, n: int) -> int:
        """Go on with the search in the spans `lo`/`hi` whose first detection and trace found `n` contour points:
        widen them by `grow` px around a contour that reaches their border and search again; returns the
        contour's points, 0 when it is not found whole inside them."""
        for attempt in range(_ROI_RETRIES + 1):
            if attempt > 0:
                n = self.tracer.detect_and_trace(self.edges, image, self._lo_ro, self._hi_ro)
            if n == 0:
                return 0
            contacts = self.tracer.contacts  # counted by the trace on these spans
            if contacts < 0:
                contacts = self.tracer.roi_contacts(self._lo_ro, self._hi_ro)
            if contacts == 0:
                self.roi_retries += attempt
                return n
            if contacts * 4 > n:  # mostly cut off: the rope is elsewhere, widening would only creep after it
                break
            if attempt < _ROI_RETRIES:  # the rope runs out of the band: widen it around what was found
                fr, fc = self.fixed.tolist() if self._fixed_known else (0.0, 0.0)
                K.spans_around_chain(
                    self.tracer.points_ro, n, grow, 0.0, self._motion.profile_ro, 1.0, 0.0, fr, fc, self.shape[0],
                    self.shape[1], self.grow_lo, self.grow_hi, self.no_moved,
                )  # fmt: skip
                K.union_spans(self._grow_lo_ro, self._grow_hi_ro, self.lo, self.hi)
        self.roi_retries += attempt
        return 0

    def _learn(self, measure: bool) -> None:
        """Keep the first frames' width and polarity readings; once the width, the fixed end and the polarity are
        all settled (they do not change afterwards), keep them for the next frames (`_steady`)."""
        if measure and math.isfinite(self.splitter.width_measured) and self.splitter.width_measured > 0:
            self._widths.append(self.splitter.width_measured)
            self._width_cache = None
        if self._polarity == 0.0 and len(self._polarity_votes) < _POLARITY_FRAMES:
            self._polarity_votes.append(float(self.splitter.polarity_used))
        config = self.config
        fixed_settled = self._fixed_known and (
            config.fixed_end_uv is not None or self._fixed_frames >= _FIXED_END_FRAMES
        )
        width_settled = config.rope_width_px is not None or len(self._widths) >= _WIDTH_FRAMES
        polarity_settled = self._polarity != 0.0 or len(self._polarity_votes) >= _POLARITY_FRAMES
        if fixed_settled and width_settled and polarity_settled:
            width_px = self._width()
            fixed_rc = (float(self.fixed[0]), float(self.fixed[1]))
            self._steady = (width_px, fixed_rc, 3.0 * (width_px or 4.0) + 10.0, self._polarity_now())

    def _polarity_now(self) -> float:
        """The configured polarity, or the majority of the first frames' once they are in (0 = decide now)."""
        if self._polarity != 0.0 or len(self._polarity_votes) < _POLARITY_FRAMES:
            return self._polarity
        return 1.0 if sum(self._polarity_votes) >= 0 else -1.0

    def _width(self) -> float | None:
        if self.config.rope_width_px is not None:
            # The configured width is the rope's; the splitter works with the spacing its blurred edges show.
            if self._width_cache is None:
                self._width_cache = self.splitter.model.edge_spacing(self.config.rope_width_px)
            return self._width_cache
        if self._widths and self._width_cache is None:
            # Motion only widens the band: the lower quartile of the first frames' spacings is the still rope's.
            self._width_cache = float(np.percentile(self._widths, 25))
        return self._width_cache

    def _fixed_end(self, points: NDArray[np.float32], n: int, width_px: float | None) -> NDArray[np.float32]:
        """The fixed end (row, col): configured, or found over the first frames.

        The first frame gives a guess: of the band's two ends the narrower one (the fixed end hardly moves, so
        its end of the band stays one rope wide), or on a tie (a rope at rest) the one nearer the top centre of
        the image (a pendulum hangs below its support, and a rig centres the support so the swing stays in view).
        Over the next frames the end that stays where it was is the fixed end: the guess is corrected as soon as
        one end has moved away and the other has not, and the position is averaged over those frames.
        """
        if self._fixed_known and (self.config.fixed_end_uv is not None or self._fixed_frames >= _FIXED_END_FRAMES):
            return self.fixed
        w = width_px or 4.0
        K.turning_angles(ro(points), i32(n), i32(max(3, round(w))), self.turn_cap)
        e1 = int(np.argmax(self.turn_cap[:n]))
        e2 = int(np.argmax(np.hypot(points[:n, 0] - points[e1, 0], points[:n, 1] - points[e1, 1])))
        ends = [self._cap_centre(points, n, e, w) for e in (e1, e2)]
        if not self._fixed_known:
            m = max(4, round(2 * w))
            widths = [np.hypot(*(points[(e - m) % n] - points[(e + m) % n])) for e in (e1, e2)]
            if abs(widths[0] - widths[1]) <= 0.25 * min(widths):
                top_centre = np.array([0.0, 0.5 * (self.shape[1] - 1)])
                far = [float(np.hypot(*(end - top_centre))) for end in ends]
                k = 0 if far[0] <= far[1] else 1
            else:
                k = 0 if widths[0] < widths[1] else 1
            self.fixed[:] = ends[k]
            self._first_ends = (ends[k].copy(), ends[1 - k].copy())
            self._fixed_known = True
            self._fixed_frames = 1
            return self.fixed
        if self._first_ends is not None and self.config.fixed_end_uv is None:
            guess, other = self._first_ends
            moved_guess = min(float(np.hypot(*(end - guess))) for end in ends)
            moved_other = min(float(np.hypot(*(end - other))) for end in ends)
            if max(moved_guess, moved_other) > max(2.0 * w, 5.0) and min(moved_guess, moved_other) < w:
                self._first_ends = None  # decided
                if moved_guess > moved_other:
                    # The guessed end moved: it is the free end. Start again from the other one, and forget what
                    # was measured relative to the wrong end.
                    self.fixed[:] = other
                    self._fixed_frames = 0
                    self._widths.clear()
                    self._width_cache = None
                    self._time_order.clear()
        d = [float(np.hypot(*(end - self.fixed))) for end in ends]
        chosen = ends[0] if d[0] <= d[1] else ends[1]
        if min(d) > 3.0 * w + 5.0:
            return self.fixed  # not the rope seen so far (another object, a clipped view): no update
        k = self._fixed_frames
        self.fixed[:] = (self.fixed * k + chosen) / (k + 1)
        self._fixed_frames += 1
        return self.fixed

    def _cap_centre(self, points: NDArray[np.float32], n: int, e: int, w: float) -> NDArray[np.float32]:
        """The contour point in the middle of the rope end around contour index `e`: the turning-weighted centroid
        of the points within a width and a half of it, snapped to the contour (a flat end has two corners, its
        largest turning angle is at one of them)."""
        m = max(3, round(1.5 * w))
        idx = np.arange(e - m, e + m + 1) % n
        weights = self.turn_cap[idx].astype(np.float64) ** 2
        if not weights.sum() > 0:
            return points[e].copy()
        centre = (points[idx].astype(np.float64) * weights[:, None]).sum(axis=0) / weights.sum()
        k = idx[int(np.argmin(np.hypot(points[idx, 0] - centre[0], points[idx, 1] - centre[1])))]
        return points[k].copy()

    def _order(
        self, outcome, t_ns: int, t_end_ns: int | None = None
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], float]:
        """Put the two shapes in time order by continuity with the previous frames (`TimeOrder`); returns
        (begin, end, confidence)."""
        return self._time_order.order(outcome.shape_a, outcome.shape_b, t_ns, t_end_ns, self._period_ns)


def _exposure_ns(exposure_us: object) -> tuple[int, str]:
    """Return the exposure in integer ns (0 = unknown) and a problem message ('' when fine)."""
    if exposure_us is None:
        return 0, ""
    try:
        value = float(exposure_us)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return 0, f"exposure_us is {exposure_us!r}, expected a number of microseconds (0 = unknown)"
    if not math.isfinite(value) or value < 0:
        return 0, f"exposure_us is {value}, expected a finite number of microseconds >= 0 (0 = unknown)"
    return round(value * 1000.0), ""
