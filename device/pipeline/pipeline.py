"""Pipeline: one frame in, the rope at the start and the end of the exposure out (with material points).

It keeps the frame's sequence: locate the rope's contour (`RopeLocator`), split it into the two shapes
(`BlurSplitter`), put them in time order (`TimeOrder`) and track the material points (`PointTracker`); the rope's
width, polarity and fixed end are learned over the first frames (`RopeTraits`). Once they have settled and the
last frame was found in its band, a frame is one kernel call (`SteadyFrame`). The stages are made, wired to one
workspace (`Workspace`, every buffer allocated once per image size) and reset together by `Stages`.
"""

from __future__ import annotations

import math
import time
from operator import attrgetter

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import as_ro
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.result import FrameStatus, PipelineResult, frame_problem
from ropecam.device.pipeline.stages import Stages
from ropecam.device.pipeline.workspace import refuse_copies
from ropecam.shared.config import check_readout
from ropecam.shared.plane import PlaneCalibration
from ropecam.shared.protocol.quality import Reason

__all__ = ["Pipeline"]


# Enum members read per frame, looked up once (an Enum class's attribute costs Python 3.11 a 48-byte method-wrapper).
_OK, _BAD_FRAME = FrameStatus.OK, FrameStatus.BAD_FRAME


@refuse_copies(
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
            config = config.on_plane(plane, (width, height))
        self.config = config
        self.shape = (height, width)
        self.stages = stages = Stages.make(config, self.shape, plane)
        """The stages, wired to one workspace (`Stages`); the attributes below are theirs."""
        self.workspace, self.edges, self.tracer = stages.workspace, stages.edges, stages.tracer
        self.static_mask, self.thresholds, self.checks = stages.static_mask, stages.thresholds, stages.checks
        self.splitter, self.tracker, self.traits = stages.splitter, stages.tracker, stages.traits
        self.locator, self._motion, self._time_order = stages.locator, stages.motion, stages.time_order
        self._tone, self._finisher, self._steady = stages.tone, stages.finisher, stages.steady
        self.fixed = stages.workspace.fixed_end.fixed
        """The fixed end (row, col) float32 (`RopeTraits.fixed_end`)."""
        self.one_call = True
        """Make a steady frame in one kernel call (`steady_frame`); False: with the calls one by one (the same
        results; the tools that time or record single kernels set it)."""
        self._clock = stages.clock
        self._u8, self._rows = np.dtype(np.uint8), float(height)  # (a float height: `set_rolling`'s, no int made)
        self._unclean_frames = 0  # frames without an OK result while the static mask was being learned
        self._no_quality: dict[str, float] = {}  # a reused result's quality before the checks ran (`process`)

    # What the locator keeps and counts (tests and tools read them here).
    lo = property(attrgetter("locator.lo"), doc="The first column of each row of the last band searched.")
    hi = property(attrgetter("locator.hi"), doc="The last column of each row of the last band searched.")
    frames_roi = property(attrgetter("locator.frames_roi"), doc="Frames found in the band predicted for them.")
    frames_coarse = property(attrgetter("locator.frames_coarse"), doc="Frames found around the coarse search's cells.")
    frames_full = property(attrgetter("locator.frames_full"), doc="Frames searched whole.")
    roi_retries = property(attrgetter("locator.roi_retries"), doc="Widenings of a band the rope ran out of.")

    # ----------------------------------------------------------------------------------------------------------
    def process(
        self, frame: object, index: int, t_ns: int, exposure_us: float | None, out: PipelineResult | None = None
    ) -> PipelineResult:
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
        out
            A record to fill (every field set again) and return instead of a new one: a caller that hands each
            result on before the next frame (the daemon) reuses one, and a steady frame then makes no Python
            object that outlives the call.

        Returns
        -------
        PipelineResult
            `out`, or a new record. Arrays in it are views into the pipeline's buffers, valid until the next call.
        """
        start_s = time.perf_counter()  # a float: no new int object per frame
        t = int(t_ns)
        exposure_ns, exposure_problem = self._clock.exposure(exposure_us)
        if out is None:
            result = PipelineResult(int(index), t, t + exposure_ns, FrameStatus.BAD_FRAME)
        else:
            result = out
            # The last frame's end time let go before the new one is made (an int above 256: a new object).
            result.reset(int(index), t, t, _BAD_FRAME, self._no_quality)
            result.t_end_ns = t + exposure_ns
        result.readout_ns = self.readout_ns
        if self.readout_ns and self.tracker.plane is not None:
            # A rolling shutter's shapes are the rope at each row's instant: their material points are placed
            # by the rope's arc length at one instant, which needs the line time in exposures (`_kernels.plane`).
            self.tracker.set_rolling(self.readout_ns / (self._rows * exposure_ns) if exposure_ns > 0 else 0.0)
        # The usual frame (C-contiguous, of the size) in linear light, checked by a kernel (no int of its shape made).
        image = self._tone.take(frame) if type(frame) is np.ndarray and frame.dtype is self._u8 else None
        problem = exposure_problem if image is not None else frame_problem(frame, self.shape) or exposure_problem
        if problem:
            result.message = problem
            self._clock.tick(t)
            self.stages.forget(roi=True)
        else:
            image = self._tone.apply(np.ascontiguousarray(frame)) if image is None else image  # (not C-contiguous)
            thresholds = self.thresholds.update(image)  # measured on the first frames, then followed
            if thresholds is not None:
                self.stages.set_thresholds(*thresholds)
            if self.static_mask.learning:
                self.static_mask.learn(image)
                if not self.static_mask.learning and self._unclean_frames > 0:
                    self.stages.relearn()
            self._finisher.rejoined = False
            self._measure(image, result, exposure_ns, self.checks.due(self.traits.settled is not None))
            if result.status is not _OK and not self._finisher.measured_all_the_same(result):
                self.stages.forget(roi=result.status is FrameStatus.NO_ROPE)
                if self._finisher.rejoined:  # shapes of a joined outline the checks doubt: no time order by them
                    self._time_order.clear()
                if self.static_mask.learning:
                    self._unclean_frames += 1
            elif self.static_mask.learning and self.splitter.measure.contrast_rejected:
                # A contrast no 8-bit rope has: the lens blur was read across a clamp's edges (`MAX_CONTRAST`)
                self._unclean_frames += 1
            elif exposure_ns == 0:
                result.message = "exposure unknown (0): no time order, the ROI follows the tip steps only"
        result.pipeline_us = (time.perf_counter() - start_s) * 1e6
        return result

    def warm_up(self) -> None:
        """Prepare everything a stream's first frames would otherwise pay for, before the stream starts.

        Builds the threshold measurement's detector (`EdgeThresholds.prepare`) and the learned static mask's
        (`StaticMask.prepare`), runs a blank frame (every buffer touched, the kernels' dispatch ready; it finds no
        rope and leaves no state) and, when the config gives `rope_width_px`, builds the edge model's tables for that
        width (10-20 ms, once per process: `edge_model.shared_model`). A measured width is known only from the first
        frames; its tables are then built on the frame that first needs them.
        """
        height, width = self.shape
        self.thresholds.prepare()
        self.static_mask.prepare()
        loc = self.locator
        counters = (loc.frames_full, loc.frames_coarse, loc.frames_roi, loc.roi_retries)
        # A blank frame teaches nothing.
        learn_frames, self.static_mask.frames = self.static_mask.frames, 0
        measure_frames, self.thresholds.frames = self.thresholds.frames, 0
        self.process(np.zeros((height, width), np.uint8), 0, 0, 0.0)
        self.static_mask.frames, self.thresholds.frames = learn_frames, measure_frames
        loc.frames_full, loc.frames_coarse, loc.frames_roi, loc.roi_retries = counters
        self._clock.last_t_ns = None  # the blank frame's time is not the stream's
        width_px = self.traits.width()
        if width_px is not None:
            self.splitter.model.tables(width_px)

    def reset_tracking(self) -> None:
        """Forget the region of interest and the motion: the next frame is searched whole, as the first one.
        What does not change between frames (fixed end, width, polarity, Lc0) is kept; the time order starts
        again too (after a gap in the frames, `Stages.forget`, it goes on from the recent tips)."""
        self.stages.reset_tracking()

    # ----------------------------------------------------------------------------------------------------------
    def _measure(self, image: NDArray[np.uint8], result: PipelineResult, exposure_ns: int, predict: bool) -> None:
        """Measure the frame (the clock ticked here or by `steady_frame`); `predict`: predict the tips first."""
        if self.locator.kept and self.traits.settled is not None and self.one_call:
            args = self._steady.args()
            if args is not None:
                self._measure_steady(image, result, exposure_ns, args, predict)
                return
        self._clock.tick(result.t_ns)
        if predict:
            motion = self._motion
            K.predict_tips(result.t_ns, exposure_ns, motion.state, motion.log, self.fixed, self.checks.buffers[0])
        n, used_roi = self.locator.locate(image, result.t_ns, exposure_ns)
        if n > 0 and self.stages.mask_structure(n, exposure_ns):  # a clamp the still rope runs round: out, again
            n, used_roi = self.locator.locate(image, result.t_ns, exposure_ns)
        self._measure_contour(image, result, exposure_ns, n, used_roi)

    def _measure_steady(
        self, image: NDArray[np.uint8], result: PipelineResult, exposure_ns: int, args: int, predict: bool
    ) -> None:
        """Measure a steady frame in one kernel call (`SteadyFrame`), then go on from where the call stopped as
        `RopeLocator.locate` and `_measure_contour` go on after those calls: the same state and result as the
        calls one by one."""
        steady, loc, tracer = self._steady, self.locator, self.tracer
        stop = steady.run(args, image, result.t_ns, result.t_end_ns, exposure_ns, predict)
        motion_px, status, swap, confidence, stretch_begin, stretch_end, checked, placed = steady.results()
        tracer.adopt_steady(self.edges, image, loc.lo_ro, loc.hi_ro)
        if stop == K.STEADY_AFTER_CONTOUR:
            n = tracer.adopt(self.edges, image, loc.lo_ro, loc.hi_ro, tracer.count)
            n, used_roi = loc.locate_in_band(image, motion_px, loc.gap_ns, n)
            self._measure_contour(image, result, exposure_ns, n, used_roi)
            return
        # The contour lies whole in the band and off the image border: `locate_in_band` and `_measure_contour` up to
        # the split (`steady_frame` counted it, kept it and its gap: `found_in_band`, `_keep_contour`).
        loc.motion.owed = True
        result.full_frame = False
        result.fixed_end = self.fixed
        outcome = self.splitter.adopt_frame(status, self.traits.settled.fixed_rc)  # type: ignore[union-attr]
        if outcome is False:  # a buffer too small for the one-call split: the split step by step
            width_px, fixed_rc, _, polarity = self.traits.settled  # type: ignore[misc]  # `SteadyFrame.args` checked it
            e = self.edges
            outcome = self.splitter.split(
                tracer.points, tracer.chain, tracer.count, fixed_rc, width_px, e.gx, e.gy, e.edges, e.mag,
                e.smooth, polarity, edge_stage=e, frame=image,
            )  # fmt: skip
            self._finisher.finish(result, outcome, exposure_ns)
        elif stop == K.STEADY_DONE and exposure_ns > 0:
            self._finisher.finish_tracked(
                result, outcome, exposure_ns, swap, confidence, stretch_begin, stretch_end, checked, placed
            )
        else:  # not two shapes, no band outline, shapes `track_frame` refused or made without a known exposure
            tracked = (swap, confidence, stretch_begin, stretch_end) if stop == K.STEADY_DONE else None
            counted = (
                steady.revisits() if stop in (K.STEADY_BROKEN, K.STEADY_AFTER_SHAPES) and exposure_ns > 0 else None
            )
            self._finisher.finish(result, outcome, exposure_ns, counted, tracked)

    def _measure_contour(
        self, image: NDArray[np.uint8], result: PipelineResult, exposure_ns: int, n: int, used_roi: bool
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
        tracer, traits = self.tracer, self.traits
        points, settled = tracer.points, traits.settled
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
            if (
                outcome is not None
                and self.locator.fixed_end.configured
                and not _rope_from(outcome.shape_a, fixed_rc, exclude, self.tracker.length0_settled_px)
            ):
                # The outline runs out of the view along a structure the rope touches (a plate edge its tip lies
                # across, a rod, before the static mask is learned): its centreline is not the rope's. (A found
                # fixed end may itself be wrong on such an outline: its centreline is kept, for what it is worth.)
                result.message = "the rope's outline runs to the image border along a structure it touches"
                outcome = None
            if outcome is not None:
                result.method = outcome.method
                result.begin = result.end = outcome.shape_a
                result.rope_width_px = outcome.width_px
                result.order_confidence = 1.0
            return
        unknown_length = self.tracker.length0_settled_px < 0.0  # before `finish` feeds this frame's shapes to Lc0
        seen = self.tracker.lengths_seen
        self._finisher.finish(result, outcome, exposure_ns)
        if unknown_length and exposure_ns > 0:
            self._finisher.refuse_fold(result, seen)
        if self.locator.cut and result.status is FrameStatus.OK and self.checks.config.enabled:
            # The rope was cut from a structure its tip lies across (`RopeLocator._attached`): the tip may be cut.
            result.status, result.reason = FrameStatus.IMPLAUSIBLE, Reason.TIP_MASKED.text
            result.message = "the rope's tip lies across a structure (cut from it): the tip may be cut"

    def _keep_contour(self, result: PipelineResult, n: int) -> None:
        """The frame's contour (`n` points) is the one the next frame's band is built around."""
        self.locator.keep(n, result.t_ns)
        result.fixed_end = self.fixed


def _rope_from(shape: NDArray[np.float32], fixed_rc: tuple[float, float], near_px: float, length0_px: float) -> bool:
    """Whether the polyline `shape` ((n, 2) row, col) can be the visible part of a rope: it starts within `near_px`
    of the fixed end `fixed_rc` and, the rope's length known (`length0_px` > 0), is at most 1.1 times as long."""
    if len(shape) == 0 or math.hypot(shape[0, 0] - fixed_rc[0], shape[0, 1] - fixed_rc[1]) > near_px:
        return False
    return length0_px <= 0.0 or float(K.polyline_length(as_ro(shape), np.int32(len(shape)))) <= 1.1 * length0_px
