"""BlurSplitter: split the closed contour of a motion-blurred rope into the rope at the start and at the end of the
exposure (and the tip track), or into one centreline when the blur cannot be split."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import cell_property, ro
from ropecam.device.pipeline.edge_model import BandEdgeModel
from ropecam.device.pipeline.edge_profile import EdgeBlur
from ropecam.device.pipeline.edges import EdgeDetector, gaussian_weights
from ropecam.device.pipeline.lens_blur import LensBlur
from ropecam.device.pipeline.paper_method import PaperSegmenter, split_by_comparison
from ropecam.device.pipeline.result import Method, SplitOutcome
from ropecam.device.pipeline.split_axis import AxisPolylines
from ropecam.device.pipeline.split_call import SplitFrameCall
from ropecam.device.pipeline.split_measure import BandMeasure
from ropecam.device.pipeline.tip_geometry import correct_slant, tip_lateral
from ropecam.device.pipeline.width_tables import WidthTables
from ropecam.device.pipeline.workspace import SplitBuffers, expose

__all__ = ["BlurSplitter", "SplitOutcome"]

_SHAPES = 2
"""`split_frame`'s (and `split_shapes`') return value when it made the two shapes."""
_BLUR_SPLIT = Method.BLUR_SPLIT


@expose("buffers", SplitBuffers)
class BlurSplitter:
    """Split a rope contour by one of the methods (``blur_split``, ``paper``, ``centerline``).

    The sequence of the blur split is `split`; its collaborators own their state: `measure` (`BandMeasure`:
    polarity, width, contrast, sweep from the edge slope), `frame_call` (`SplitFrameCall`: the whole split in
    one `split_frame` call once width, polarity and contrast are known), `lens` (`LensBlur`: the band edge
    model, of the camera blur given or read from the first frames), the tables of each rope width
    (`WidthTables`) and the comparison methods (`split_by_comparison`).

    Parameters
    ----------
    capacity
        Maximum number of contour points.
    method
        The configured method.
    static_ratio
        Tip sweep / rope width below which the centreline fallback replaces the split (when the body's own sweep,
        `K.body_sweep`, is below it too).
    corner_scale_px
        Chord (points) of the turning angle that finds the segmentation points.
    paper_radius_px
        Threshold T of the paper's Feature 3.
    output_step_px
        Spacing of the returned polylines.
    tip_cap
        Shape of the rope's free end: ``flat`` (the axis ends at the band's end) or ``round`` (half a width
        beyond the axis end).
    smooth_sigma_px
        The edge detector's Gaussian smoothing.
    lens_blur_px
        The camera blur (Gaussian sigma, px) of the band edge model (`BandEdgeModel`); None: measured on the
        first frames of the blur split with the sharpening (`LensBlur`), `DEFAULT_LENS_BLUR_PX` until then.
    sharpen_gain, sharpen_sigma_px
        The camera's sharpening (unsharp mask) of the band edge model, with a given `lens_blur_px`.
    output_smoothing_px
        Half-width along the rope of the smoothing of the returned polylines (0: none).
    """

    def __init__(
        self,
        capacity: int,
        method: str = "blur_split",
        static_ratio: float = 0.6,
        corner_scale_px: int = 3,
        paper_radius_px: float = 15.0,
        output_step_px: float = 2.0,
        tip_cap: str = "flat",
        smooth_sigma_px: float = 1.0,
        lens_blur_px: float | None = None,
        output_smoothing_px: float = 0.0,
        sharpen_gain: float = 0.0,
        sharpen_sigma_px: float = 1.0,
        buffers: SplitBuffers | None = None,
    ) -> None:
        if buffers is None:
            buffers = SplitBuffers.make(capacity)
        elif buffers.turn.shape[0] != capacity:
            raise ValueError(f"buffers are for {buffers.turn.shape[0]} contour points, expected {capacity}")
        self.buffers = buffers
        """The split's buffers (`SplitBuffers`; each also a read-only attribute: ``self.sides``)."""
        self.fixed_dist, self.slope_work = self.scratch[1], self.scratch[2]
        self.method = method
        self.paper = PaperSegmenter(capacity, paper_radius_px, output_step_px=output_step_px)
        self.tip_cap_ratio = 0.5 if tip_cap == "round" else 0.0
        self.weights = gaussian_weights(smooth_sigma_px).astype(np.float64)
        self.smooth_sigma = float(smooth_sigma_px)
        self.lens = LensBlur(self.weights, lens_blur_px, sharpen_gain, sharpen_sigma_px, method == "blur_split")
        """The band edge model in use and the camera blur behind it (read on the first frames unless given)."""
        self.sweep_window = 3
        self.corner_rad = 0.5
        """Smallest turning angle (rad, at the chord scale) taken for a band corner: a slanted band end's obtuse
        corner turns about 45 degrees, smeared over the chord."""
        self.failure = ""
        """Why the last `split` returned None."""
        self.work, self.sweeps_a, self.sweeps_b = self.lines[0], self.lines[1], self.lines[2]
        self.sweep_px = 0.0
        self.static_ratio = float(static_ratio)
        self.corner_scale = int(corner_scale_px)
        self._refresh: Callable[[int, int, int, int], None] | None = None
        self.side_a, self.side_b, self.out_a, self.out_b = self.sides[0], self.sides[1], self.sides[2], self.sides[3]
        self._state = buffers.state
        self._count = 0
        self._given = False
        """Whether the last `_prepare` was given the width and polarity (nothing measured)."""
        self.axis = AxisPolylines(buffers, output_step_px, output_smoothing_px, smooth_sigma_px)
        """The returned polylines' finish (tip fit, anchoring, resampling) and the centreline fallback."""
        # Read-only views of the own buffers and int32 constants, made once (a view costs 1-2 us of Python).
        self._side_a_ro, self._side_b_ro = ro(self.side_a), ro(self.side_b)
        self._sweeps_a_ro, self._sweeps_b_ro = ro(self.sweeps_a), ro(self.sweeps_b)
        self._plus, self._minus = np.int32(1), np.int32(-1)
        self._zero = np.int32(0)
        self._spans: tuple[NDArray[np.int32], NDArray[np.int32]] = (np.zeros(0, np.int32), np.zeros(0, np.int32))
        """The row spans (lo, hi) the planes of this `split` are valid in (`measure_widths` stays inside them)."""
        self._bound: tuple[NDArray, ...] = ()
        """The arrays of the last `_prepare` (points, chain, gx, gy, mag): the same buffers every frame, so their
        read-only views are made once."""
        self._bound_views: tuple[NDArray, ...] = ()
        """Their read-only views (points, chain, gx, gy, mag), made with `_bound`."""
        self._gradients: tuple[NDArray, ...] = ()
        """(gx, gy, mag) of the last `_prepare` as given (writable: `split_shapes` takes them in `Planes`)."""
        self._no_index, self._no_distances = ro(np.zeros(0, np.int32)), ro(np.zeros(0, np.float64))
        self._no_gains, self._no_frame = self._no_distances, ro(np.zeros((0, 0), np.uint8))
        self.measure = BandMeasure(self.lens.model, self.dist, self.slope_work)
        self._info, self._seg = buffers.info, buffers.seg  # read every frame (`_frame_outcome`): plain attributes
        self._info_cells = memoryview(self._info)  # its values one by one (a memoryview's item: no NumPy scalar)
        self._axis_shape = self.axis.shape  # a steady frame's shapes (`_frame_outcome`), the bound method made once
        self._shapes_outcome = SplitOutcome(_BLUR_SPLIT, buffers.sides[0][:0], buffers.sides[1][:0], None, 0.0, 0.0)
        """The outcome `_frame_outcome` fills for two shapes, one object for every frame (no allocation per frame):
        valid, as its shapes, until the next split."""
        self.frame_call = SplitFrameCall(buffers)
        self.polarity_used = np.float32(0.0)
        """The polarity of the last split (+1 bright rope, -1 dark)."""
        self.width = 4.0
        """The edge spacing (px) the last split used."""
        self.width_measured = math.nan
        """The edge spacing (px) measured on the last contour (nan: given, or not measured)."""
        self._fixed_key: tuple[float, float] | None = None
        self._fixed32 = (np.float32(0.0), np.float32(0.0))
        self._width_key = math.nan
        self._width_consts: WidthTables | None = None
        self._polarity_key = 0.0
        self._polarity32 = np.float32(0.0)
        self._views: dict[int, tuple[NDArray, NDArray]] = {}
        self._per_width: dict[float, WidthTables] = {}

    _count = cell_property(
        "_state", K.FRAME_STATE.n, "The stored contour's point count (`_n`): `split_frame`'s, which it reads there."
    )

    @property
    def _n(self) -> np.int32:
        """The stored contour's point count as the kernels take it (made on use: the one-call path does not)."""
        return np.int32(self._count)  # NumPy 2 refuses a value out of the int32 range

    @_n.setter
    def _n(self, n: int) -> None:
        self._count = int(n)

    def _ro(self, array: NDArray) -> NDArray:
        """A read-only view of `array`, made once per array (the pipeline passes the same buffers every frame)."""
        cached = self._views.get(id(array))
        if cached is not None and cached[0] is array:
            return cached[1]
        view = ro(array)
        if len(self._views) > 32:
            self._views.clear()
        self._views[id(array)] = (array, view)
        return view

    def _constants(self, width: float) -> WidthTables:
        """The scalars and tables that depend only on the rope width, made once per width."""
        found = self._per_width.get(width)
        if found is None:
            if len(self._per_width) > 64:
                self._per_width.clear()
            found = self._per_width[width] = WidthTables(self, width)
        return found

    @property
    def model(self) -> BandEdgeModel:
        """The band edge model in use (`LensBlur.model`)."""
        return self.lens.model

    @property
    def blur_measured(self) -> EdgeBlur | None:
        """The lens blur and sharpening the first frames measured (`LensBlur.measured`)."""
        return self.lens.measured

    @property
    def blur_read(self) -> EdgeBlur | None:
        """The lens blur and sharpening measured, or read so far (`LensBlur.value`)."""
        return self.lens.value

    def restart(self) -> None:
        """Forget what the first frames read off the band (the contrast readings, and the lens blur and sharpening
        when they were measured rather than given): they were read on contours the static mask did not yet clean,
        where a clamp's edges pass for the rope's (`Stages.relearn`)."""
        self.measure.forget()
        self.frame_call.key = None
        if self.lens.restart():
            self._forget_model()

    def edge_spacing(self, width_px: float) -> float:
        """Edge spacing (px) of a still rope `width_px` wide under the edge model in use (`BandEdgeModel`)."""
        return self.model.edge_spacing(width_px)

    def _forget_model(self) -> None:
        """Make again what was derived from the edge model, which changed (`LensBlur.read`): the tables per
        width, the contrast (divided by its rope width), the one-call split's arguments (`SteadyFrame` binds
        again)."""
        self.measure.model = self.lens.model
        self.measure.rescale()
        self._per_width.clear()
        self._width_key = math.nan
        self._width_consts = None
        self.frame_call.key = None

    def split(
        self,
        points: NDArray[np.float32],
        chain: NDArray[np.int32],
        n: int,
        fixed_rc: tuple[float, float],
        width_px: float | None,
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        edges: NDArray[np.uint8],
        mag: NDArray[np.float32],
        smooth: NDArray[np.float32],
        polarity: float = 0.0,
        edge_stage: EdgeDetector | None = None,
        frame: NDArray[np.uint8] | None = None,
    ) -> SplitOutcome | None:
        """Split the closed contour (`_split`); while the lens blur is being read (`LensBlur.read`), read it on
        this frame and, when that changes the edge model, split the frame again with it.
        """
        outcome = self._split(
            points, chain, n, fixed_rc, width_px, gx, gy, edges, mag, smooth, polarity, edge_stage, frame
        )
        lens = self.lens
        if (
            lens.estimate is not None
            and outcome is not None
            and frame is not None
            and lens.read(frame, points, n, fixed_rc, self.width, self.sweep_px)
        ):
            # The model read a still rope under a blur it did not expect as a moving one (a blurred edge's
            # gradient is low, as a sweeping one's): the frame is split again with the measured blur.
            self._forget_model()
            outcome = self._split(
                points, chain, n, fixed_rc, width_px, gx, gy, edges, mag, smooth, polarity, edge_stage, frame
            )
        return outcome

    def _split(
        self,
        points: NDArray[np.float32],
        chain: NDArray[np.int32],
        n: int,
        fixed_rc: tuple[float, float],
        width_px: float | None,
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        edges: NDArray[np.uint8],
        mag: NDArray[np.float32],
        smooth: NDArray[np.float32],
        polarity: float = 0.0,
        edge_stage: EdgeDetector | None = None,
        frame: NDArray[np.uint8] | None = None,
    ) -> SplitOutcome | None:
        """Split the closed contour (`n` subpixel `points`, integer `chain`) of a rope fixed at `fixed_rc`.

        Parameters
        ----------
        width_px
            The rope width if known (config or earlier frames); otherwise measured here.
        gx, gy, edges, mag
            The gradients, edge map and gradient magnitude the contour came from (read only).
        polarity
            +1 bright rope, -1 dark rope, 0 to decide from the gradients.
        edge_stage, frame
            The edge stage whose last `detect` on `frame` made the planes (`smooth` is its `smooth`). It fills
            `smooth` inside its band only, and the contrast and the tip fit read it a few pixels beyond: the split
            has the edge stage smooth those boxes of `frame` first (`EdgeDetector.refresh`). Once the rope's width,
            polarity and contrast are known, the split runs in one kernel call (`split_frame`), which smooths them
            itself. None (both): `smooth` is valid everywhere.

        Returns
        -------
        SplitOutcome or None
            None when the contour cannot be split (too short, no segmentation points).
        """
        if frame is not None and self.frame_call.matches(
            points, chain, gx, gy, mag, smooth, edge_stage, fixed_rc, width_px, polarity
        ):
            # The same contour buffers, edge stage, fixed end, width and polarity as the last frame, which took
            # the one-call path: everything `_prepare` and the checks below would set is set already.
            self._smooth = smooth
            self.failure = "contour found but no segmentation points"
            self._count = n
            outcome = self._frame_outcome(self.frame_call.call(edge_stage, frame, self.sweep_px, n), fixed_rc)
            if outcome is not False:
                return outcome
        self.frame_call.key = None
        self._smooth = smooth
        refresh = None
        if edge_stage is not None and frame is not None:
            # Made only when a step of the sequence reads the smoothed image (not on the one-call path).
            refresh = (
                edge_stage.refresh if frame is edge_stage.frame else functools.partial(edge_stage.smooth_box, frame)
            )
        self._refresh = refresh
        self.failure = "contour found but no segmentation points"
        self._spans = edge_stage.spans if edge_stage is not None else self.measure.whole_spans(edges.shape)
        self._prepare(points, chain, n, width_px, gx, gy, edges, polarity, mag, fixed_rc)
        points_in, chain_in = points, chain
        points, chain, n = self._points, self._chain, self._n
        if self.method in ("paper", "centerline"):
            outcome, sweep_px = split_by_comparison(
                self.method, self.paper, self._points, self._chain, int(self._n), fixed_rc, self.width
            )
            self.sweep_px = self.sweep_px if sweep_px is None else sweep_px
            return outcome
        if fixed_rc != self._fixed_key:  # the fixed end settles after a few frames: its float32 pair made once
            self._fixed_key, self._fixed32 = fixed_rc, (np.float32(fixed_rc[0]), np.float32(fixed_rc[1]))
        fixed_r, fixed_c = self._fixed32
        width = self.width
        if width != self._width_key:
            self._width_key, self._width_consts = width, self._constants(width)
        consts = self._width_consts
        assert consts is not None
        if (
            edge_stage is not None
            and frame is not None
            and self.method == "blur_split"
            and self.measure.contrast_settled
            and smooth is edge_stage.smooth
            and gx is edge_stage.gx
            and gy is edge_stage.gy
            and mag is edge_stage.mag
        ):
            call = self.frame_call
            call.bind(
                consts, edge_stage, self._bound_views, fixed_rc, self._fixed32, self.polarity_used,
                self.measure.contrast_for(width), self.measure.decision_contrast(width),
            )  # fmt: skip
            outcome = self._frame_outcome(call.call(edge_stage, frame, self.sweep_px, self._count), fixed_rc)
            if outcome is not False:
                if self._given:
                    call.key = (points_in, chain_in, gx, gy, mag, smooth, edge_stage, fixed_rc, width_px, polarity)
                return outcome
        # The band's corners lie at the free end, but an end that also moves along the rope (a whipping tip)
        # slants the band's end: the corners can then differ in distance from the fixed end by up to about the
        # sweep. The last frame's sweep widens the zone searched (a rope does not change its speed much between
        # frames); the sharpest turn in the zone is still a corner, the sides turn little.
        search = np.float32(max(consts.search_px, 1.2 * self.sweep_px))
        found = K.find_segmentation_points(
            points, n, consts.scale, fixed_r, fixed_c, search, consts.min_gap, consts.corner, self.fixed_dist,
            self.turn, self.work, self.idx,
        )  # fmt: skip
        if found < 0 or self.method == "static":
            return self.static(fixed_rc)
        idx = self.idx
        i_fix, seg_a, seg_b = idx[0], idx[1], idx[3]  # int32 scalars, as the kernels take them
        plus, minus = self._plus, self._minus
        seg = self.seg
        ar, ac = points[seg_a].tolist()
        br, bc = points[seg_b].tolist()
        if refresh is not None:
            # The tip fit (`extend_to_band_end`) reads the smoothed image up to 3 blur + 1 (reach) + 2 (flank) px
            # past the band's end next to each corner, on lines 0.5 px apart, bilinearly: this frame's values must
            # be there, and the band need not reach so far.
            grow = 3.0 * float(consts.blur) + 6.0 + width
            height, width_img = self._smooth.shape
            refresh(
                max(0, math.floor(min(ar, br) - grow)), min(height - 1, math.ceil(max(ar, br) + grow)),
                max(0, math.floor(min(ac, bc) - grow)), min(width_img - 1, math.ceil(max(ac, bc) + grow)),
            )  # fmt: skip
        seg[0, 0] = ar
        seg[0, 1] = ac
        seg[1, 0] = br
        seg[1, 1] = bc
        sweep = math.hypot(ar - br, ac - bc)
        # Read once per split: while it is learned each reading is one of the first `CONTRAST_FRAMES` frames'.
        contrast = self._contrast(fixed_rc)
        decide = contrast * self.measure.ratio_gain  # the decision's (`BandMeasure.ratio_gain`)
        if sweep < 1.5 * width:
            # The corners of the band are a rope width apart whatever the sweep below that: read the sweep from
            # the edge slope instead (contrast / sweep, see `BandMeasure.sweep_from_gradient`).
            from_slope = self.measure.sweep_from_gradient(
                self._chain, self._n, self._mag_ro, i_fix, seg_a, seg_b, decide, consts
            )
            if math.isfinite(from_slope):
                sweep = min(from_slope, 1.5 * width)
        self.sweep_px = sweep
        # A tip that turns while a wave sweeps the body (a whip) ends the band one rope wide: the body's own
        # sweep keeps the split, whose sides are then the two shapes there (the band's middle is half a sweep off).
        if sweep < self.static_ratio * width:
            body = self.measure.body_sweep(self._chain, self._n, self._mag_ro, i_fix, seg_a, seg_b, decide, consts)
            if not body >= self.static_ratio * width:
                return self.static(fixed_rc)
        tables = consts.tables
        table, step = consts.table_ro, consts.table_step
        gx, gy, pol = self._gx, self._gy, self.polarity_used
        # The local sweep along each side, from the edge's slope (contrast / sweep): a whipping rope does not
        # sweep in proportion to the distance from the fixed end. Without a contrast reading, that proportion.
        local = plus if contrast >= 5.0 else self._zero
        if local:
            # The usual case, in one kernel call; its rare failures (a full buffer) are redone step by step below.
            # Every contour point checked by the tip fit (no distances), the sweep table walked (no index).
            status = K.split_shapes(
                points, chain, n, i_fix, seg_a, seg_b, K.Planes(self._smooth, *self._gradients),
                self._no_frame if frame is None else frame, np.float32(1.0 / contrast), pol, consts.group,
                self._no_index, fixed_r, fixed_c, self._no_distances, self.group,
            )  # fmt: skip
            if status >= 0 or status == K.NOT_FOUND:
                self.sweep_px = sweep
                return self._written_outcome(status, tables.width_px, sweep)
            inv, half, mag = np.float32(1.0 / contrast), consts.sweep_window, self._mag_ro
            ratios, sweeps = tables.peak_ratio, tables.sweeps_px
            no, gains = self._no_gains, self.slope_work
            for seg_i, sign, out, out_ro in ((seg_a, plus, self.sweeps_a, self._sweeps_a_ro),
                                             (seg_b, minus, self.sweeps_b, self._sweeps_b_ro)):  # fmt: skip
                K.side_sweeps(chain, n, i_fix, seg_i, sign, mag, inv, no, ratios, sweeps, half, self.work, out)
                # As `split_shapes`: the rope's own contrast along the band, when it varies along the side.
                if frame is not None and consts.rope_px > 0.0 and K.contrast_gains(
                    points, chain, n, i_fix, seg_i, sign, frame, gx, gy, pol, out_ro, consts.width,
                    float(np.float32(1.0 / inv)) * float(np.float32(consts.rope_px)), K.CONTRAST_STRIDE, self.work,
                    gains,
                ) > 0:  # fmt: skip
                    K.side_sweeps(chain, n, i_fix, seg_i, sign, mag, inv, ro(gains), ratios, sweeps, half, self.work,
                                  out)  # fmt: skip
        sweeps_a, sweeps_b = self._sweeps_a_ro, self._sweeps_b_ro
        smooth_ro = self._ro(self._smooth)
        for _ in range(2):
            sw = np.float32(sweep)
            if local:  # as `split_shapes` does
                keep = consts.keep
                na = K.offset_by_table_thinned(
                    points, chain, n, i_fix, seg_a, plus, gx, gy, pol, sweeps_a, step, table, keep, keep, self.side_a
                )
                nb = K.offset_by_table_thinned(
                    points, chain, n, i_fix, seg_b, minus, gx, gy, pol, sweeps_b, step, table, keep, keep, self.side_b
                )
            else:
                na = K.offset_by_table(
                    points, chain, n, i_fix, seg_a, plus, gx, gy, pol, sweeps_a, local, sw, step, table, self.side_a
                )
                nb = K.offset_by_table(
                    points, chain, n, i_fix, seg_b, minus, gx, gy, pol, sweeps_b, local, sw, step, table, self.side_b
                )
            na = self.axis.fit_tip(self.side_a, na, points, n, smooth_ro, consts, seg_a, seg_b)
            nb = self.axis.fit_tip(self.side_b, nb, points, n, smooth_ro, consts, seg_a, seg_b)
            # The fitted tips are sharper than the band's rounded corners: their distance across the rope is the
            # sideways sweep at the tip. Where it differs, the offsets of the proportional model are redone with it.
            if local:
                break
            lateral = tip_lateral(self.side_a, na, self.side_b, nb)
            if not (math.isfinite(lateral) and abs(lateral - sweep) > 0.25):
                break
            if lateral < self.static_ratio * width:
                break
            sweep = lateral
        self.sweep_px = sweep
        correct_slant(self.side_a, na, self.side_b, nb, tables.slant_px)
        # A rope keeps its length within an exposure: two shapes of clearly different lengths mean the contour
        # was not cut at the band's corners (a faint, broken band end traced the wrong way round).
        len_a = K.polyline_length(self._side_a_ro, np.int32(na))
        len_b = K.polyline_length(self._side_b_ro, np.int32(nb))
        if abs(len_a - len_b) > max(3.0 * width, 0.1 * max(len_a, len_b)):
            self.failure = f"the two shapes differ in length ({len_a:.0f} and {len_b:.0f} px): split rejected"
            return None
        na = self.axis.anchor_fixed_end(self.side_a, na, fixed_rc, width)
        nb = self.axis.anchor_fixed_end(self.side_b, nb, fixed_rc, width)
        len_a = K.polyline_length(self._side_a_ro, np.int32(na))
        len_b = K.polyline_length(self._side_b_ro, np.int32(nb))
        shape_a = self.axis.resample(0, na, len_a)
        shape_b = self.axis.resample(1, nb, len_b)
        return SplitOutcome(Method.BLUR_SPLIT, shape_a, shape_b, seg, tables.width_px, sweep)

    def _prepare(
        self,
        points: NDArray[np.float32],
        chain: NDArray[np.int32],
        n: int,
        width_px: float | None,
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        edges: NDArray[np.uint8],
        polarity: float,
        mag: NDArray[np.float32],
        fixed_rc: tuple[float, float] | None,
    ) -> None:
        """Store read-only views, the contour orientation, the polarity and the rope width of this contour."""
        bound = self._bound
        if not (
            bound and points is bound[0] and chain is bound[1] and gx is bound[2] and gy is bound[3] and mag is bound[4]
        ):
            self._points, self._chain = self._ro(points), self._ro(chain)
            self._mag_ro = self._ro(mag)
            self._gx, self._gy = self._ro(gx), self._ro(gy)
            self._bound = (points, chain, gx, gy, mag)
            self._bound_views = (self._points, self._chain, self._gx, self._gy, self._mag_ro)
            self._gradients = (gx, gy, mag)
        self._n = np.int32(n)  # NumPy 2 refuses a value out of the int32 range
        mag = self._mag_ro
        pol = float(polarity)
        if pol != 0.0 and width_px is not None:
            if pol != self._polarity_key:
                self._polarity_key, self._polarity32 = pol, np.float32(pol)
            self.polarity_used = self._polarity32
            self.width_measured = math.nan
            self.width = float(width_px)
            self._given = True
            return
        self._given = False
        self.polarity_used, self.width_measured, self.width = self.measure.polarity_and_width(
            self._points, self._chain, self._n, self._gx, self._gy, mag, self._ro(edges), self._spans, width_px,
            polarity, fixed_rc,
        )  # fmt: skip

    def _contrast(self, fixed_rc: tuple[float, float]) -> float:
        """The rope's contrast (`BandMeasure.contrast`) read on the contour stored by `_prepare`."""
        self.measure.ratio_applies = self.lens.decoded and float(self.polarity_used) < 0.0
        return self.measure.contrast(
            self._points, self._chain, int(self._n), self._gx, self._gy, self._smooth, self._refresh,
            float(self.polarity_used), self.width, fixed_rc,
        )  # fmt: skip

    def static(self, fixed_rc: tuple[float, float] | None = None) -> SplitOutcome | None:
        """Return the centreline of a rope that did not move (or cannot be split) (`AxisPolylines.centreline`) on
        the contour of the last `split`. Call after `split` on the same contour."""
        return self.axis.centreline(
            self._points, self._chain, self._n, self._gx, self._gy, self.polarity_used, self.width, fixed_rc,
            self._ro(self._smooth), self._constants,
        )  # fmt: skip

    def adopt_frame(self, status: int, fixed_rc: tuple[float, float]) -> SplitOutcome | bool | None:
        """Take the results of a `split_frame` call made inside `steady_frame` (with the state `split` would have
        set, on the contour, frame and spans of the key of `SplitFrameCall.one_call_key`; the contour's point count
        in that state), as `split` would have after making it. Returns as `split`, or False when the kernel
        reported a full buffer: `split` then redoes the frame's split step by step (it makes the same `split_frame`
        call first, with the same result)."""
        self.failure = "contour found but no segmentation points"
        return self._frame_outcome(status, fixed_rc)

    def _frame_outcome(self, status: int, fixed_rc: tuple[float, float]) -> SplitOutcome | bool | None:
        """The outcome of the `split_frame` call that returned `status` (its `info`, `seg` and shapes are here);
        False when it reported a full buffer."""
        width_px = self.frame_call.width_px
        info = self._info
        if status == _SHAPES:  # the usual outcome first; read field by field (no list), into one reused outcome
            item = self._info_cells
            self.sweep_px = sweep = item[6]
            shape = self._axis_shape
            outcome = self._shapes_outcome
            outcome.method, outcome.segmentation_points = _BLUR_SPLIT, self._seg
            outcome.shape_a = shape(0 if item[4] else 2, item[0])  # the counts as floats: no int made
            outcome.shape_b = shape(1 if item[5] else 3, item[1])
            outcome.width_px, outcome.sweep_px = width_px, sweep
            return outcome
        if status < 0 and status != K.NOT_FOUND:
            return False
        sweep = float(info[6])
        if sweep >= 0.0:
            self.sweep_px = sweep
        if status == K.SPLIT_STATIC:
            return self.static(fixed_rc)
        return self._written_outcome(status, width_px, sweep)

    def _written_outcome(self, status: int, width_px: float, sweep_px: float) -> SplitOutcome | None:
        """The two shapes a kernel (`split_shapes`, `split_frame`) wrote when it returned `status` (their counts,
        lengths and which buffer holds each in `info`), or None for NOT_FOUND (lengths too different)."""
        count_a, count_b, len_a, len_b, smoothed_a, smoothed_b, _ = self._info.tolist()
        if status == K.NOT_FOUND:
            self.failure = f"the two shapes differ in length ({len_a:.0f} and {len_b:.0f} px): split rejected"
            return None
        shape_a = (self.side_a if smoothed_a else self.out_a)[: int(count_a)]
        shape_b = (self.side_b if smoothed_b else self.out_b)[: int(count_b)]
        return SplitOutcome(Method.BLUR_SPLIT, shape_a, shape_b, self._seg, width_px, sweep_px)
