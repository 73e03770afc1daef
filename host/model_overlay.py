"""The ANCF model next to a recorded run: the model's rope and its error, as channels of a replayed recording.

`ModelOverlay.fit` runs `ropecam compare`'s release-time fit (`ropecam.host.compare.release.fit_release`:
material-point tracks in metres, least-squares release time, one model run over the whole recording);
`ModelOverlay.messages` then gives, for each replayed FrameResult, the model's rope at the start and end of the
exposure (``foxglove.SceneUpdate`` in the plane frame) and the distance of each measured material point from the
model (``ropecam.ModelError``, mm).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Final

import numpy as np

from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.host.compare.measurement import default_points
from ropecam.shared.errors import DataError

if TYPE_CHECKING:
    from ropecam.host.model.config import RopeConfig, SolverConfig
    from ropecam.host.model.trajectory import Trajectory
    from ropecam.host.recording.convert import Encoder
    from ropecam.shared.protocol.records import FrameResult

__all__ = ["ModelOverlay"]

MODEL_POINTS: Final = 101
"""Samples of the model rope drawn per shape."""
_MODEL_COLOR: Final = (0.2, 0.9, 0.3, 1.0)


@dataclasses.dataclass(frozen=True)
class ModelOverlay:
    """A model trajectory aligned with a device's clock.

    Parameters
    ----------
    trajectory
        The model run (model time 0 = release).
    release_time_s
        Release time on the device clock (seconds).
    length_m
        Unstretched rope length of the model.
    s_m
        Material points (arc lengths from the fixed end) whose error is reported.
    calibration
        (camera, plane pose) that turns the device's pixels into metres on the plane.
    """

    trajectory: Trajectory
    release_time_s: float
    length_m: float
    s_m: tuple[float, ...]
    calibration: tuple[CameraModel, PlanePose]
    rms_error_m: float = math.nan

    @classmethod
    def fit(
        cls,
        frames: Sequence[FrameResult],
        calibration: tuple[CameraModel, PlanePose],
        rope: RopeConfig,
        solver: SolverConfig,
        s_m: Sequence[float] | None = None,
        release_time_s: float | None = None,
        progress: Callable[[int, float], None] | None = None,
    ) -> ModelOverlay:
        """Fit the release time to the measured frames (as `ropecam compare`) and run the model over them.

        Raises
        ------
        DataError
            No frame has a measured shape.
        """
        from ropecam.host.compare.measurement import measured_frame
        from ropecam.host.compare.release import fit_release

        points = tuple(s_m) if s_m else tuple(default_points(rope.length_m))
        if not frames:
            raise DataError("the recording holds no FrameResult of the chosen device: nothing to compare")
        measured = [measured_frame(f) for f in frames]
        release = fit_release(measured, calibration, rope, solver, points, release_time_s, progress, "the recording")
        return cls(release.trajectory, release.release_time_s, rope.length_m, points, calibration,
                   release.errors.overall_rms_m)  # fmt: skip

    def _model_time(self, t_ns: int) -> float | None:
        """Model time (s) of a device time; before the release the rope rests (time 0); None past the model's end."""
        times = self.trajectory.times_s
        t_s = t_ns * 1e-9 - self.release_time_s
        if t_s > times[-1] + 1e-9:
            return None  # the model run stopped: no model to compare with (not its last state)
        return float(max(t_s, times[0]))

    def frame_errors_mm(self, record: FrameResult) -> tuple[list[float | None], list[float | None]]:
        """Distances (mm) of the frame's material points from the model at exposure start and end.

        The points are placed and timed as `ropecam compare` does (`tracks_from_frames`): with a rolling shutter
        each at its own row's time, placed on the rope at one instant (docs/compare.md, "Rolling shutter"). None
        where not measured, for every point of a frame whose status is not OK (the fit ignores those too) or whose
        shapes miss the plane, and for a shape seen past the end of the model run.
        """
        from ropecam.host.compare.measurement import measured_frame, tracks_from_frames
        from ropecam.shared.protocol.records import FrameStatus

        nothing: list[float | None] = [None] * len(self.s_m)
        if record.status != FrameStatus.OK:
            return list(nothing), list(nothing)
        try:
            tracks, _ = tracks_from_frames([measured_frame(record)], *self.calibration, self.s_m, self.length_m, [])
        except DataError:  # both shapes miss the plane
            return list(nothing), list(nothing)
        assert tracks.point_times_s is not None  # set by MaterialPointTracks
        out: list[list[float | None]] = []
        for sample in range(2):  # exposure start, then end (the tracks are in time order)
            model_t = tracks.point_times_s[sample] - self.release_time_s
            if np.any(model_t > self.trajectory.times_s[-1] + 1e-9):
                out.append(list(nothing))  # the model run stopped: no model to compare with (not its last state)
                continue
            model_t = np.maximum(model_t, self.trajectory.times_s[0])  # before the release the rope rests
            model = np.stack(
                [self.trajectory.positions([t], [s])[0, 0] for t, s in zip(model_t, self.s_m, strict=True)]
            )
            distance_mm = np.linalg.norm(tracks.positions_m[sample] - model, axis=1) * 1e3
            out.append([None if math.isnan(d) else round(float(d), 6) for d in distance_mm])
        return out[0], out[1]

    def messages(
        self,
        record: FrameResult,
        device_id: int,
        t_ns: int,
        errors_mm: tuple[list, list] | None = None,
        encoder: Encoder | None = None,
    ) -> list[tuple[str, bytes, str, str]]:
        """Return (topic, bytes, schema name, message encoding) of the model channels for one frame.

        Parameters
        ----------
        errors_mm
            `frame_errors_mm` of the frame if already computed.
        encoder
            Encoding of the model scene (default JSON); the ``ropecam.ModelError`` is JSON.
        """
        from ropecam.host.recording.convert import JsonEncoder, model_content, model_error_message
        from ropecam.host.session import device_topic

        encoder = encoder if encoder is not None else JsonEncoder()
        times = (self._model_time(record.exposure_start_t_ns), self._model_time(record.exposure_end_t_ns))
        errors = errors_mm if errors_mm is not None else self.frame_errors_mm(record)
        grid = np.linspace(0.0, self.length_m, MODEL_POINTS)
        running = [t for t in times if t is not None]  # past the end of the model run nothing is drawn
        shapes = self.trajectory.positions(running, grid) if running else np.zeros((0, MODEL_POINTS, 2))
        scene = encoder.scene(model_content(shapes, _MODEL_COLOR, device_id, record.frame_index), t_ns)
        error = model_error_message(device_id, record.frame_index, t_ns, self.release_time_s, times, self.s_m, errors)
        return [
            (device_topic(device_id, "plane/model"), scene, "foxglove.SceneUpdate", encoder.encoding),
            (device_topic(device_id, "model_error"), error, "ropecam.ModelError", "json"),
        ]
