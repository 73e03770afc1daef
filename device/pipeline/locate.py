"""RopeLocator: find the rope's contour in a frame, in the band predicted from the last one or by searching."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import cell_property, i32, ro
from ropecam.device.pipeline.contour import ContourTracer
from ropecam.device.pipeline.edges import EdgeDetector
from ropecam.device.pipeline.fixed_end import HIDDEN_REACH_PX, FixedEndFinder
from ropecam.device.pipeline.motion import MotionModel
from ropecam.device.pipeline.workspace import COARSE_BLOCK, RoiBuffers, expose

__all__ = ["ATTACHED_PX", "ROI_RETRIES", "RopeLocator"]

ROI_RETRIES = 2
"""Times a band is widened around a contour that runs out of it before the next way of searching is tried."""
_COARSE_MIN_CELLS = 8
"""Smallest group of active cells the coarse search keeps (a hot pixel makes a cross of 5; a rope of the
smallest accepted contour, 40 px, about 20)."""
_COARSE_DILATE = 2
"""Cells added around the kept cells."""
ATTACHED_PX = HIDDEN_REACH_PX + 16.0
"""Farthest a configured fixed end may lie from the nearest point of the rope's contour (px): a clamp hides the
rope's end up to `HIDDEN_REACH_PX`. A component farther from it is another structure (a plate edge, a
distractor), however large."""
_OTHER_COMPONENTS = 3
"""Components not attached to a configured fixed end dropped per search before it gives up."""


@expose("buffers", RoiBuffers)
class RopeLocator:
    """Find the rope's contour: in the band predicted from the last contour, else around the cells where a coarse
    look (block sums) sees intensity steps, else in the whole frame; a band the contour runs out of is widened
    around what was found (up to `ROI_RETRIES` times) before the next way is tried.

    Keeps the last frame's contour (the tracer's own buffer, `prev_count` points) for the next frame's band, and
    counts the frames found each way. Those counts and times are int64 cells (``buffers.cells``, `K.LOCATE_CELLS`),
    which `steady_frame` updates itself on a steady frame: its Python makes no int of them; the attributes read and
    write them on demand.

    Parameters
    ----------
    margin_px
        The band's margin around the predicted contour.
    edges, tracer, motion, fixed_end
        The stages it runs (the edges and the contour in the spans) and reads (the motion model's prediction and
        its measured error, the fixed end).
    canny_low
        The edge detector's low threshold (it sets the coarse look's step).
    buffers
        The spans and the coarse look's cells (`RoiBuffers`; each also a read-only attribute: ``self.lo``).
    """

    def __init__(
        self,
        margin_px: int,
        edges: EdgeDetector,
        tracer: ContourTracer,
        motion: MotionModel,
        fixed_end: FixedEndFinder,
        canny_low: float,
        buffers: RoiBuffers,
    ) -> None:
        self.margin_px = int(margin_px)
        self.shape = edges.shape
        self.edges, self.tracer, self.motion, self.fixed_end = edges, tracer, motion, fixed_end
        self.buffers = buffers
        # Read-only views made once (a view per kernel call costs microseconds of Python).
        self.lo_ro, self.hi_ro, self._grow_lo_ro, self._grow_hi_ro = (
            ro(a) for a in (buffers.lo, buffers.hi, buffers.grow_lo, buffers.grow_hi)
        )
        # The last frame's contour, which the next frame's band is built around: the tracer's own buffer (no copy
        # per frame). Valid because nothing traces between the end of a frame and the band building at the start
        # of the next one (`locate` builds the band first); `prev_count` = 0 marks it stale.
        self.prev_points_ro = tracer.points_ro
        self._cells = buffers.cells
        self.kept = False
        """Whether a contour is kept for the next frame's band (`prev_count` > 0; a plain attribute: the steady
        frame's test)."""
        height, width = self.shape
        self.band_args = (
            self.margin_px, height, width, *motion.need_args, fixed_end.fixed, motion.group, buffers.band,
        )  # fmt: skip
        """`band_stage`'s arguments after the frame's (Python ints and floats for its int64/float64 scalars)."""
        # A cell is active when its mean differs from a neighbour's by canny_low / 8 grey levels: the step over
        # which the Sobel magnitude of a sharp edge reaches the low threshold.
        self.set_canny_low(canny_low)
        self.cut = False
        """Whether this frame's contour was cut from a structure it touched (`_attached`): its tip may be cut."""

    # The cells (`K.LOCATE_CELLS`) as attributes, read and written on demand.
    prev_count = cell_property("_cells", K.LOCATE.prev_count, "Point count of the kept contour (0: none).")
    prev_t_ns = cell_property("_cells", K.LOCATE.prev_t_ns, "Start of the kept contour's frame (ns).")
    need_gap_ns = cell_property("_cells", K.LOCATE.need_gap_ns, "The gap the band's error was measured over (ns).")
    gap_ns = cell_property("_cells", K.LOCATE.gap_ns, "The gap from the kept contour's frame to the last steady one.")
    frames_roi = cell_property("_cells", K.LOCATE.frames_roi, "Frames found in the band predicted for them.")
    frames_coarse = cell_property("_cells", K.LOCATE.frames_coarse, "Frames found around the coarse cells.")
    frames_full = cell_property("_cells", K.LOCATE.frames_full, "Frames searched whole.")
    roi_retries = cell_property("_cells", K.LOCATE.roi_retries, "Widenings of a band the rope ran out of.")

    def set_canny_low(self, canny_low: float) -> None:
        """Follow the edge detector's low threshold (the coarse look's step)."""
        self._coarse_step = i32(max(1, round(COARSE_BLOCK * COARSE_BLOCK * canny_low / 8.0)))

    def forget(self) -> None:
        """Forget the last contour: the next frame is searched without a band."""
        self.prev_count = 0
        self.kept = False

    def locate(self, image: NDArray[np.uint8], t_ns: int, exposure_ns: int) -> tuple[int, bool]:
        """Find the rope's contour in the frame exposed from `t_ns` for `exposure_ns`.

        Returns
        -------
        tuple[int, bool]
            The contour's point count (in the tracer; 0: none) and whether it was found in the band predicted
            from the last frame.
        """
        self.fixed_end.exposure_known = exposure_ns > 0
        self.cut = False
        if self.prev_count > 0:
            model = self.motion
            # The measured error holds for the time gap it was measured over: a longer one (a dropped frame) gets
            # the step-scaled uncertainty, which grows with the gap.
            gap_ns = t_ns - self.prev_t_ns
            # One kernel call (the arguments after the frame's made once): the last band's error measured on the
            # last contour when it was found in that band (`owed`), the prediction, the band.
            motion = K.band_stage(
                self.prev_points_ro, self.prev_count, model.owed, 2 * gap_ns <= 3 * self.need_gap_ns,
                self.fixed_end.known, t_ns, exposure_ns, *self.band_args,
            )  # fmt: skip
            n = self.tracer.detect_and_trace(self.edges, image, self.lo_ro, self.hi_ro)
            return self.locate_in_band(image, motion, gap_ns, n)
        return self._locate_elsewhere(image)

    def locate_in_band(self, image: NDArray[np.uint8], motion_px: float, gap_ns: int, n: int) -> tuple[int, bool]:
        """`locate` after the first search of the band predicted with uncertainty `motion_px` over `gap_ns` from
        the last frame, which found `n` contour points."""
        self.cut = False
        n = self._search(image, self.margin_px + max(8, math.ceil(2.0 * motion_px)), self._attached(n))
        if n > 0:
            self.found_in_band(gap_ns)
            return n, True
        self.motion.forget_need()
        return self._locate_elsewhere(image)

    def found_in_band(self, gap_ns: int) -> None:
        """The contour was found in the band predicted over `gap_ns`: the next band measures its error on it."""
        self.frames_roi += 1
        self.motion.owed = True
        self.need_gap_ns = gap_ns

    def keep(self, n: int, t_ns: int) -> None:
        """The contour of the frame exposed from `t_ns` (`n` points in the tracer) is the one the next frame's
        band is built around (`steady_frame` keeps a steady frame's itself, and counts it in `frames_roi`)."""
        self.prev_count = n
        self.prev_t_ns = t_ns
        self.kept = n > 0

    def _locate_elsewhere(self, image: NDArray[np.uint8]) -> tuple[int, bool]:
        """`locate` without a band: around the coarse look's cells, else in the whole frame."""
        kept = K.coarse_spans(
            ro(image), i32(COARSE_BLOCK), self._coarse_step, i32(_COARSE_MIN_CELLS), i32(_COARSE_DILATE),
            self.coarse_sums, self.coarse_labels, self.coarse_stack, self.lo, self.hi,
        )  # fmt: skip
        if kept > 0:
            first = self._attached(self.tracer.detect_and_trace(self.edges, image, self.lo_ro, self.hi_ro))
            n = self._search(image, self.margin_px + 8, first)
            if n > 0:
                self.frames_coarse += 1
                return n, False
        self.frames_full += 1
        lo, hi = self.edges.full_lo_ro, self.edges.full_hi_ro
        return self._attached(self.tracer.detect_and_trace(self.edges, image, lo, hi), lo, hi), False

    def _attached(self, n: int, lo: NDArray[np.int32] | None = None, hi: NDArray[np.int32] | None = None) -> int:
        """The contour just traced (`n` points, in the spans `lo`/`hi`, default the locator's), or, when the fixed
        end is configured (a plane calibration, ``fixed_end_uv``) and the contour keeps farther than
        `ATTACHED_PX` from it, the largest other component that comes that near (up to `_OTHER_COMPONENTS` are
        dropped; 0: none). The rope is the structure attached to its fixed end: before the static mask is
        learned, a plate edge the rope's tip lies across is a larger component than the rope (the lab scene
        through the paper's camera: it was measured as the rope, "clipped" by the image border)."""
        if not self.fixed_end.configured:
            return n
        for dropped in range(_OTHER_COMPONENTS + 1):
            if n == 0 or self._near_fixed_end(n):
                return n
            if dropped == _OTHER_COMPONENTS:
                return 0
            n = self.tracer.trace_next(self.edges, self.lo_ro if lo is None else lo, self.hi_ro if hi is None else hi)
            self.cut = self.cut or self.tracer.joined
        return n

    def _near_fixed_end(self, n: int) -> bool:
        """Whether the contour just traced (`n` points) comes within `ATTACHED_PX` of the fixed end."""
        fr, fc = self.fixed_end.fixed.tolist()
        points = self.tracer.points[:n]
        return float(np.min((points[:, 0] - fr) ** 2 + (points[:, 1] - fc) ** 2)) <= ATTACHED_PX**2

    def _search(self, image: NDArray[np.uint8], grow: int, n: int) -> int:
        """Go on with the search in the spans `lo`/`hi` whose first detection and trace found `n` contour points:
        widen them by `grow` px around a contour that reaches their border and search again; returns the
        contour's points, 0 when it is not found whole inside them."""
        for attempt in range(ROI_RETRIES + 1):
            if attempt > 0:
                n = self._attached(self.tracer.detect_and_trace(self.edges, image, self.lo_ro, self.hi_ro))
            if n == 0:
                return 0
            contacts = self.tracer.contacts  # counted by the trace on these spans
            if contacts < 0:
                contacts = self.tracer.roi_contacts(self.lo_ro, self.hi_ro)
            if contacts == 0:
                self.roi_retries += attempt
                return n
            if contacts * 4 > n:  # mostly cut off: the rope is elsewhere, widening would only creep after it
                break
            if attempt < ROI_RETRIES:  # the rope runs out of the band: widen it around what was found
                fr, fc = self.fixed_end.fixed.tolist() if self.fixed_end.known else (0.0, 0.0)
                K.spans_around_chain(
                    self.tracer.points_ro, n, grow, 0.0, self.motion.profile_ro, 1.0, 0.0, fr, fc, self.shape[0],
                    self.shape[1], self.grow_lo, self.grow_hi, self.no_moved,
                )  # fmt: skip
                K.union_spans(self._grow_lo_ro, self._grow_hi_ro, self.lo, self.hi)
        self.roi_retries += attempt
        return 0
