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
from numpy.typing import NDArray

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

    def _errors_mm(self, shape_px: NDArray[np.float64] | None, model_t_s: float | None) -> list[float | None]:
        from ropecam.host.compare.measurement import shape_points_m

        if shape_px is None or model_t_s is None:
            return [None] * len(self.s_m)
        measured, _ = shape_points_m(shape_px, "OK", *self.calibration, np.asarray(self.s_m), self.length_m)
        model = self.trajectory.positions([model_t_s], self.s_m)[0]
        distance_mm = np.linalg.norm(measured - model, axis=1) * 1e3
        return [None if math.isnan(d) else round(float(d), 6) for d in distance_mm]

    def frame_errors_mm(self, record: FrameResult) -> tuple[list[float | None], list[float | None]]:
        """Distances (mm) of the frame's material points from the model at exposure start and end.

        None where not measured, for every point of a frame whose status is not OK (the fit ignores those too), and
        for a time past the end of the model run.
        """
        from ropecam.shared.protocol.records import FrameStatus

        if record.status != FrameStatus.OK:
            return [None] * len(self.s_m), [None] * len(self.s_m)
        return (
            self._errors_mm(record.begin_px, self._model_time(record.exposure_start_t_ns)),
            self._errors_mm(record.end_px, self._model_time(record.exposure_end_t_ns)),
        )

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
