"""CameraModel and PlanePose as values: equality compares their arrays, they are not hashable."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.host.calibration.geometry import CameraModel, PlanePose

K = np.array([[700.0, 0, 321.0], [0, 690.0, 238.0], [0, 0, 1]])


def test_camera_models_compare_by_value() -> None:
    camera = CameraModel(K, np.array([-0.15, 0.1, 0, 0, 0]), (640, 480))
    assert camera == CameraModel(K.copy(), [-0.15, 0.1, 0.0, 0.0, 0.0], (640, 480))
    assert camera == CameraModel(K, [-0.15, 0.1, 0.0, 0.0], (640, 480))  # a missing k3 is k3 = 0
    assert camera != CameraModel(K, [-0.15, 0.1, 0.0, 0.0, 0.01], (640, 480))
    assert camera != CameraModel(K * [[1.001], [1], [1]], [-0.15, 0.1, 0.0, 0.0], (640, 480))
    assert camera != CameraModel(K, [-0.15, 0.1, 0.0, 0.0], (640, 481))
    assert camera != "camera" and camera not in [None, 3]
    assert camera in [CameraModel(K, [-0.15, 0.1, 0, 0], (640, 480))]
    with pytest.raises(TypeError, match="unhashable"):
        hash(camera)


def test_plane_poses_compare_by_value() -> None:
    pose = PlanePose.from_rvec([0.1, -0.2, 0.05], [0.0, -0.1, 1.5])
    assert pose == PlanePose(pose.rotation.copy(), list(pose.translation_m))
    assert pose != PlanePose(pose.rotation, pose.translation_m + np.array([0, 0, 1e-9]))
    assert pose != PlanePose(np.eye(3), pose.translation_m)
    assert pose != (pose.rotation, pose.translation_m)
    with pytest.raises(TypeError, match="unhashable"):
        hash(pose)
