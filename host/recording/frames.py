"""The coordinate frames of a calibrated device, as a Foxglove transform tree.

``device<ID>/plane`` (root; metres; x along the release direction, y down, z the plane normal away from the
camera side as ``ropecam calibrate plane`` measured it) -> ``device<ID>/camera`` (OpenCV camera axes: x right, y
down, z along the optical axis) -> ``device<ID>/image`` (pixels: x = u, y = v).

A transform cannot scale, so pixels stay pixels: the image frame is the camera's image plane at the focal distance
with one pixel drawn as one unit, its origin at (-cx, -cy, fx) in the camera frame. Each pixel (u, v) then lies on
its own viewing ray (exactly for undistorted pixels with fx = fy), so seen from the camera frame the pixel scene
(``/device<ID>/image/scene``) covers the metric one (``/device<ID>/plane/scene``), about f / distance times larger.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.host.recording.convert import Transform

__all__ = ["device_transforms", "quaternion"]


def quaternion(rotation: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """Return the unit quaternion (x, y, z, w) of a 3x3 rotation matrix (w >= 0)."""
    r = np.asarray(rotation, dtype=np.float64)
    trace = float(np.trace(r))
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = ((r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s)
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        v = np.empty(3)
        v[i] = 0.25 * s
        v[j] = (r[j, i] + r[i, j]) / s
        v[k] = (r[k, i] + r[i, k]) / s
        q = (v[0], v[1], v[2], (r[k, j] - r[j, k]) / s)
    x, y, z, w = (float(c) for c in np.asarray(q) / np.linalg.norm(q))
    return (x, y, z, w) if w >= 0 else (-x, -y, -z, -w)


def device_transforms(device_id: int, camera: CameraModel, plane: PlanePose) -> list[Transform]:
    """Return plane -> camera and camera -> image of one calibrated device (see the module docstring)."""
    to_plane = plane.rotation.T  # X_plane = R^T (X_camera - t)
    origin = -to_plane @ plane.translation_m
    k = np.asarray(camera.camera_matrix, dtype=np.float64)
    prefix = f"device{device_id}"
    return [
        Transform(f"{prefix}/plane", f"{prefix}/camera", tuple(float(v) for v in origin), quaternion(to_plane)),
        Transform(
            f"{prefix}/camera", f"{prefix}/image", (-float(k[0, 2]), -float(k[1, 2]), float(k[0, 0])), (0, 0, 0, 1.0)
        ),
    ]
