"""SelfChecks: turn an implausible answer into a status with a reason instead of OK.

A frame the pipeline measured is compared with what the first frames taught it and with what the motion model
predicted, using scalars the pipeline has already computed (no per-frame allocation beyond the result):

======================  ==============================================================================  ===========
reason                  fails when                                                                      status
======================  ==============================================================================  ===========
``length``              a shape's length Lc differs from Lc0 (the median of the first shapes) by more   IMPLAUSIBLE
                        than ``length_tolerance`` (a fraction of Lc0), or the two shapes of a split
                        differ from each other by more than ``length_mismatch`` (a fraction of Lc0)
``width``               the width the split used differs from the learned width by more than            IMPLAUSIBLE
                        ``width_tolerance`` (a fraction of it); or, on a split of known exposure whose
                        contour's area is measured (no prediction yet), the contour encloses less than
                        ``min_band_area`` x the still rope's area (length x width): the outline is not a
                        band round the rope (a whisker of a structure's outline that ran out and back)
``fixed_end``           a shape starts farther from the learned or given fixed end than                  IMPLAUSIBLE
                        ``fixed_end_widths`` rope widths plus ``fixed_end_floor_px``
``tip_motion``          the tips' midpoint lies farther from where the motion model predicted it than    IMPLAUSIBLE
                        ``tip_motion_factor`` x the model's own predicted error plus ``tip_motion_floor_px``
``order``               the time order is decided (known exposure, two shapes) with a confidence below   IMPLAUSIBLE
                        ``min_order_confidence``; or a split of known exposure has nothing to decide it
                        by (no earlier frame in the order's history: confidence 0.5) while its tips lie
                        more than ``order_unknown_widths`` rope widths apart: either shape may be the
                        start of the exposure
``no_blur``             a split's tips lie more than ``no_blur_px`` (and 4 / ``min_blur_evidence``) px   NO_BLUR
                        apart without
                        evidence of blur: the
                        exposure is unknown (0: a still photo, a video) or the motion model has no
                        prediction (the first frames, after a gap), and the area the contour
                        encloses beyond the still rope's (length x width) is less than
                        ``min_blur_evidence`` x the area the split's sweep implies (0.5 x length x tip
                        separation, the rope turning about its fixed end); the frame then carries the
                        static centreline instead of the split
``tip_masked``          the static mask lies within ``tip_mask_widths`` rope widths +                   IMPLAUSIBLE
                        ``tip_mask_floor_px`` beyond either shape's free tip, along the rope (or up to
                        a width behind it or beside it): the mask may have cut the rope there (a rope
                        crossing a masked plate edge or cable ends at it), and the rope's end is not
                        seen; unless the frame shows both tips as the rope's ends (the rope at each
                        tip, and beyond it the still scene the mask learned: `StaticMask.shows_end`)
``fallback_sweep``      the blur split fell back to one shape (the band's middle: the rope at           IMPLAUSIBLE
                        mid-exposure) while the tip's path over the last frames swept more than
                        ``fallback_sweep_widths`` rope widths during the exposure: the shape is neither
                        the start nor the end of the exposure; also the one-shape frame right after
                        such a frame, which has no prediction (once)
``tip_kink``            either shape's direction turns by more than ``tip_kink_deg`` between its last    IMPLAUSIBLE
                        ``tip_kink_widths`` rope widths and the same arc before them: a free end
                        carries no bending moment and runs straight; a turn there is a tip that ran
                        on along noise beyond the band's faint end
``tip_at_fixed_end``    a frame of known exposure without a motion prediction (the first frames, after   IMPLAUSIBLE
                        a gap): a shape's free tip lies at the fixed end (within ``fixed_end_widths``
                        rope widths + ``fixed_end_floor_px``) although the shape is more than twice
                        that long: it ran out along the rope and back (round a clamp's outline), its
                        tip is not the rope's
``tip_corner``          a split of known exposure without a motion prediction: a fitted tip lies         IMPLAUSIBLE
                        farther than ``tip_corner_widths`` rope widths + ``tip_corner_floor_px`` from
                        its segmentation point (the band's corner it was read at): the tip fit ran
                        along the band's end or off it; and on any split: its two segmentation points
                        lie closer together than half the rope's width (the learned edge spacing: one
                        corner found twice) while its tips lie farther apart than the corners by more
                        than a width
``tip_short``           one shape (the blur split's static fallback) of a frame of known exposure ends   IMPLAUSIBLE
                        farther than ``tip_short_widths`` rope widths + ``tip_short_floor_px`` from the
                        contour's farthest point from the fixed end (the band's far end): its tip was
                        read at a cap inside the band, short of the rope's end
``fixed_end_guess``     a frame of known exposure measured about a fixed end only guessed on an outline  IMPLAUSIBLE
                        (`FixedEndFinder.confirmed` false) that shows no rope at rest (the guess's outline
                        no band, or its ends' widths across more than half a rope width apart; or the
                        frame's tips more than a width apart): checked by `ResultFinisher` after the others
======================  ==============================================================================  ===========

Each check's measure goes into the frame's quality record (`QUALITY_KEYS`), whether it passes or not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import ro
from ropecam.shared.config import check_range
from ropecam.shared.errors import ConfigError
from ropecam.shared.protocol.frame_result import FrameStatus
from ropecam.shared.protocol.quality import QUALITY_KEYS, Reason

if TYPE_CHECKING:
    from ropecam.device.pipeline.static_mask import StaticMask

__all__ = ["QUALITY_KEYS", "ChecksConfig", "Reason", "SelfChecks", "contour_area_px2"]


@dataclass(frozen=True, slots=True)
class ChecksConfig:
    """Thresholds of the self-checks (the ``[pipeline.checks]`` table; docs/pipeline.md gives their reasoning).

    Parameters
    ----------
    enabled
        ``false`` reports every measured frame as OK (the quality record is still filled).
    length_tolerance
        Largest accepted |Lc / Lc0 - 1| of either shape (fraction of the length the first frames measured).
    length_mismatch
        Largest accepted difference of the two shapes' Lc / Lc0 in one split (the same rope at two instants).
    width_tolerance
        Largest accepted |w / w0 - 1| of the width the split used against the learned (or given) width.
    fixed_end_widths, fixed_end_floor_px
        A shape must start within ``fixed_end_widths`` x the rope width + ``fixed_end_floor_px`` of the fixed end;
        the same reach is ``tip_at_fixed_end``'s (a free tip that near the fixed end).
    tip_motion_factor, tip_motion_floor_px
        The tips' midpoint must lie within ``tip_motion_factor`` x the motion model's predicted error +
        ``tip_motion_floor_px`` of its prediction (checked once the model holds two frames).
    min_order_confidence
        Smallest accepted time-order confidence of a frame whose order is decided (0 disables the check).
    order_unknown_widths
        Largest tip separation, in rope widths, of a split of known exposure reported OK although nothing decided
        its time order (the first split of a stream, or after the order's history was dropped: confidence 0.5,
        the history left unordered);
        a wrong order puts each shape the tips' separation off (0: the check is off).
    no_blur_px
        Largest tip separation of a split reported from a frame of unknown exposure without evidence of blur (4 /
        `min_blur_evidence` px when that is larger: below it the contour's pixel noise, about a px^2 per px of
        length, is more than half the threshold, and the area is no evidence either way).
    min_blur_evidence
        Smallest ratio of the contour's area beyond the still rope's to the area the split's sweep implies that
        counts as evidence of blur (frames of unknown exposure only).
    tip_mask_widths, tip_mask_floor_px
        A free tip must end farther than ``tip_mask_widths`` x the rope width + ``tip_mask_floor_px`` before the
        static mask, along the rope (both 0: the check is off).
    min_band_area
        Smallest ratio of the contour's area to the still rope's (the begin shape's length x the learned width) with
        which a split of known exposure, whose area is measured, may be reported OK (0: the check is off).
    fallback_sweep_widths
        Largest sweep of the tip's path during the exposure, in rope widths, with which the blur split may fall
        back to one shape (the band's middle) and report it OK (0: the check is off).
    tip_kink_widths, tip_kink_deg
        Largest turn (degrees) of either shape's direction between the chord of its last ``tip_kink_widths`` rope
        widths and the chord of the same arc before them (``tip_kink_widths`` 0: the check is off).
    tip_corner_widths, tip_corner_floor_px
        Largest distance of a split's fitted tip from its segmentation point, ``tip_corner_widths`` x the rope
        width + ``tip_corner_floor_px``, on a frame of known exposure without a motion prediction; on every split,
        the two segmentation points no closer than half a rope width, or the tips no farther apart than the
        corners + a width (``tip_corner_widths`` 0: both checks are off).
    tip_short_widths, tip_short_floor_px
        Largest distance of one shape's free tip (the blur split's static fallback, frames of known exposure) from
        the contour's farthest point from the fixed end, ``tip_short_widths`` x the rope width +
        ``tip_short_floor_px`` (``tip_short_widths`` 0: the check is off).
    """

    enabled: bool = True
    length_tolerance: float = 0.15
    length_mismatch: float = 0.03
    width_tolerance: float = 0.5
    fixed_end_widths: float = 3.0
    fixed_end_floor_px: float = 6.0
    tip_motion_factor: float = 3.0
    tip_motion_floor_px: float = 4.0
    min_order_confidence: float = 0.0
    order_unknown_widths: float = 1.0
    no_blur_px: float = 2.0
    min_blur_evidence: float = 0.3
    tip_mask_widths: float = 1.0
    tip_mask_floor_px: float = 2.0
    fallback_sweep_widths: float = 1.5
    min_band_area: float = 0.25
    tip_kink_widths: float = 5.0
    tip_kink_deg: float = 15.0
    tip_corner_widths: float = 1.5
    tip_corner_floor_px: float = 2.0
    tip_short_widths: float = 1.0
    tip_short_floor_px: float = 2.0

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ConfigError(f"checks.enabled must be true or false, got {self.enabled!r}")
        check_range("checks.length_tolerance", self.length_tolerance, 0.01, 10.0)
        check_range("checks.length_mismatch", self.length_mismatch, 0.001, 10.0)
        check_range("checks.width_tolerance", self.width_tolerance, 0.01, 10.0)
        check_range("checks.fixed_end_widths", self.fixed_end_widths, 0.0, 1000.0)
        check_range("checks.fixed_end_floor_px", self.fixed_end_floor_px, 0.0, 10_000.0)
        check_range("checks.tip_motion_factor", self.tip_motion_factor, 0.5, 1000.0)
        check_range("checks.tip_motion_floor_px", self.tip_motion_floor_px, 0.0, 10_000.0)
        check_range("checks.min_order_confidence", self.min_order_confidence, 0.0, 1.0)
        check_range("checks.order_unknown_widths", self.order_unknown_widths, 0.0, 100.0)
        check_range("checks.no_blur_px", self.no_blur_px, 0.0, 10_000.0)
        check_range("checks.min_blur_evidence", self.min_blur_evidence, 0.0, 100.0)
        check_range("checks.tip_mask_widths", self.tip_mask_widths, 0.0, 100.0)
        check_range("checks.tip_mask_floor_px", self.tip_mask_floor_px, 0.0, 100.0)
        check_range("checks.fallback_sweep_widths", self.fallback_sweep_widths, 0.0, 100.0)
        check_range("checks.min_band_area", self.min_band_area, 0.0, 1.0)
        check_range("checks.tip_kink_widths", self.tip_kink_widths, 0.0, 100.0)
        check_range("checks.tip_kink_deg", self.tip_kink_deg, 0.0, 180.0)
        check_range("checks.tip_corner_widths", self.tip_corner_widths, 0.0, 100.0)
        check_range("checks.tip_corner_floor_px", self.tip_corner_floor_px, 0.0, 100.0)
        check_range("checks.tip_short_widths", self.tip_short_widths, 0.0, 100.0)
        check_range("checks.tip_short_floor_px", self.tip_short_floor_px, 0.0, 100.0)


_MESSAGES = {
    Reason.LENGTH: "the rope's length is implausible (length_ratio off Lc0 by more than checks.length_tolerance, "
    "or the two shapes' lengths apart by more than checks.length_mismatch)",
    Reason.WIDTH: "the rope's width is implausible (width_ratio off the learned width by more than "
    "checks.width_tolerance)",
    Reason.FIXED_END: "a shape does not start at the fixed end (fixed_end_px beyond checks.fixed_end_widths)",
    Reason.TIP_MOTION: "the tips are not where the motion model predicted them (tip_motion_px beyond "
    "tip_motion_limit_px)",
    Reason.ORDER: "the time order is not certain enough (order_confidence below checks.min_order_confidence), or "
    "nothing decided it (no earlier frame to go by) while the tips lie more than checks.order_unknown_widths rope "
    "widths apart: either shape may be the start of the exposure",
    Reason.NO_BLUR: "no blur to split (no exposure time, or no motion prediction yet to check the split against, "
    "and the contour's area shows too little blur for the tips' separation): the static centreline is given instead",
    Reason.TIP_MASKED: "a free tip ends at the static mask, which may hide the rope's end (within "
    "checks.tip_mask_widths rope widths + checks.tip_mask_floor_px of it)",
    Reason.FALLBACK_SWEEP: "one shape (the band's middle) while the tip's path swept more than "
    "checks.fallback_sweep_widths rope widths during the exposure: neither the start nor the end of the exposure",
    Reason.TIP_KINK: "a shape turns by more than checks.tip_kink_deg within checks.tip_kink_widths rope widths of its "
    "free tip, where a rope runs straight: the tip ran on beyond the rope's end",
    Reason.TIP_AT_FIXED_END: "a shape's free tip lies at the fixed end (within checks.fixed_end_widths rope widths + "
    "checks.fixed_end_floor_px): it ran out along the rope and back (round a clamp's outline)",
    Reason.TIP_CORNER: "a split's tip lies farther than checks.tip_corner_widths rope widths + "
    "checks.tip_corner_floor_px from the band's corner it was read at, or the band's two corners lie within half a "
    "rope width of each other (one corner found twice) while the tips lie farther apart: the tips were not read at "
    "the band's corners",
    Reason.TIP_SHORT: "one shape's free tip ends farther than checks.tip_short_widths rope widths + "
    "checks.tip_short_floor_px short of the contour's far end: it was read inside the band, not at the rope's end",
    Reason.FIXED_END_GUESS: "the rope moves and its fixed end is still a guess on the outline (not given, held by no "
    "structure, no end yet seen staying while the other moved): the shapes may run from the free tip",
}


class SelfChecks:
    """The self-checks of one pipeline: `predict` before a frame is measured, `check` after.

    Parameters
    ----------
    config
        The thresholds.
    fallback_single
        A single shape is the blur split's fallback (``method = "blur_split"``), checked with
        ``fallback_sweep``; False: one shape is what the method gives (``centerline``, ``static``), never checked so.

    Attributes
    ----------
    quality
        The last checked frame's measures (`QUALITY_KEYS`; one dict reused, valid until the next `check`).
    buffers
        (predicted, thresholds, measures): the arrays `predict_tips` and `check_frame` read and write (the
        pipeline's `steady_frame` makes both calls with them; the thresholds' memory is writable, the checks pass
        a read-only view of it).
    """

    __slots__ = (
        "_carry", "_measure_cells", "_measures", "_predicted", "_settled_frames", "_swept",
        "_thresholds", "buffers", "checks_sweep", "config", "quality",
    )  # fmt: skip

    def __init__(self, config: ChecksConfig, fallback_single: bool = True) -> None:
        self.config = config
        self.quality: dict[str, float] = {}
        self._predicted = np.full(4, math.nan)
        """The tips' predicted midpoint (row, col), the prediction's error (px) and the tip's sweep along its path
        (px); nan error: no prediction."""
        thresholds = np.zeros(1, K.CHECK_THRESHOLDS)
        for name in K.CHECK_THRESHOLDS.names:
            thresholds[0][name] = getattr(config, name)
        if not fallback_single:  # one shape is the method's answer, not a fallback
            thresholds[0]["fallback_sweep_widths"] = 0.0
            thresholds[0]["tip_short_widths"] = 0.0
        self._thresholds = ro(thresholds)
        self._measures = np.zeros(1, K.CHECK_QUALITY)
        """The last checked frame's measures, by name (`check_frame` writes them; `quality` holds a copy)."""
        self._measure_cells = memoryview(self._measures.view(np.float64))  # the same, cell by cell (`verdict`)
        self._settled_frames = 0
        self.checks_sweep = float(thresholds[0]["fallback_sweep_widths"]) > 0.0
        """Whether ``fallback_sweep`` is checked (its threshold above 0: a one shape that is a fallback)."""
        self._swept = False
        """This frame failed ``fallback_sweep`` on its own prediction (not carried over, `verdict`)."""
        self._carry = False
        """The frame before this one did (`due` moves `_swept` here at each frame's start)."""
        self.buffers = (self._predicted, thresholds, self._measures)

    @staticmethod
    def message(reason: Reason) -> str:
        """Return the human-readable message of a failed check."""
        return _MESSAGES[reason]

    def predict(
        self, motion_state: NDArray[np.int64], motion_log: NDArray[np.float64], fixed: NDArray[np.float32],
        t_ns: int, exposure_ns: int, settled: bool = True,
    ) -> None:  # fmt: skip
        """Keep where the motion model (its `state` and `log`) puts the tips' midpoint in the frame exposed from
        `t_ns` for `exposure_ns` (about the fixed end (row, col)).

        Nothing while the fixed end is not `settled` or the model holds fewer than two frames measured after it
        settled: the model's history is relative to the fixed end of its time, which may have moved since.
        """
        if self.due(settled):
            K.predict_tips(t_ns, exposure_ns, motion_state, motion_log, fixed, self._predicted)

    def due(self, settled: bool = True) -> bool:
        """`predict`'s first half: count the frames since the fixed end `settled`; False (and no prediction) while
        the model cannot hold two frames measured after it, True when `predict_tips` is to be called (the caller
        then makes the call into ``buffers[0]``: `predict`, or the pipeline's `steady_frame`)."""
        self._carry, self._swept = self._swept, False  # a new frame: "right after" is this one only
        if not settled:
            self._settled_frames = 0
        elif self._settled_frames <= 2:  # counted to 3 only: a count past 256 would be a new int object per frame
            self._settled_frames += 1
        if self._settled_frames <= 2:
            self._predicted[2] = math.nan
            self._predicted[3] = math.nan
            return False
        return True

    def needs_area(self, exposure_ns: int) -> bool:
        """True when a split needs the contour's area as evidence of blur: its exposure is unknown, or the motion
        model has no prediction to check its tips against (the first frames, a gap)."""
        return exposure_ns <= 0 or math.isnan(self._predicted[2])

    def forget(self) -> None:
        """Drop the prediction (the motion model was cleared)."""
        self._predicted[2] = math.nan
        self._predicted[3] = math.nan

    def restart(self) -> None:
        """Forget the last frames' verdicts too (the pipeline's tracking was reset): nothing is carried."""
        self.forget()
        self._swept = self._carry = False

    def check(
        self,
        begin: NDArray[np.float32],
        end: NDArray[np.float32],
        fixed: NDArray[np.float32],
        stretch_begin: float | None,
        stretch_end: float | None,
        width_px: float,
        learned_width_px: float | None,
        order_confidence: float,
        exposure_ns: int,
        split: bool,
        contour_area_px2: float = math.nan,
        mask: NDArray[np.uint8] | None = None,
        corner_px: float = math.nan,
        corners: NDArray[np.float32] | None = None,
        order_undecided: bool = False,
        static: StaticMask | None = None,
        frame: NDArray[np.uint8] | None = None,
    ) -> tuple[FrameStatus, Reason]:
        """Check one measured frame; return its status (OK when every check passes) and the first failed reason.

        Parameters
        ----------
        begin, end
            The shapes (row, col) float32, fixed end first.
        fixed
            The fixed end (row, col).
        stretch_begin, stretch_end
            Lc / Lc0 of each shape (None: Lc0 not known yet).
        width_px
            The width the split used; `learned_width_px` the learned or given one (None: not known yet).
        order_confidence
            The time order's confidence.
        exposure_ns
            The frame's exposure (0: unknown).
        split
            True when the method gave two shapes (a blur split), False for one centreline.
        contour_area_px2
            Area the rope's contour encloses (`contour_area_px2`; needed only for a split of unknown exposure:
            nan counts as no evidence of blur).
        mask
            The static mask (uint8, the image's shape, read-only; `MASK_FREE` where edges are kept; None: no
            mask), for ``tip_masked``.
        corner_px
            How far the split's fitted tips lie from its segmentation points (`tip_corner_px`, measured on the
            split's own tips, before the tracking may move them along the sweep), for ``tip_corner`` (nan: not
            checked).
        corners
            The split's segmentation points (2, 2) float32 (row, col), for ``tip_corner``'s coinciding corners; for
            one shape (`split` False) the contour's farthest point from the fixed end (1, 2: `K.contour_far_end`),
            for ``tip_short`` (None: not known, not checked).
        order_undecided
            Nothing decided the split's time order (no earlier frame in the order's history: `K.order_shapes`
            kept the split's own pairing and left the history unordered), for ``order``.
        static, frame
            The learned static mask and the frame (its shape, uint8 in linear light): a ``tip_masked`` verdict is
            withdrawn (the checks made again without the mask) when the frame shows both tips as the rope's ends
            (`StaticMask.shows_end`: the rope at each tip, the learned still scene beyond it). None: it stands.
        """
        code = K.check_frame(
            begin, end, fixed, self._predicted, _nan_if_none(stretch_begin), _nan_if_none(stretch_end), width_px,
            learned_width_px or 0.0, order_confidence, exposure_ns, split, contour_area_px2,
            _NO_MASK if mask is None else mask, _NO_CORNERS if corners is None else corners, self._thresholds,
            self._measures,
        )  # fmt: skip
        if code == K.CHECK_TIP_MASKED and static is not None and frame is not None:
            # A tip at the mask is the mask's doing only where the rope goes on under it: where the frame shows the
            # rope at both tips and the still scene it learned beyond them, nothing is hidden (simulated texture,
            # dust and scratches rows: the mask covers the plate's grain and specks, not the rope's end).
            width = learned_width_px or width_px
            reach_px = self.config.tip_mask_widths * width + self.config.tip_mask_floor_px
            if static.shows_end(begin, frame, width, reach_px) and static.shows_end(end, frame, width, reach_px):
                code = K.check_frame(
                    begin, end, fixed, self._predicted, _nan_if_none(stretch_begin), _nan_if_none(stretch_end),
                    width_px, learned_width_px or 0.0, order_confidence, exposure_ns, split, contour_area_px2,
                    _NO_MASK, _NO_CORNERS if corners is None else corners, self._thresholds, self._measures,
                )  # fmt: skip
        if (code == K.CHECK_NONE or code == K.CHECK_TIP_SHORT) and exposure_ns > 0 and math.isnan(self._predicted[2]):
            # Checks of a frame the motion model cannot check (the first frames, after a gap); a steady frame's
            # tips are checked against the prediction instead (`check_frame`, inside `steady_frame`). ``tip_short``
            # is the last check: a frame fails it only when it passes these too.
            code = (
                self._unpredicted(
                    begin, end, fixed, learned_width_px or width_px, split, contour_area_px2, corner_px,
                    order_undecided,
                )
                or code
            )  # fmt: skip
        return self.verdict(code)

    def _unpredicted(
        self,
        begin: NDArray[np.float32],
        end: NDArray[np.float32],
        fixed: NDArray[np.float32],
        width: float,
        split: bool,
        contour_area_px2: float,
        corner_px: float,
        order_undecided: bool,
    ) -> int:
        """The code of the first failed check among ``width`` (the band's area), ``tip_at_fixed_end``,
        ``tip_corner`` and ``order`` (a time order nothing decided) on a frame of known exposure without a motion
        prediction (`K.CHECK_NONE`: all passed)."""
        config = self.config
        if (
            split
            and math.isfinite(self._measures[0]["blur_evidence"])
            and contour_area_px2 < config.min_band_area * _length_px(begin) * width
        ):
            return int(Reason.WIDTH)
        reach_px = config.fixed_end_widths * width + config.fixed_end_floor_px
        for shape in (begin, end) if split else (begin,):
            tip_px = math.hypot(float(shape[-1, 0]) - float(fixed[0]), float(shape[-1, 1]) - float(fixed[1]))
            if tip_px <= reach_px and _length_px(shape) > 2.0 * reach_px:
                return int(Reason.TIP_AT_FIXED_END)
        corner_limit_px = config.tip_corner_widths * width + config.tip_corner_floor_px
        if split and config.tip_corner_widths > 0.0 and corner_px > corner_limit_px:  # False for nan
            return int(Reason.TIP_CORNER)
        # Without an earlier frame in the order's history (`order_shapes` then keeps the split's own pairing, with
        # confidence 0.5) the pairing of shapes and instants is a coin flip; a wrong one puts each shape the tips'
        # separation off (simulated `lab late swing`, tuning seed, frame 0: a stream that starts mid-swing, tips
        # 7.4 px apart, both shapes swapped). After still frames the history is ordered (their tips, and nearness
        # to the last one), even where the confidence is 0.5.
        if (
            split
            and order_undecided
            and config.order_unknown_widths > 0.0
            and self._measures[0]["tip_separation_px"] > config.order_unknown_widths * width
        ):
            return int(Reason.ORDER)
        return K.CHECK_NONE

    def verdict(self, code: int) -> tuple[FrameStatus, Reason]:
        """The status and reason of `check_frame`'s `code` (its measures are in ``buffers[2]``, which go into
        `quality`): `check`'s last step, for a `check_frame` call made elsewhere (the pipeline's `steady_frame`)."""
        _set_quality(self.quality, self._measure_cells)
        # A one-shape frame right after one that failed `fallback_sweep` has no prediction to check its sweep
        # against (that failure cleared the motion model): the tip swept a frame ago, so it fails too (once: a rope
        # coming to rest must be reported again). ``tip_short`` is the last check: a frame that failed only it
        # passed every other one, so the carried failure takes its place (it clears the motion model again).
        carried = (
            (code == K.CHECK_NONE or code == K.CHECK_TIP_SHORT)
            and self._carry
            and self.checks_sweep
            and self.quality[_Q3] == 0.0
            and math.isnan(self._predicted[2])
        )
        if carried:
            code = K.CHECK_FALLBACK_SWEEP
        self._swept = code == K.CHECK_FALLBACK_SWEEP and not carried
        if code == K.CHECK_NONE or not self.config.enabled:
            return _PASSED
        failed = Reason(code)
        return (FrameStatus.NO_BLUR if failed is Reason.NO_BLUR else FrameStatus.IMPLAUSIBLE), failed


_Q0, _Q1, _Q2, _Q3, _Q4, _Q5, _Q6 = QUALITY_KEYS  # `_set_quality`'s keys (seven: `CHECK_QUALITY`'s fields)
_PASSED = (FrameStatus.OK, Reason.NONE)
"""`verdict`'s answer when every check passed, made once: reading an attribute of an Enum class costs Python 3.11 a
48-byte method-wrapper each time (its metaclass has a `__getattr__`), a Python allocation per frame."""


def _set_quality(quality: dict[str, float], values: memoryview) -> None:
    """Set the measures `values` (float64 cells in `QUALITY_KEYS` order) into `quality` without making an object: no
    iterator, no list, no NumPy scalar (a frame then replaces the floats of the dict's keys)."""
    quality[_Q0] = values[0]
    quality[_Q1] = values[1]
    quality[_Q2] = values[2]
    quality[_Q3] = values[3]
    quality[_Q4] = values[4]
    quality[_Q5] = values[5]
    quality[_Q6] = values[6]


_NO_MASK = np.zeros((1, 1), np.uint8)
"""A mask with nothing masked (`check_frame` reads pixels outside a mask as free)."""
_NO_MASK.flags.writeable = False
_NO_CORNERS = np.zeros((0, 2), np.float32)
"""No segmentation points (`check_frame` then skips ``tip_corner``'s coinciding corners)."""
_NO_CORNERS.flags.writeable = False


def _length_px(shape: NDArray[np.float32]) -> float:
    """Return the length (px) of the polyline `shape` (row, col)."""
    steps = np.diff(shape.astype(np.float64), axis=0)
    return float(np.hypot(steps[:, 0], steps[:, 1]).sum())


def tip_corner_px(begin: NDArray[np.float32], end: NDArray[np.float32], corners: NDArray[np.float32]) -> float:
    """The larger distance of the two free tips from the segmentation points `corners` (2, 2), each tip paired
    with a corner the way that makes the larger distance smaller (the split does not say which corner is which
    instant's)."""
    tb = begin[-1].astype(np.float64)
    te = end[-1].astype(np.float64)
    c0 = corners[0].astype(np.float64)
    c1 = corners[1].astype(np.float64)

    def gap(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
        return math.hypot(float(a[0] - b[0]), float(a[1] - b[1]))

    return min(max(gap(tb, c0), gap(te, c1)), max(gap(tb, c1), gap(te, c0)))


def folds_back(shape: NDArray[np.float32], width_px: float | None) -> bool:
    """Whether the polyline `shape` ((n, 2) row, col, fixed end first) runs out and back along itself or crosses
    itself: one of its points lies within 2 rope widths + 2 px (`width_px`, 3 px when unknown) of a point more than
    6 widths + 10 px before it along it. A rope's centreline does not lie on itself; an outline walked out and back
    along one of its sides (a side lost to noise) gives such a centreline at its tip, and an outline whose sides
    broke into loops (the faint band of simulated lab-hard on a fresh device, tuning seed, frame 20: a centreline
    crossing itself twice, OK with its tip 200 px short) gives one along the way. O(n^2): 1.7 ms for 270 points,
    7 ms for 650 (a loaded machine); `Pipeline` calls it only before Lc0 is known."""
    if len(shape) < 3:
        return False
    width = width_px if width_px is not None and math.isfinite(width_px) and width_px > 0 else 3.0
    steps = np.hypot(np.diff(shape[:, 0]), np.diff(shape[:, 1]))
    arc = np.concatenate(([0.0], np.cumsum(steps, dtype=np.float64)))
    first = np.searchsorted(arc, arc - (6.0 * width + 10.0))  # the points before first[i] lie that far before i
    later = np.flatnonzero(first > 0)
    if len(later) == 0:
        return False
    tail, head = shape[later], shape[: first[-1]]
    d_row = tail[:, None, 0] - head[None, :, 0]
    d_col = tail[:, None, 1] - head[None, :, 1]
    squared = d_row * d_row + d_col * d_col
    squared[np.arange(len(head))[None, :] >= first[later][:, None]] = np.inf  # not far enough before
    return bool(squared.min() <= (2.0 * width + 2.0) ** 2)


def _nan_if_none(value: float | None) -> float:
    return math.nan if value is None else float(value)


def contour_area_px2(points: NDArray[np.float32], n: int) -> float:
    """Return the area (px^2) the closed contour of the first `n` points (row, col) encloses (shoelace formula)."""
    if n < 3:
        return 0.0
    r = points[:n, 0].astype(np.float64)
    c = points[:n, 1].astype(np.float64)
    return 0.5 * abs(float(np.dot(r, np.roll(c, -1)) - np.dot(c, np.roll(r, -1))))
