"""MotionModel: where the rope's free end will be in the next frame (it places the region of interest)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import ro
from ropecam.device.pipeline.workspace import NEED_BINS, MotionBuffers, expose

__all__ = ["NEED_BINS", "MotionModel"]

NEED_GAIN = 1.5
"""The next frame's uncertainty cap is NEED_GAIN x the largest error measured over the last two frames (in the
bin and its neighbours) plus NEED_FLOOR_PX + NEED_MOTION_SHARE x the step-scaled uncertainty."""
NEED_FLOOR_PX = 1.5
NEED_MOTION_SHARE = 0.04
"""The floor also grows by this share of the frame's step-scaled uncertainty (`predict`'s, px): a frame of a larger
step is predicted less well (rig, 119 FPS: ~12 px, floor ~2; paper, 30 FPS: 20-29 px, floor ~2.5-2.7)."""


@expose("buffers", MotionBuffers)
class MotionModel:
    """The free end's recent positions, which predict where the rope is in the next frame (the ROI).

    Holds the midpoint of the two tips (independent of the time order) at mid-exposure of up to three
    consecutive measured frames, as log-polar coordinates about the fixed end (log radius, unwrapped angle), the
    last tip sweep and exposure, in the arrays of the kernels `observe_motion` and `predict_motion`, and the band
    prediction's measured error (`need`, `profile`) with what it is measured against (`band`, `owed`), which the
    pipeline's `band_stage` call updates. Cleared after a frame without shapes.
    """

    __slots__ = ("buffers", "need_args", "owed", "profile_ro", "state_ro")

    def __init__(self, buffers: MotionBuffers | None = None) -> None:
        self.buffers = buffers if buffers is not None else MotionBuffers.make()
        """(each also a read-only attribute) ``state``: mid-exposure times (ns), then [frames held, last exposure
        ns] (`K.MOTION_COUNT`, `K.MOTION_EXPOSURE`); ``log``: log-polar tip midpoints (log radius, angle) per
        frame, then (last tip sweep px, unused); ``need``: the band prediction's error beyond the margin (px) per
        bin of the distance from the fixed end, this frame's and the last one's (`need_profile`, in `band_stage`);
        ``profile``: cap on the next band's uncertainty per bin (px; inf: none yet), `spans_around_chain`'s
        profile; ``band``: what the last band was built with, for measuring its error on the next call
        (`band_stage`'s state)."""
        self.state_ro = ro(self.state)
        self.profile_ro = ro(self.profile)
        self.owed = False
        """The last frame was found in the band `band_stage` built last: the next call measures its error."""
        self.need_args = (NEED_GAIN, NEED_FLOOR_PX, NEED_MOTION_SHARE)
        """`band_stage`'s gain, floor (px) and floor share of the uncertainty: the module's constants as they are
        when the model is made (tests patch them)."""

    def clear(self) -> None:
        """Forget everything (a gap in the measurements)."""
        self.state[K.MOTION_COUNT] = 0
        self.state[K.MOTION_EXPOSURE] = 0
        self.log[K.MOTION_FRAMES, 0] = 0.0
        self.forget_need()

    def forget_need(self) -> None:
        """Forget the band prediction's measured error (a frame not found in its predicted band): no cap."""
        self.need.fill(0.0)
        self.profile.fill(np.inf)
        self.owed = False

    @property
    def frames(self) -> int:
        """Measured frames held (0-3)."""
        return int(self.state[K.MOTION_COUNT])

    @property
    def sweep_px(self) -> float:
        """The last frame's tip sweep (px)."""
        return float(self.log[K.MOTION_FRAMES, 0])

    def observe(
        self,
        begin: NDArray[np.float32],
        end: NDArray[np.float32],
        fixed: NDArray[np.float32],
        t_mid_ns: int,
        sweep_px: float,
        exposure_ns: int,
    ) -> None:
        """Add a measured frame: its two shapes (float32 (n, 2), tip last), the fixed end (row, col) float32
        (2,), the mid-exposure time (ns), the split's tip sweep (px; the distance between the tips when larger)
        and the exposure (ns, 0 = unknown).

        Raises
        ------
        ValueError
            When a shape has no point.
        """
        try:
            held = K.observe_motion(begin, end, fixed, t_mid_ns, sweep_px, exposure_ns, self.state, self.log)
        except TypeError:  # not the splitter's writable float32 buffers: copies
            held = K.observe_motion(
                np.array(begin, np.float32), np.array(end, np.float32), np.array(fixed, np.float32), int(t_mid_ns),
                float(sweep_px), int(exposure_ns), self.state, self.log,
            )  # fmt: skip
        if held < 0:
            raise ValueError(f"cannot observe the motion of shapes of {len(begin)} and {len(end)} points")

    def predict(self, t_ns: int, exposure_ns: int) -> tuple[float, float, float]:
        """Return the predicted motion of the rope from the last measured frame to the frame starting at `t_ns`
        (exposure `exposure_ns`) as the complex factor (real, imaginary) that rotates and scales points about the
        fixed end, and the uncertainty of the free end's position (px) (`predict_motion`).

        With one measured frame the direction is unknown: no motion, an uncertainty of 1.3 x the last sweep
        scaled from the exposure to the time gap, plus a pixel. With two, a constant angular and radial velocity
        (uncertainty half the predicted step); with three, a constant acceleration (uncertainty 0.3 x the step
        plus the acceleration term); both plus a quarter of the sweep and 2 px. (The tip itself is predicted to
        1-5 px on the simulated rigs; the margin is for the rest of a bending rope.)
        """
        return K.predict_motion(t_ns, exposure_ns, self.state, self.log)
