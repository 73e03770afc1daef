"""SelfChecks: turn an implausible answer into a status with a reason instead of OK.

A frame the pipeline measured is compared with what the first frames taught it and with what the motion model
predicted, using scalars the pipeline has already computed (no per-frame allocation beyond the result):

======================  ==============================================================================  ===========
reason                  fails when                                                                      status
======================  ==============================================================================  ===========
``length``              a shape's length Lc differs from Lc0 (the median of the first shapes) by more   IMPLAUSIBLE
                        than ``length_tolerance`` (a fraction of Lc0)
``width``               the width the split used differs from the learned width by more than            IMPLAUSIBLE
                        ``width_tolerance`` (a fraction of it)
``fixed_end``           a shape starts farther from the learned or given fixed end than                  IMPLAUSIBLE
                        ``fixed_end_widths`` rope widths plus ``fixed_end_floor_px``
``tip_motion``          the tips' midpoint lies farther from where the motion model predicted it than    IMPLAUSIBLE
                        ``tip_motion_factor`` x the model's own predicted error plus ``tip_motion_floor_px``
``order``               the time order is decided (known exposure, two shapes) with a confidence below   IMPLAUSIBLE
                        ``min_order_confidence``
``no_blur``             a split's tips lie more than ``no_blur_px`` (and 4 / ``min_blur_evidence``) px   NO_BLUR
                        apart without
                        evidence of blur: the
                        exposure is unknown (0: a still photo, a video) and the area the contour
                        encloses beyond the still rope's (length x width) is less than
                        ``min_blur_evidence`` x the area the split's sweep implies (0.5 x length x tip
                        separation, the rope turning about its fixed end); the frame then carries the
                        static centreline instead of the split
======================  ==============================================================================  ===========

Each check's measure goes into the frame's quality record (`QUALITY_KEYS`), whether it passes or not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.shared.config import check_range
from ropecam.shared.errors import ConfigError
from ropecam.shared.protocol.frame_result import FrameStatus
from ropecam.shared.protocol.quality import QUALITY_KEYS, Reason

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
    width_tolerance
        Largest accepted |w / w0 - 1| of the width the split used against the learned (or given) width.
    fixed_end_widths, fixed_end_floor_px
        A shape must start within ``fixed_end_widths`` x the rope width + ``fixed_end_floor_px`` of the fixed end.
    tip_motion_factor, tip_motion_floor_px
        The tips' midpoint must lie within ``tip_motion_factor`` x the motion model's predicted error +
        ``tip_motion_floor_px`` of its prediction (checked once the model holds two frames).
    min_order_confidence
        Smallest accepted time-order confidence of a frame whose order is decided (0 disables the check).
    no_blur_px
        Largest tip separation of a split reported from a frame of unknown exposure without evidence of blur (4 /
        `min_blur_evidence` px when that is larger: below it the contour's pixel noise, about a px^2 per px of
        length, is more than half the threshold, and the area is no evidence either way).
    min_blur_evidence
        Smallest ratio of the contour's area beyond the still rope's to the area the split's sweep implies that
        counts as evidence of blur (frames of unknown exposure only).
    """

    enabled: bool = True
    length_tolerance: float = 0.25
    width_tolerance: float = 0.5
    fixed_end_widths: float = 3.0
    fixed_end_floor_px: float = 6.0
    tip_motion_factor: float = 3.0
    tip_motion_floor_px: float = 4.0
    min_order_confidence: float = 0.0
    no_blur_px: float = 2.0
    min_blur_evidence: float = 0.3

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ConfigError(f"checks.enabled must be true or false, got {self.enabled!r}")
        check_range("checks.length_tolerance", self.length_tolerance, 0.01, 10.0)
        check_range("checks.width_tolerance", self.width_tolerance, 0.01, 10.0)
        check_range("checks.fixed_end_widths", self.fixed_end_widths, 0.0, 1000.0)
        check_range("checks.fixed_end_floor_px", self.fixed_end_floor_px, 0.0, 10_000.0)
        check_range("checks.tip_motion_factor", self.tip_motion_factor, 0.5, 1000.0)
        check_range("checks.tip_motion_floor_px", self.tip_motion_floor_px, 0.0, 10_000.0)
        check_range("checks.min_order_confidence", self.min_order_confidence, 0.0, 1.0)
        check_range("checks.no_blur_px", self.no_blur_px, 0.0, 10_000.0)
        check_range("checks.min_blur_evidence", self.min_blur_evidence, 0.0, 100.0)


_MESSAGES = {
    Reason.LENGTH: "the rope's length is implausible (length_ratio off Lc0 by more than checks.length_tolerance)",
    Reason.WIDTH: "the rope's width is implausible (width_ratio off the learned width by more than "
    "checks.width_tolerance)",
    Reason.FIXED_END: "a shape does not start at the fixed end (fixed_end_px beyond checks.fixed_end_widths)",
    Reason.TIP_MOTION: "the tips are not where the motion model predicted them (tip_motion_px beyond "
    "tip_motion_limit_px)",
    Reason.ORDER: "the time order is not certain enough (order_confidence below checks.min_order_confidence)",
    Reason.NO_BLUR: "no blur to split (no exposure time): the static centreline is given instead",
}


