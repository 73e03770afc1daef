"""Stages: the stages of one `Pipeline`, made for one config and image size and wired to one workspace, and the
resets that keep them consistent with each other (a gap in the frames, new Canny thresholds, traits learned again)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ropecam.device.pipeline.background import BackgroundFlattening
from ropecam.device.pipeline.checks import SelfChecks
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.contour import ContourTracer
from ropecam.device.pipeline.edges import EdgeDetector, gaussian_weights
from ropecam.device.pipeline.finish import FrameClock, ResultFinisher
from ropecam.device.pipeline.locate import RopeLocator
from ropecam.device.pipeline.motion import MotionModel
from ropecam.device.pipeline.split import BlurSplitter
from ropecam.device.pipeline.static_mask import StaticMask
from ropecam.device.pipeline.steady import SteadyFrame
from ropecam.device.pipeline.thresholds import EdgeThresholds
from ropecam.device.pipeline.time_order import TimeOrder
from ropecam.device.pipeline.tone import ToneCurve
from ropecam.device.pipeline.tracking import PointTracker, plane_params
from ropecam.device.pipeline.traits import RopeTraits
from ropecam.device.pipeline.workspace import Workspace, refuse_copies
from ropecam.shared.plane import PlaneCalibration

__all__ = ["SWINGING_PX", "Stages"]

SWINGING_PX = 3.0
"""An end of the rope's outline that moved farther than this (px) from the stream's first outline to its second is a
rope already swinging (a rope released from rest falls about a pixel there): only then are the first frames' still
structures searched for its clamp (`Stages.mask_structure`)."""


@refuse_copies(
    "Stages cannot be copied or pickled: its steady frame reads a table of the raw addresses of its workspace's "
    "buffers, which a copy would share; make new ones with Stages.make(config, shape, plane) instead"
)
@dataclass(frozen=True, slots=True)
class Stages:
    """The stages of one pipeline, each holding its part of one workspace (`Stages.make`)."""

    workspace: Workspace
    """Every buffer of the per-frame path, by stage (its arrays cannot be replaced: `steady_frame`'s table holds
    their addresses)."""
    tone: ToneCurve | BackgroundFlattening
    """The gamma curve applied to each frame (`PipelineConfig.gamma`); with ``background_png`` in the same pass
    the background's texture divided out (`BackgroundFlattening`)."""
    edges: EdgeDetector
    tracer: ContourTracer
    static_mask: StaticMask
    """The static structures whose edges are dropped (learned over the first `static_frames` frames)."""
    thresholds: EdgeThresholds
    """The Canny thresholds measured on the first `threshold_frames` frames (at most `canny_low`/`high`), then
    followed: updated every `threshold_update_frames` slices, a slice every `threshold_sample_every` frames."""
    splitter: BlurSplitter
    tracker: PointTracker
    traits: RopeTraits
    motion: MotionModel
    checks: SelfChecks
    """The self-checks that turn an implausible frame into a status with a reason (`SelfChecks`)."""
    time_order: TimeOrder
    locator: RopeLocator
    finisher: ResultFinisher
    steady: SteadyFrame
    clock: FrameClock
    """The stream's frame period and each frame's exposure (its cells in the workspace, where `steady_frame` ticks
    them; the finisher reads the period from it)."""

    @classmethod
    def make(cls, config: PipelineConfig, shape: tuple[int, int], plane: PlaneCalibration | None) -> Stages:
        """Make the stages for frames of `shape` (height, width) and one workspace for them.

        Parameters
        ----------
        config
            Pipeline settings (already moved onto `plane`: `PipelineConfig.on_plane`).
        shape
            (height, width) of every frame, pixels.
        plane
            The plane calibration, or None: with it the material points are placed by arc length on the plane
            (`PointTracker.plane`), without it by arc length in the image.

        Returns
        -------
        Stages
            The wired stages, with a new workspace.
        """
        height, width = shape
        tone: ToneCurve | BackgroundFlattening = ToneCurve(config.gamma, shape)
        if config.background_png:
            tone = BackgroundFlattening.from_png(config.background_png, shape, config.gamma)
        cap = config.max_contour
        weights = gaussian_weights(config.smooth_sigma_px)
        fraction = np.array(config.material_points_m, np.float64) / config.rope_length_m
        ws = Workspace.make(height, width, cap, weights, fraction)
        edges = EdgeDetector(height, width, config.smooth_sigma_px, config.canny_low, config.canny_high, ws.edges)
        tracer = ContourTracer(height, width, cap, config.min_contour_px, buffers=ws.contour)
        static_mask = StaticMask.from_config(ws.edges, config, shape, edges)
        thresholds = EdgeThresholds(
            height,
            width,
            config.smooth_sigma_px,
            config.canny_low,
            config.canny_high,
            config.threshold_frames,
            update_frames=config.threshold_update_frames,
            sample_every=config.threshold_sample_every,
        )
        lens_blur_px, sharpen_gain, sharpen_sigma_px = config.edge_blur_given or (None, 0.0, 1.0)
        splitter = BlurSplitter(
            cap, config.method, config.static_ratio, config.corner_scale_px,
            config.paper_endpoint_radius_px, config.output_step_px, config.tip_cap, config.smooth_sigma_px,
            lens_blur_px, output_smoothing_px=config.output_smoothing_px, buffers=ws.split,
            sharpen_gain=sharpen_gain, sharpen_sigma_px=sharpen_sigma_px,
        )  # fmt: skip
        splitter.paper.radius_scaled = config.paper_endpoint_radius_scaled
        splitter.lens.decoded = config.gamma != 1.0  # a camera sharpens the encoded frame (`LensBlurEstimate`)
        # A given fixed end (the plane origin, `fixed_end_uv`) is where the rope is held: the shapes start there.
        splitter.axis.through_fixed = config.fixed_end_uv is not None
        tracker = PointTracker(
            config.material_points_m, config.rope_length_m, config.length0_px, config.length0_frames, ws.track
        )
        if plane is not None:
            tracker.plane = plane_params(plane)
        traits = RopeTraits(config, shape, ws.fixed_end, splitter.edge_spacing)
        traits.fixed_end.mask = ws.edges.static_mask  # a rope's end hidden in a masked clamp is found inside it
        motion = MotionModel(ws.motion)
        checks = SelfChecks(config.checks, fallback_single=config.method == "blur_split")
        time_order = TimeOrder(ws.order)
        locator = RopeLocator(config.roi_margin_px, edges, tracer, motion, traits.fixed_end, config.canny_low, ws.roi)
        clock = FrameClock(ws.clock)
        finisher = ResultFinisher(
            splitter, tracker, time_order, motion, checks, traits, tracer, locator, ws.fixed_end.fixed, clock,
            static_mask,
        )  # fmt: skip
        steady = SteadyFrame(
            ws, config.roi_margin_px, edges, tracer, splitter, tracker, locator, traits, checks, static_mask
        )
        return cls(
            ws, tone, edges, tracer, static_mask, thresholds, splitter, tracker, traits, motion, checks,
            time_order, locator, finisher, steady, clock,
        )  # fmt: skip

    def set_thresholds(self, low: float, high: float) -> None:
        """Use the Canny thresholds `low`/`high` from now on (the kernels' argument lists made again)."""
        self.edges.set_thresholds(low, high)
        self.tracer.forget_args()
        self.locator.set_canny_low(low)
        self.steady.unbind()

    def forget(self, roi: bool) -> None:
        """Drop the state that predicts this frame from the last one after a frame without shapes (a gap): the
        tips, steps and sweeps (and with `roi`, the region of interest), so the next frame starts afresh instead
        of extrapolating stale motion. What does not change between frames (fixed end, width, polarity, Lc0)
        is kept, and so is the time-order history, which `TimeOrder.order` drops itself when it is over four frame
        periods old."""
        self.motion.clear()
        self.splitter.sweep_px = 0.0
        if roi:
            self.locator.forget()

    def reset_tracking(self) -> None:
        """Forget the region of interest and the motion, and the time order's history: the next frame is searched
        whole, as the first one (`Pipeline.reset_tracking`)."""
        self.forget(roi=True)
        self.time_order.clear()
        self.checks.restart()

    def mask_structure(self, n: int, exposure_ns: int) -> bool:
        """While the static mask is learned (a stream's first frames), take the structure a still rope's outline
        (the tracer's `n` points) runs round at one end (a clamp, its rod: `FixedEndFinder.structure`) into the
        mask, on the stream's first outline. When that outline showed none (a rope already swinging), take the
        block-like still structure at an end of the outline (`FixedEndFinder.learned_structure`) from the still
        structures of the first `EARLY_FRAMES` frames (`StaticMask.early`; the traits are then learned again), or
        else from the learned mask on the first outline after it is marked. Returns whether it did: the frame's
        contour is then to be found again."""
        mask = self.static_mask
        finder = self.traits.fixed_end
        if mask.learned_due:  # the learned mask just marked: the clamp's outline, but for what the rope swept
            mask.learned_due = False
            if mask.swinging and mask.structure_px == 0 and exposure_ns > 0 and self.traits.settled is None:
                learned = self.traits.fixed_end.learned_structure(
                    self.tracer.points, n, self.traits.width(), mask.buffers.static_mask
                )
                if learned is not None:
                    mask.add_structure(learned)
                    self.locator.forget()
                    return True
            return False
        if mask.structure_tried and mask.learning and not mask.early_tried and mask.structure_px == 0:
            early = mask.early() if exposure_ns > 0 and not finder.configured and mask.first_ends else None
            if early is None:
                return False
            mask.early_tried = True  # the first outline showed no clamp: a rope already swinging? look again
            ends = finder.end_points(self.tracer.points, n, self.traits.width())
            moved = max(min(float(np.hypot(*(a - b))) for b in ends) for a in mask.first_ends)
            mask.swinging = moved > SWINGING_PX
            if not mask.swinging:
                return False  # a rope at rest (released from rest): its own still part is no clamp
            learned = finder.learned_structure(self.tracer.points, n, self.traits.width(), early, mask.first_ends)
            if learned is None:
                return False
            mask.add_structure(learned)
            self.relearn()  # what the first frames taught was read across the clamp
            self.locator.forget()
            return True
        if mask.structure_tried or not mask.learning or exposure_ns <= 0 or self.traits.settled is not None:
            return False
        mask.structure_tried = True  # the first outline of a stream: a rope released from rest is still there
        mask.first_ends = finder.end_points(self.tracer.points, n, self.traits.width())
        region = self.traits.fixed_end.structure(self.tracer.points, n, self.traits.width())
        if region is None:
            return False
        mask.add_structure(region)
        self.locator.forget()
        return True

    def relearn(self) -> None:
        """Learn the rope's traits (fixed end, width, polarity, Lc0, and the contrast and lens blur the split reads)
        again, with the static mask now known: the
        first frames failed (a clamp, rod or plate edge joined to the rope's contour), so what they taught is
        suspect."""
        self.traits.restart()
        self.tracker.restart()
        self.splitter.restart()
        self.steady.unbind()
        self.reset_tracking()
