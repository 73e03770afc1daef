"""A rolling shutter's line time reaches the material points' placement on the plane (`PointTracker.set_rolling`,
set by `Pipeline.process` from the readout, the image height and each frame's exposure)."""

from __future__ import annotations

import numpy as np

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.shared.plane import PlaneCalibration

PLANE = PlaneCalibration(
    np.array([[100.0, 0.0, 32.0], [0.0, 100.0, 24.0], [0.0, 0.0, 1.0]]), np.zeros(5), (64, 48), np.eye(3),
    np.array([0.0, 0.0, 1.0]), "a test plane",
)  # fmt: skip


def test_the_line_time_in_exposures_follows_the_frames_exposure() -> None:
    pipeline = Pipeline(PipelineConfig(), (64, 48), readout_us=2000, plane=PLANE)
    frame = np.zeros((48, 64), np.uint8)
    pipeline.process(frame, 0, 0, 4000.0)
    params = pipeline.tracker.plane
    assert params is not None and not params.flags.writeable
    assert params[K.PLANE.rolling] == 2_000_000 / (48 * 4_000_000)
    pipeline.process(frame, 1, 8_000_000, 4000.0)
    assert pipeline.tracker.plane is params  # unchanged: the same array (the steady frame keeps its table)
    pipeline.process(frame, 2, 16_000_000, 2000.0)
    assert pipeline.tracker.plane[K.PLANE.rolling] == 2_000_000 / (48 * 2_000_000)
    pipeline.process(frame, 3, 24_000_000, 0.0)  # exposure unknown: no correction
    assert pipeline.tracker.plane[K.PLANE.rolling] == 0.0


def test_a_global_shutter_leaves_the_plane_as_calibrated() -> None:
    pipeline = Pipeline(PipelineConfig(), (64, 48), readout_us=0, plane=PLANE)
    params = pipeline.tracker.plane
    pipeline.process(np.zeros((48, 64), np.uint8), 0, 0, 4000.0)
    assert pipeline.tracker.plane is params and params[K.PLANE.rolling] == 0.0


def test_the_work_buffer_holds_a_rolling_placement_of_the_longest_shapes() -> None:
    # Both shapes together have at most the contour's points; the rolling placement needs `ROLLING_WORK` values per
    # point, else the kernel places by the sheared shapes' own arcs without a word (a lowered max_contour did).
    pipeline = Pipeline(PipelineConfig(max_contour=100), (64, 48), readout_us=2000, plane=PLANE)
    assert len(pipeline.tracker.work) >= K.ROLLING_WORK * 100