class SelfChecks:
    """The self-checks of one pipeline: `predict` before a frame is measured, `check` after.

    Parameters
    ----------
    config
        The thresholds.

    Attributes
    ----------
    quality
        The last checked frame's measures (`QUALITY_KEYS`; one dict reused, valid until the next `check`).
    """

    __slots__ = ("_predicted", "_settled_frames", "config", "quality")

    def __init__(self, config: ChecksConfig) -> None:
        self.config = config
        self.quality: dict[str, float] = {}
        self._predicted = np.full(3, math.nan)
        """The tips' predicted midpoint (row, col) and the prediction's error (px); nan: no prediction."""
        self._settled_frames = 0

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
        count = int(motion_state[K.MOTION_COUNT])
        predicted = self._predicted
        self._settled_frames = self._settled_frames + 1 if settled else 0
        if count < 2 or self._settled_frames <= 2:
            predicted[2] = math.nan
            return
        f_re, f_im, error_px = K.predict_motion(t_ns, exposure_ns, motion_state, motion_log)
        radius = math.exp(motion_log[count - 1, 0])
        angle = motion_log[count - 1, 1]
        z_re, z_im = radius * math.cos(angle), radius * math.sin(angle)
        predicted[0] = fixed[0] + f_re * z_re - f_im * z_im
        predicted[1] = fixed[1] + f_re * z_im + f_im * z_re
        predicted[2] = error_px

    def needs_area(self, exposure_ns: int) -> bool:
        """True when a split needs the contour's area as evidence of blur: its exposure is unknown, or the motion
        model has no prediction to check its tips against (the first frames, a gap)."""
        return exposure_ns <= 0 or math.isnan(self._predicted[2])

    def forget(self) -> None:
        """Drop the prediction (the motion model was cleared)."""
        self._predicted[2] = math.nan

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
        """
        c = self.config
        q = self.quality
        failed = Reason.NONE
        length_ratio = math.nan
        for stretch in (stretch_begin, stretch_end):
            if stretch is not None and math.isfinite(stretch) and not abs(stretch - 1.0) <= abs(length_ratio - 1.0):
                length_ratio = stretch
        q["length_ratio"] = length_ratio
        if abs(length_ratio - 1.0) > c.length_tolerance:
            failed = Reason.LENGTH
        width_ratio = width_px / learned_width_px if learned_width_px else math.nan
        q["width_ratio"] = width_ratio
        if failed is Reason.NONE and abs(width_ratio - 1.0) > c.width_tolerance:
            failed = Reason.WIDTH
        fr, fc = float(fixed[0]), float(fixed[1])
        offset = max(
            math.hypot(float(begin[0, 0]) - fr, float(begin[0, 1]) - fc),
            math.hypot(float(end[0, 0]) - fr, float(end[0, 1]) - fc),
        )
        q["fixed_end_px"] = offset
        width = learned_width_px or width_px
        if failed is Reason.NONE and offset > c.fixed_end_widths * width + c.fixed_end_floor_px:
            failed = Reason.FIXED_END
        br, bc, er, ec = float(begin[-1, 0]), float(begin[-1, 1]), float(end[-1, 0]), float(end[-1, 1])
        separation = math.hypot(er - br, ec - bc)
        q["tip_separation_px"] = separation
        predicted = self._predicted
        motion_px = limit_px = math.nan
        if not math.isnan(predicted[2]):
            motion_px = math.hypot(0.5 * (br + er) - predicted[0], 0.5 * (bc + ec) - predicted[1])
            limit_px = c.tip_motion_factor * predicted[2] + c.tip_motion_floor_px
        q["tip_motion_px"] = motion_px
        q["tip_motion_limit_px"] = limit_px
        if failed is Reason.NONE and motion_px > limit_px:
            failed = Reason.TIP_MOTION
        if failed is Reason.NONE and split and exposure_ns > 0 and order_confidence < c.min_order_confidence:
            failed = Reason.ORDER
        evidence = math.nan
        unchecked = split and self.needs_area(exposure_ns)
        if unchecked:
            length_px = _length_px(begin)
            evidence = (contour_area_px2 - length_px * width) / max(0.5 * length_px * separation, 1.0)
        q["blur_evidence"] = evidence
        # The pixel contour's area is uncertain by ~ half a pixel along both sides (~ length px^2), which is
        # 2 / separation of the implied sweep area: a verdict only where that is below half the threshold.
        limit_px = max(c.no_blur_px, 4.0 / c.min_blur_evidence) if c.min_blur_evidence > 0 else c.no_blur_px
        if unchecked and separation > limit_px and not evidence >= c.min_blur_evidence:
            failed = Reason.NO_BLUR  # before the others: the pipeline replaces the split by the static centreline
        if failed is Reason.NONE or not c.enabled:
            return FrameStatus.OK, Reason.NONE
        return (FrameStatus.NO_BLUR if failed is Reason.NO_BLUR else FrameStatus.IMPLAUSIBLE), failed


def _length_px(shape: NDArray[np.float32]) -> float:
    """Length of a polyline (row, col) in px."""
    steps = np.diff(shape.astype(np.float64), axis=0)
    return float(np.hypot(steps[:, 0], steps[:, 1]).sum())


def contour_area_px2(points: NDArray[np.float32], n: int) -> float:
    """Return the area (px^2) the closed contour of the first `n` points (row, col) encloses (shoelace formula)."""
    if n < 3:
        return 0.0
    r = points[:n, 0].astype(np.float64)
    c = points[:n, 1].astype(np.float64)
    return 0.5 * abs(float(np.dot(r, np.roll(c, -1)) - np.dot(c, np.roll(r, -1))))
