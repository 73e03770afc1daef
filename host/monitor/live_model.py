"""The ANCF model next to the live stream: wait for the rope at rest, detect the release, align the model with it.

Live there is no whole run to fit the release time to (`ropecam replay --model` does that). Instead, per device:
the tip (metres on the plane) must first stay within `rest_tolerance_m` for `rest_frames` frames (armed); the first
frame whose tip then moved `release_move_m` from the rest position dates the release (a tip creeping off rest for
`CREEP_FRAMES` frames without getting there is a hand moving the rope: disarmed): the model is simulated once
up front, so the time its own tip needs to move that far is known, and ``release = detection time - that time``.
From then on every decoded frame gets the model channels and the model error column.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Final

import numpy as np

from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.host.compare.measurement import default_points
from ropecam.host.model_overlay import ModelOverlay
from ropecam.shared.errors import ModelError

if TYPE_CHECKING:
    from ropecam.host.model.trajectory import Trajectory
    from ropecam.shared.protocol.records import FrameResult

__all__ = ["LiveModel"]

REST_FRAMES: Final = 10
REST_TOLERANCE_M: Final = 0.002
RELEASE_MOVE_M: Final = 0.005
CREEP_FRAMES: Final = 12
"""A released rope's tip moves `RELEASE_MOVE_M` within a few frames; one that stays between the rest tolerance and
that for this many frames is being moved by hand: wait for rest again."""


@dataclass
class _DeviceState:
    rest_tips: deque[tuple[float, float]] = field(default_factory=lambda: deque(maxlen=REST_FRAMES))
    rest_tip: tuple[float, float] | None = None
    creeping: int = 0  # armed frames with the tip off rest but not yet released
    overlay: ModelOverlay | None = None


class LiveModel:
    """Release detection and model alignment for every device of a live stream (a `Session` model source).

    Parameters
    ----------
    trajectory
        The model run from its release (``CableModel(rope, solver).run()``).
    length_m
        Unstretched rope length of the model.
    calibration
        (camera, plane pose) of the devices.
    s_m
        Material points whose error is reported (default L/4, L/2, 3L/4, L).

    Raises
    ------
    ModelError
        The model's tip never moves `release_move_m` within the simulated time.
    """

    def __init__(
        self,
        trajectory: Trajectory,
        length_m: float,
        calibration: tuple[CameraModel, PlanePose],
        s_m: tuple[float, ...] | None = None,
        rest_frames: int = REST_FRAMES,
        rest_tolerance_m: float = REST_TOLERANCE_M,
        release_move_m: float = RELEASE_MOVE_M,
    ) -> None:
        self.trajectory = trajectory
        self.length_m = length_m
        self.calibration = calibration
        self.s_m = s_m or tuple(default_points(length_m))
        self.rest_frames = rest_frames
        self.rest_tolerance_m = rest_tolerance_m
        self.release_move_m = release_move_m
        tips = trajectory.positions(trajectory.times_s, [length_m])[:, 0, :]
        moved = np.flatnonzero(np.hypot(*(tips - tips[0]).T) >= release_move_m)
        if moved.size == 0:
            raise ModelError(
                f"the model's tip never moves {release_move_m * 1e3:g} mm in its {trajectory.times_s[-1]:g} s: "
                "no release to align with (check the rope's initial angle and the solver duration)"
            )
        self.model_move_time_s = float(trajectory.times_s[moved[0]])
        self._devices: dict[int, _DeviceState] = {}

    def __call__(self, record: FrameResult, device_id: int) -> ModelOverlay | None:
        """Update the device's release detection with a decoded frame; return its aligned model once released."""
        state = self._devices.setdefault(device_id, _DeviceState())
        if state.overlay is not None:
            return state.overlay
        samples = [
            (t, tip)
            for t, tip in (
                (record.exposure_start_t_ns, record.begin_tip_px),
                (record.exposure_end_t_ns, record.end_tip_px),
            )
            if tip is not None
        ]
        if not samples:
            return None
        tips_m = pixels_to_plane([tip for _, tip in samples], *self.calibration)
        if state.rest_tip is not None:
            for (t_ns, _), tip_m in zip(samples, tips_m, strict=True):
                if math.dist(tip_m, state.rest_tip) >= self.release_move_m:
                    release_s = t_ns * 1e-9 - self.model_move_time_s
                    state.overlay = ModelOverlay(self.trajectory, release_s, self.length_m, self.s_m, self.calibration)
                    return state.overlay
            if math.dist(tips_m[-1], state.rest_tip) > self.rest_tolerance_m:
                state.creeping += 1
                if state.creeping > CREEP_FRAMES:
                    state.rest_tip, state.creeping = None, 0
                    state.rest_tips.clear()
                return None
            state.creeping = 0
        state.rest_tips.append(tuple(tips_m[-1]))
        spread = np.ptp(np.asarray(state.rest_tips), axis=0)
        if len(state.rest_tips) == self.rest_frames and float(np.hypot(*spread)) <= self.rest_tolerance_m:
            state.rest_tip = tuple(np.mean(np.asarray(state.rest_tips), axis=0))
        return None

    def describe(self) -> str:
        """One line about every device's state (for the display)."""
        if not self._devices:
            return "model: waiting for frames"
        parts = []
        for device_id, state in sorted(self._devices.items()):
            if state.overlay is not None:
                parts.append(f"dev{device_id} released at {state.overlay.release_time_s:.3f} s (device clock)")
            elif state.rest_tip is not None:
                parts.append(f"dev{device_id} armed: rope at rest")
            else:
                parts.append(f"dev{device_id} waiting for the rope at rest")
        return "model: " + "; ".join(parts)
