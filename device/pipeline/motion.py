"""MotionModel: where the rope's free end will be in the next frame (it places the region of interest)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K

__all__ = ["MotionModel"]


class MotionModel:
    """The free end's recent positions, which predict where the rope is in the next frame (the ROI).

    Holds the midpoint of the two tips (independent of the time order) at mid-exposure of up to three
    consecutive measured frames, as log-polar coordinates about the fixed end (log radius, unwrapped angle), the
    last tip sweep and exposure, in arrays for the kernels `observe_motion` and `predict_motion`. Cleared after a
    frame without shapes.
    """

    __slots__ = ("_out", "log", "state", "sweep", "times_ns")

    def __init__(self) -> None:
        self.times_ns = np.zeros(K.MOTION_FRAMES, np.int64)
        self.log = np.zeros((K.MOTION_FRAMES, 2), np.float64)
        self.state = np.zeros(2, np.int64)  # frames held, exposure (ns)
        self.sweep = np.zeros(1, np.float64)
        self._out = np.zeros(3, np.float64)

    def clear(self) -> None:
        """Forget everything (a gap in the measurements)."""
        self.state[0] = 0
        self.state[1] = 0
        self.sweep[0] = 0.0

    @property
    def frames(self) -> int:
        """Measured frames held (0-3)."""
        return int(self.state[0])

    def observe(
        self,
        begin: NDArray[np.float32],
        end: NDArray[np.float32],
        fixed: NDArray[np.float32],
        t_mid_ns: int,
        sweep_px: float,
        exposure_ns: int,
    ) -> None:
        """Add a measured frame: its two shapes (tip last; float32 (n, 2)), the fixed
        end (row, col) float32 (2,), the mid-exposure time (ns), the split's tip sweep (px; the distance between
        the tips when larger) and the exposure (ns, 0 = unknown).

        Raises
        ------
        ValueError
            When a shape has no point.
        """
        if not begin.flags.writeable:  # the kernel takes the splitter's writable buffers; never per frame
            begin = begin.copy()
        if not end.flags.writeable:
            end = end.copy()
        if K.observe_motion(
            begin, end, fixed, t_mid_ns, sweep_px, exposure_ns, self.times_ns, self.log, self.state, self.sweep
        ) < 0:  # fmt: skip
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
        out = self._out
        K.predict_motion(t_ns, exposure_ns, self.times_ns, self.log, self.state, self.sweep, out)
        rot_a, rot_b, motion = out.tolist()
        return rot_a, rot_b, motion
