"""Pipeline: one frame in, the rope at the start and the end of the exposure out (with material points).

It owns every buffer (allocated once per image size) and keeps the little state that links frames: the region of
interest around the last rope, the fixed end, the rope width, Lc0 and the previous shapes used to put the two
shapes of a frame in time order.
"""

from __future__ import annotations

import cmath
import math
import time

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import i32, resident_zeros, ro
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.contour import ContourTracer
from ropecam.device.pipeline.edges import EdgeDetector
from ropecam.device.pipeline.result import FrameResult, FrameStatus
from ropecam.device.pipeline.split import BlurSplitter
from ropecam.device.pipeline.tracking import PointTracker

__all__ = ["Pipeline"]

_FIXED_END_FRAMES = 10
_WIDTH_FRAMES = 15
"""Frames whose measured rope width (median) is used afterwards, when the config gives none."""
_POLARITY_FRAMES = 5
_ROI_RETRIES = 2
"""Times a band is widened around a contour that runs out of it before the next way of searching is tried."""
_COARSE_BLOCK = 4
"""Cell size (px) of the coarse search for the rope when there is no ROI."""
_COARSE_MIN_CELLS = 8
"""Smallest group of active cells the coarse search keeps (a hot pixel makes a cross of 5; a rope of the
smallest accepted contour, 40 px, about 20)."""
_COARSE_DILATE = 2
"""Cells added around the kept cells."""
"""Frames whose polarity votes decide the polarity afterwards, when the config says auto."""


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
        self.edges = EdgeDetector(height, width, config.smooth_sigma_px, config.canny_low, config.canny_high)
        self.tracer = ContourTracer(height, width, cap, config.min_contour_px)
        self.splitter = BlurSplitter(
            cap, config.method, config.static_ratio, config.corner_scale_px,
            config.paper_endpoint_radius_px, config.output_step_px, config.tip_cap, config.smooth_sigma_px,
            config.lens_blur_px, output_smoothing_px=config.output_smoothing_px,
        )  # fmt: skip
        self.tracker = PointTracker(
            config.material_points_m, config.rope_length_m, config.length0_px, config.length0_frames
        )
        self.splitter.paper.radius_scaled = config.paper_endpoint_radius_scaled
        self.lo = np.zeros(height, np.int32)
        self.hi = np.zeros(height, np.int32)
        self.grow_lo = np.zeros(height, np.int32)
        self.grow_hi = np.zeros(height, np.int32)
        # Read-only views made once (a view per kernel call costs microseconds of Python), int32 constants.
        self._lo_ro, self._hi_ro, self._grow_lo_ro, self._grow_hi_ro = (
            ro(a) for a in (self.lo, self.hi, self.grow_lo, self.grow_hi)
        )
        self._height32, self._width32 = np.int32(height), np.int32(width)
        self._margin32 = i32(config.roi_margin_px)
        self.prev_points = np.zeros((cap, 2), np.float32)
        self._prev_points_ro = ro(self.prev_points)
        self.prev_count = 0
        self.turn_cap = np.zeros(cap, np.float32)
        self.begin_buf = np.zeros((cap, 2), np.float32)
        self.end_buf = np.zeros((cap, 2), np.float32)
        self.fixed = np.zeros(2, np.float32)
        self._fixed_known = config.fixed_end_uv is not None
        self._fixed_frames = 0
        self._first_ends: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None
        if config.fixed_end_uv is not None:
            self.fixed[:] = (config.fixed_end_uv[1], config.fixed_end_uv[0])
        self._widths: list[float] = []
        self._polarity = {"auto": 0.0, "bright": 1.0, "dark": -1.0}[config.polarity]
        self._polarity_votes: list[float] = []
        self._width_cache: float | None = None
        self._tip_history: list[tuple[int, tuple[float, float]]] = []
        self._order_rejects = 0
        self._history_ordered = False
        self._period_ns: int | None = None  # the shortest time between frame starts seen: the frame period
        self._last_frame_t_ns: int | None = None
        self._motion = _MotionState()
        self._roi_t_ns: int | None = None
        self.frames_full = 0
        self.frames_coarse = 0
        self.frames_roi = 0
        self.roi_retries = 0
        cells = (max(1, height // _COARSE_BLOCK), max(1, width // _COARSE_BLOCK))
        self.coarse_sums = resident_zeros(cells, np.int32)
        self.coarse_labels = resident_zeros(cells, np.int32)
        self.coarse_stack = resident_zeros(max(cells[0] * cells[1], width), np.int32)
        # A cell is active when its mean differs from a neighbour's by canny_low / 8 grey levels: the step over
        # which the Sobel magnitude of a sharp edge reaches the low threshold.
        self._coarse_step = i32(max(1, round(_COARSE_BLOCK * _COARSE_BLOCK * config.canny_low / 8.0)))

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
        if self._last_frame_t_ns is not None and t_ns > self._last_frame_t_ns:
            gap_ns = int(t_ns - self._last_frame_t_ns)
            self._period_ns = gap_ns if self._period_ns is None else min(self._period_ns, gap_ns)
        self._last_frame_t_ns = int(t_ns)
        exposure_ns, exposure_problem = _exposure_ns(exposure_us)
        result = FrameResult(
            frame=int(index), t_ns=int(t_ns), t_end_ns=int(t_ns) + exposure_ns, status=FrameStatus.BAD_FRAME
        )
        problem = self._check_frame(frame) or exposure_problem
        if problem:
            result.message = problem
            self._forget(roi=True)
        else:
            assert isinstance(frame, np.ndarray)
            image = frame if frame.flags.c_contiguous else np.ascontiguousarray(frame)
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
        self._tip_history.clear()
        self._history_ordered = False

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
        n, used_roi = self._locate(image, result.t_ns, exposure_ns)
        result.full_frame = not used_roi
        if n == 0:
            self.prev_count = 0
            result.status = FrameStatus.NO_ROPE
            result.message = "no edge component large enough to be the rope"
            return
        points = self.tracer.points
        self.prev_points[:n] = points[:n]
        self.prev_count = n
        self._roi_t_ns = result.t_ns
        width_px = self._width()
        fixed = self._fixed_end(points, n, width_px)
        measure = self.config.rope_width_px is None and len(self._widths) < _WIDTH_FRAMES
        result.fixed_end = self.fixed
        exclude = 3.0 * (width_px or 4.0) + 10.0
        fixed_rc = (float(fixed[0]), float(fixed[1]))
        clipped = self.tracer.border_contacts(fixed_rc, exclude) > 0
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
            self._polarity_now(),
        )
        if measure and math.isfinite(self.splitter.width_measured) and self.splitter.width_measured > 0:
            self._widths.append(self.splitter.width_measured)
            self._width_cache = None
        if self._polarity == 0.0 and len(self._polarity_votes) < _POLARITY_FRAMES:
            self._polarity_votes.append(float(self.splitter.polarity_used))
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
        if outcome is None:
            result.status = FrameStatus.LOST_TRACK
            result.message = self.splitter.failure
            return
        result.method = outcome.method
        result.rope_width_px = outcome.width_px
        result.segmentation_points = outcome.segmentation_points
        begin, end, confidence = self._order(outcome, result.t_ns, result.t_end_ns)
        result.begin, result.end, result.order_confidence = begin, end, confidence
        begin_ro = ro(begin)
        end_ro = begin_ro if end is begin else ro(end)
        length_begin = self.tracker.length(begin_ro)
        length_end = length_begin if end is begin else self.tracker.length(end_ro)
        self.tracker.observe(length_begin)
        if end is not begin:
            self.tracker.observe(length_end)
        result.material_arc_m = self.tracker.arc_m
        result.material_begin, result.stretch_begin = self.tracker.track(begin_ro, 0, length_begin)
        result.material_end, result.stretch_end = self.tracker.track(end_ro, 1, length_end)
        result.status = FrameStatus.OK
        (begin_r, begin_c), (end_r, end_c) = begin[-1].tolist(), end[-1].tolist()
        sweep_px = max(self.splitter.sweep_px, math.hypot(end_r - begin_r, end_c - begin_c))
        tip_mid = (0.5 * (begin_r + end_r), 0.5 * (begin_c + end_c))
        self._motion.observe(result.t_ns + exposure_ns // 2, tip_mid, self.fixed, sweep_px, exposure_ns)

    def _locate(self, image: NDArray[np.uint8], t_ns: int, exposure_ns: int) -> tuple[int, bool]:
        """Find the rope's contour: in the band predicted from the last contour, else around the cells where a
        coarse look (block sums) sees intensity steps, else in the whole frame; a band the contour runs out of
        is widened around what was found (up to `_ROI_RETRIES` times) before the next way is tried.

        Returns (contour points, found in the band predicted from the last frame).
        """
        margin = self.config.roi_margin_px
        # Python ints and floats for the band kernel's int64/float64 scalars (a NumPy scalar costs 1.5-2 us here).
        fr, fc = self.fixed.tolist() if self._fixed_known else (0.0, 0.0)
        height, width = self.shape
        if self.prev_count > 0:
            rot_a, rot_b, motion = self._motion.predict(t_ns, exposure_ns) if self._fixed_known else (1.0, 0.0, 0.0)
            K.spans_around_points(
                self._prev_points_ro, self.prev_count, margin, motion, rot_a, rot_b, fr, fc, height, width, self.lo,
                self.hi,
            )  # fmt: skip
            n = self._search(image, margin + max(8, math.ceil(2.0 * motion)), fr, fc)
            if n > 0:
                self.frames_roi += 1
                return n, True
        kept = K.coarse_spans(
            ro(image), i32(_COARSE_BLOCK), self._coarse_step, i32(_COARSE_MIN_CELLS), i32(_COARSE_DILATE),
            self.coarse_sums, self.coarse_labels, self.coarse_stack, self.lo, self.hi,
        )  # fmt: skip
        if kept > 0:
            n = self._search(image, margin + 8, fr, fc)
            if n > 0:
                self.frames_coarse += 1
                return n, False
        self.frames_full += 1
        self.edges.detect(image, self.edges.full_lo_ro, self.edges.full_hi_ro)
        return self._trace(self.edges.full_lo_ro, self.edges.full_hi_ro), False

    def _search(self, image: NDArray[np.uint8], grow: int, fr: float, fc: float) -> int:
        """Detect and trace inside the spans `lo`/`hi`, widening them by `grow` px around a contour that reaches
        their border; returns the contour's points, 0 when it is not found whole inside them."""
        for attempt in range(_ROI_RETRIES + 1):
            self.edges.detect(image, self._lo_ro, self._hi_ro)
            n = self._trace(self._lo_ro, self._hi_ro)
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
                K.spans_around_points(
                    self.tracer.points_ro, n, grow, 0.0, 1.0, 0.0, fr, fc, self.shape[0], self.shape[1], self.grow_lo,
                    self.grow_hi,
                )  # fmt: skip
                K.union_spans(self._grow_lo_ro, self._grow_hi_ro, self.lo, self.hi)
        self.roi_retries += attempt
        return 0

    def _trace(self, lo: NDArray[np.int32], hi: NDArray[np.int32]) -> int:
        e = self.edges
        return self.tracer.trace(e.edges, lo, hi, e.mag_ro, e.gx_ro, e.gy_ro, e.stack_ro, e.count)

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
                    self._tip_history.clear()
                    self._history_ordered = False
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
        """Put the two shapes in time order by continuity with the previous frames; returns (begin, end, conf).

        The tips of the last three frames (two time samples each: start and end of the exposure) give a
        least-squares constant-acceleration fit of the tip's path (constant velocity from one frame); it predicts
        the tip at this frame's start and end, and the pairing of the two shapes with those predictions that fits
        better wins. A swinging rope reverses every half period: across the gap between frames (several exposures long
        at low frame rates) a constant velocity overshoots there, a constant acceleration does not.
        """
        a, b = outcome.shape_a, outcome.shape_b
        if t_end_ns is None or t_end_ns <= t_ns:
            # Exposure unknown: the two shapes carry the same time, nothing can say which came first, and their
            # tips would put two different positions at one time into the history.
            return a, b, (1.0 if a is b else 0.5)
        history = self._tip_history
        if history and t_ns - history[-1][0] > 4 * (self._period_ns or 25_000_000):
            history.clear()  # too old to extrapolate (frames lost): start again
            self._history_ordered = False
        if a is b or not history:
            self._history_ordered = a is b
            self._remember_tips(a, b, t_ns, t_end_ns)
            return a, b, (1.0 if a is b else 0.5)
        if not self._history_ordered:
            return self._order_by_nearness(a, b, t_ns, t_end_ns)
        (pbr, pbc), (per, pec) = self._predict_tips(t_ns, t_end_ns)
        ar, ac = a[-1].tolist()
        br, bc = b[-1].tolist()
        # Squared distances: their difference is 2 (b - a) . (pred_end - pred_begin), so the predicted direction
        # of motion decides, not where the prediction lies (a path bias moves both predictions alike).
        straight = (ar - pbr) ** 2 + (ac - pbc) ** 2 + (br - per) ** 2 + (bc - pec) ** 2
        swapped = (br - pbr) ** 2 + (bc - pbc) ** 2 + (ar - per) ** 2 + (ac - pec) ** 2
        confidence = 0.5 + 0.5 * abs(straight - swapped) / (straight + swapped + 1e-6)
        begin, end = (a, b) if straight <= swapped else (b, a)
        # A frame whose tips lie far from the predicted path (a bad split, something crossing the rope) must not
        # steer the next predictions: it is left out, unless the next frame disagrees too (the motion changed).
        # Judged on what does not depend on the order: where the band's middle is and how far the tip swept.
        pred_sweep = math.hypot(per - pbr, pec - pbc)
        mid_miss = 0.5 * math.hypot(ar + br - pbr - per, ac + bc - pbc - pec)
        sweep_miss = abs(math.hypot(br - ar, bc - ac) - pred_sweep)
        last_r, last_c = history[-1][1]
        reach = math.hypot(0.5 * (pbr + per) - last_r, 0.5 * (pbc + pec) - last_c)  # how far it extrapolates
        tolerance = max(3.0, 0.5 * pred_sweep, 0.25 * reach)
        odd = mid_miss > tolerance or sweep_miss > tolerance
        if odd and self._order_rejects < 1:
            self._order_rejects += 1
            return begin, end, 0.5 + 0.5 * (confidence - 0.5) * 0.5
        if odd:
            history.clear()
            self._history_ordered = False
        self._order_rejects = 0
        self._remember_tips(begin, end, t_ns, t_end_ns)
        return begin, end, confidence

    def _order_by_nearness(
        self, a: NDArray[np.float32], b: NDArray[np.float32], t_ns: int, t_end_ns: int
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], float]:
        """Order this frame's shapes when the history's own order is a guess (one split frame, no earlier one).

        Between two exposures the tip moves on from where the last one ended: of the last frame's two tips and
        this frame's two, the nearest pair is (last end, this begin) for any motion that does not reverse in the
        gap. That orders both frames; the remembered one is corrected, so the prediction starts from a consistent
        history.
        """
        history = self._tip_history
        ar, ac = a[-1].tolist()
        br, bc = b[-1].tolist()
        last = history[-2:] if len(history) >= 2 and history[-2][0] < history[-1][0] else history[-1:]
        best = (math.inf, 0, 0)
        for j, (_, (r, c)) in enumerate(last):
            for mine, (qr, qc) in enumerate(((ar, ac), (br, bc))):
                best = min(best, (math.hypot(qr - r, qc - c), j, mine))
        _, j, mine = best
        if len(last) == 2 and j == 0:
            # The remembered begin is nearer: it was the end; swap the two samples' positions.
            (t_first, p_first), (t_second, p_second) = history[-2], history[-1]
            history[-2], history[-1] = (t_first, p_second), (t_second, p_first)
        begin, end = (a, b) if mine == 0 else (b, a)
        distances = sorted(math.hypot(qr - r, qc - c) for _, (r, c) in last for qr, qc in ((ar, ac), (br, bc)))
        confidence = 0.5 + 0.5 * (distances[1] - distances[0]) / (distances[1] + distances[0] + 1e-6)
        self._history_ordered = True
        self._remember_tips(begin, end, t_ns, t_end_ns)
        return begin, end, confidence

    def _remember_tips(self, begin: NDArray[np.float32], end: NDArray[np.float32], t_ns: int, t_end_ns: int) -> None:
        """Keep the last six tip samples (time, (row, col)) oldest first: two per split frame, one per single
        shape."""
        history = self._tip_history
        if begin is end:
            # One shape (no blur to split): the band's centre, a sample at mid-exposure.
            history.append(((t_ns + t_end_ns) // 2, tuple(begin[-1].tolist())))
        else:
            history.append((t_ns, tuple(begin[-1].tolist())))
            history.append((t_end_ns, tuple(end[-1].tolist())))
        del history[:-6]

    def _predict_tips(self, t_ns: int, t_end_ns: int) -> tuple[tuple[float, float], tuple[float, float]]:
        """Predict the tip (row, col) at `t_ns` and `t_end_ns` from the remembered tips: a least-squares quadratic
        in time through four to six samples, a line through two or three, no motion from one. Plain floats and
        the normal equations by hand: NumPy's per-call overhead would cost more than the arithmetic."""
        history = self._tip_history
        t0 = history[-1][0]
        span = max(1, t0 - history[0][0])
        size = 3 if len(history) >= 4 else min(len(history), 2)
        m0 = m1 = m2 = m3 = m4 = 0.0  # sums of x^k
        r0 = r1 = r2 = c0 = c1 = c2 = 0.0  # sums of x^k * tip (row, col)
        for t, (row, col) in history:
            x = (t - t0) / span
            x2 = x * x
            m0 += 1.0
            m1 += x
            m2 += x2
            m3 += x2 * x
            m4 += x2 * x2
            r0 += row
            r1 += x * row
            r2 += x2 * row
            c0 += col
            c1 += x * col
            c2 += x2 * col
        if size == 3:
            a0, a1, a2 = _solve3(m0, m1, m2, m3, m4, r0, r1, r2)
            b0, b1, b2 = _solve3(m0, m1, m2, m3, m4, c0, c1, c2)
        elif size == 2:
            a0, a1, a2 = _solve2(m0, m1, m2, r0, r1)
            b0, b1, b2 = _solve2(m0, m1, m2, c0, c1)
        else:
            a0, a1, a2 = r0 / m0, 0.0, 0.0
            b0, b1, b2 = c0 / m0, 0.0, 0.0
        q = (t_ns - t0) / span
        e = (t_end_ns - t0) / span
        return (a0 + a1 * q + a2 * q * q, b0 + b1 * q + b2 * q * q), (
            a0 + a1 * e + a2 * e * e,
            b0 + b1 * e + b2 * e * e,
        )


def _solve2(m0: float, m1: float, m2: float, y0: float, y1: float) -> tuple[float, float, float]:
    """Solve a line's normal equations [[m0, m1], [m1, m2]] c = (y0, y1); a singular system (all samples at one
    time) gives the mean and no slope."""
    det = m0 * m2 - m1 * m1
    if abs(det) < 1e-12:
        return y0 / m0, 0.0, 0.0
    return (y0 * m2 - y1 * m1) / det, (m0 * y1 - m1 * y0) / det, 0.0


def _solve3(
    m0: float, m1: float, m2: float, m3: float, m4: float, y0: float, y1: float, y2: float
) -> tuple[float, float, float]:
    """Solve a quadratic's normal equations [[m0, m1, m2], [m1, m2, m3], [m2, m3, m4]] c = y by Cramer's rule
    (the times are scaled to [-1, 0]: well conditioned); a singular system falls back to the line."""
    a = m2 * m4 - m3 * m3
    b = m1 * m4 - m2 * m3
    c = m1 * m3 - m2 * m2
    det = m0 * a - m1 * b + m2 * c
    if abs(det) < 1e-12:
        return _solve2(m0, m1, m2, y0, y1)
    k0 = (y0 * a - y1 * b + y2 * c) / det
    k1 = (m0 * (y1 * m4 - m3 * y2) - y0 * b + m2 * (m1 * y2 - y1 * m2)) / det
    k2 = (m0 * (m2 * y2 - y1 * m3) - m1 * (m1 * y2 - y1 * m2) + y0 * c) / det
    return k0, k1, k2


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


class _MotionState:
    """The free end's recent positions, which predict where the rope is in the next frame (the ROI).

    Holds the midpoint of the two tips (independent of the time order) at mid-exposure of up to three
    consecutive measured frames, as log-polar coordinates about the fixed end (log radius, unwrapped angle), the
    last tip sweep and exposure. Cleared after a frame without shapes.
    """

    __slots__ = ("exposure_ns", "logs", "sweep_px", "times_ns")

    def __init__(self) -> None:
        self.times_ns: list[int] = []
        self.logs: list[complex] = []
        self.sweep_px = 0.0
        self.exposure_ns = 0

    def clear(self) -> None:
        """Forget everything (a gap in the measurements)."""
        self.times_ns.clear()
        self.logs.clear()
        self.sweep_px = 0.0
        self.exposure_ns = 0

    def observe(
        self, t_mid_ns: int, tip_mid: tuple[float, float], fixed: NDArray[np.float32], sweep_px: float, exposure_ns: int
    ) -> None:
        """Add a measured frame: mid-exposure time, midpoint of the two tips and fixed end (row, col), tip sweep
        (px) and exposure (ns, 0 = unknown)."""
        fixed_r, fixed_c = fixed.tolist()
        z = complex(tip_mid[0] - fixed_r, tip_mid[1] - fixed_c)
        if abs(z) < 1.0 or (self.times_ns and t_mid_ns <= self.times_ns[-1]):
            self.clear()  # tip on the fixed end, or time went backwards or stood still: a new sequence
            if abs(z) < 1.0:
                return
        log = cmath.log(z)
        if self.logs:  # unwrap the angle
            turns = round((log.imag - self.logs[-1].imag) / (2.0 * math.pi))
            log -= 2j * math.pi * turns
        self.times_ns.append(int(t_mid_ns))
        self.logs.append(log)
        if len(self.times_ns) > 3:
            del self.times_ns[0], self.logs[0]
        self.sweep_px = float(sweep_px) if math.isfinite(sweep_px) else 0.0
        self.exposure_ns = int(exposure_ns)

    def predict(self, t_ns: int, exposure_ns: int) -> tuple[float, float, float]:
        """Return the predicted motion of the rope from the last measured frame to the frame starting at `t_ns`
        as the complex factor (real, imaginary) that rotates and scales points about the fixed end, and the
        uncertainty of the free end's position (px).

        With one measured frame the direction is unknown: no motion, an uncertainty of 1.3 x the last sweep
        scaled from the exposure to the time gap, plus a pixel. With two, a constant angular and radial velocity
        (uncertainty half the predicted step); with three, a constant acceleration (uncertainty 0.3 x the step
        plus the acceleration term); both plus a quarter of the sweep and 2 px. (The tip itself is predicted to
        1-5 px on the simulated rigs; the margin is for the rest of a bending rope.)
        """
        if not self.times_ns:
            return 1.0, 0.0, 0.0
        gap_ns = float(t_ns + exposure_ns // 2 - self.times_ns[-1])
        sweep = self.sweep_px
        if len(self.times_ns) == 1 or gap_ns <= 0:
            scale = gap_ns / self.exposure_ns if self.exposure_ns > 0 and gap_ns > 0 else 1.0
            return 1.0, 0.0, 1.3 * sweep * max(1.0, scale) + 1.0
        l0, l1 = self.logs[-2], self.logs[-1]
        dt1 = float(self.times_ns[-1] - self.times_ns[-2])
        rate = (l1 - l0) / dt1
        radius = math.exp(l1.real)
        if len(self.times_ns) == 2:
            step = rate * gap_ns
            uncertainty = 0.5 * abs(cmath.exp(step) - 1.0) * radius
        else:
            dt0 = float(self.times_ns[-2] - self.times_ns[-3])
            accel = (rate - (l0 - self.logs[-3]) / dt0) / (0.5 * (dt0 + dt1))
            step = (rate + 0.5 * dt1 * accel) * gap_ns + 0.5 * accel * gap_ns * gap_ns
            uncertainty = 0.3 * abs(cmath.exp(rate * gap_ns) - 1.0) * radius + abs(accel) * gap_ns * gap_ns * radius
        factor = cmath.exp(step)
        if not (abs(step.real) < 1.0 and math.isfinite(factor.real) and math.isfinite(factor.imag)):
            return 1.0, 0.0, 1.3 * sweep * 2.0 + 1.0  # implausible (a jump): no direction
        return factor.real, factor.imag, uncertainty + 0.25 * sweep + 2.0
