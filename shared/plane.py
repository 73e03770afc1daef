"""The motion-plane calibration (``plane.yaml`` of ``ropecam calibrate plane``) for the device, without OpenCV.

``ropecam.host.calibration.files.write_plane`` writes OpenCV FileStorage YAML: ``image_width``, ``image_height``,
``camera_matrix`` (3x3), ``distortion_coefficients`` (OpenCV's k1 k2 p1 p2 [k3 [k4 k5 k6]]), ``plane_rotation``
(3x3) and ``plane_translation_m`` (3): X_camera = R X_plane + t, the plane frame's origin at the rope's fixed end.
The device reads it with this small reader (it has no OpenCV outside capture) to know the fixed end in the image
(the origin's projection) and to measure arc length on the plane (`PlaneCalibration.to_plane`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ropecam.shared.errors import ConfigError

__all__ = ["PlaneCalibration", "read_plane_file"]

_UNDISTORT_ITERATIONS = 20
_MATRIX_KEYS = ("camera_matrix", "distortion_coefficients", "plane_rotation", "plane_translation_m")


@dataclass(frozen=True, slots=True)
class PlaneCalibration:
    """A camera (pinhole with OpenCV distortion) and the pose of the motion plane in it.

    Parameters
    ----------
    camera_matrix
        (3, 3) float64 intrinsics.
    distortion
        OpenCV distortion coefficients: 4, 5 or 8 of k1 k2 p1 p2 k3 k4 k5 k6 (float64).
    image_size
        (width, height) the camera was calibrated at.
    rotation, translation_m
        X_camera = rotation @ X_plane + translation_m; the plane is z = 0 of the plane frame, its origin the fixed end.
    source
        Where it was read from (for messages).
    """

    camera_matrix: NDArray[np.float64]
    distortion: NDArray[np.float64]
    image_size: tuple[int, int]
    rotation: NDArray[np.float64]
    translation_m: NDArray[np.float64]
    source: str = "plane calibration"

    def __post_init__(self) -> None:
        if self.camera_matrix.shape != (3, 3) or self.rotation.shape != (3, 3) or self.translation_m.shape != (3,):
            raise ConfigError(f"{self.source}: camera_matrix and plane_rotation must be 3x3, plane_translation_m 3")
        if self.distortion.size not in (4, 5, 8):
            raise ConfigError(
                f"{self.source}: distortion_coefficients has {self.distortion.size} values, expected 4, 5 or 8"
            )
        if not np.allclose(self.rotation @ self.rotation.T, np.eye(3), atol=1e-6):
            raise ConfigError(f"{self.source}: plane_rotation is not a rotation matrix")
        if not (np.all(np.isfinite(self.camera_matrix)) and np.all(np.isfinite(self.translation_m))):
            raise ConfigError(f"{self.source}: camera_matrix and plane_translation_m must be finite")

    def project(self, points_m: ArrayLike) -> NDArray[np.float64]:
        """Project points (x, y) in metres on the plane, shape (n, 2), to distorted pixels (u, v), shape (n, 2)."""
        xy = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        xyz = np.column_stack([xy, np.zeros(len(xy))]) @ self.rotation.T + self.translation_m
        if np.any(xyz[:, 2] <= 0):
            raise ValueError(f"{self.source}: a plane point lies behind the camera")
        return self._distort(xyz[:, :2] / xyz[:, 2:3])

    def origin_uv(self) -> tuple[float, float]:
        """Return the plane origin (the rope's fixed end) in distorted pixels (u, v)."""
        u, v = self.project(np.zeros((1, 2)))[0]
        return float(u), float(v)

    def to_plane(self, pixels_uv: ArrayLike) -> NDArray[np.float64]:
        """Convert distorted pixels (u, v), shape (n, 2), to points (x, y) in metres on the plane.

        Raises
        ------
        ValueError
            A pixel's viewing ray is parallel to the plane or meets it behind the camera.
        """
        uv = np.asarray(pixels_uv, dtype=np.float64).reshape(-1, 2)
        rays = np.column_stack([self._undistort(uv), np.ones(len(uv))]) @ self.rotation  # R^T ray, plane frame
        origin = -self.rotation.T @ self.translation_m
        if np.any(np.abs(rays[:, 2]) < 1e-12):
            raise ValueError(f"{self.source}: a pixel's viewing ray is parallel to the motion plane")
        scale = -origin[2] / rays[:, 2]
        if np.any(scale <= 0):
            raise ValueError(f"{self.source}: a pixel's viewing ray meets the motion plane behind the camera")
        return (origin[None, :2] + scale[:, None] * rays[:, :2]).reshape(-1, 2)

    def _distort(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        k = np.zeros(8)
        k[: self.distortion.size] = self.distortion
        x, y = xy[:, 0], xy[:, 1]
        r2 = x * x + y * y
        radial = (1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]))) / (1 + r2 * (k[5] + r2 * (k[6] + r2 * k[7])))
        xd = x * radial + 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x)
        yd = y * radial + k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y
        m = self.camera_matrix
        return np.column_stack([m[0, 0] * xd + m[0, 1] * yd + m[0, 2], m[1, 1] * yd + m[1, 2]])

    def _undistort(self, uv: NDArray[np.float64]) -> NDArray[np.float64]:
        """Normalised undistorted coordinates of distorted pixels (OpenCV's fixed-point iteration)."""
        k = np.zeros(8)
        k[: self.distortion.size] = self.distortion
        m = self.camera_matrix
        yd = (uv[:, 1] - m[1, 2]) / m[1, 1]
        xd = (uv[:, 0] - m[0, 2] - m[0, 1] * yd) / m[0, 0]
        x, y = xd.copy(), yd.copy()
        for _ in range(_UNDISTORT_ITERATIONS):
            r2 = x * x + y * y
            icdist = (1 + r2 * (k[5] + r2 * (k[6] + r2 * k[7]))) / (1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4])))
            dx = 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x)
            dy = k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y
            x, y = (xd - dx) * icdist, (yd - dy) * icdist
        return np.column_stack([x, y])

    def check_image(self, image_size: tuple[int, int]) -> None:
        """Check the plane origin (the fixed end) projects inside an image of `image_size` (width, height).

        Raises
        ------
        ConfigError
            The origin projects outside the image, or behind the camera.
        """
        width, height = image_size
        try:
            u, v = self.origin_uv()
        except ValueError as exc:
            raise ConfigError(f"{self.source}: the plane origin (the rope's fixed end): {exc}") from exc
        if not (-0.5 <= u <= width - 0.5 and -0.5 <= v <= height - 0.5):
            raise ConfigError(
                f"{self.source}: the plane origin (the rope's fixed end) projects to (u, v) = ({u:.1f}, {v:.1f}) px, "
                f"outside the {width}x{height} image; expected a plane calibration of this camera whose origin was "
                "moved to the fixed end (ropecam calibrate plane --origin)"
            )


def _values(text: str, key: str, source: str) -> NDArray[np.float64]:
    """The numbers of top-level key `key`: a scalar, or a ``!!opencv-matrix``'s ``data: [...]``."""
    match = re.search(rf"^{re.escape(key)}:(.*?)(?=^\S|\Z)", text, re.MULTILINE | re.DOTALL)
    if match is None:
        raise ConfigError(f"{source}: key {key!r} is missing (expected a plane.yaml of ropecam calibrate plane)")
    body = match.group(1)
    data = re.search(r"data:\s*\[(.*?)\]", body, re.DOTALL)
    raw = data.group(1) if data else body
    try:
        values = np.array([float(v) for v in raw.replace(",", " ").split()], dtype=np.float64)
    except ValueError as exc:
        raise ConfigError(f"{source}: key {key!r} is not a list of numbers: {raw.strip()[:60]!r}") from exc
    if data is not None:
        rows = re.search(r"rows:\s*(\d+)", body)
        cols = re.search(r"cols:\s*(\d+)", body)
        if rows and cols and int(rows.group(1)) * int(cols.group(1)) != values.size:
            raise ConfigError(f"{source}: key {key!r} has {values.size} values, its rows x cols say otherwise")
    if not np.all(np.isfinite(values)):
        raise ConfigError(f"{source}: key {key!r} holds a non-finite value")
    return values


def read_plane_file(path: str | Path) -> PlaneCalibration:
    """Read a plane.yaml (OpenCV FileStorage YAML of ``ropecam calibrate plane``).

    Raises
    ------
    ConfigError
        Missing or unreadable file, a missing or malformed key (the message names the file and the key).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the plane calibration: {exc}") from exc
    source = str(path)
    if not text.lstrip().startswith("%YAML"):
        raise ConfigError(f"{path}: not an OpenCV FileStorage YAML file (expected a plane.yaml starting with %YAML)")
    width, height = (_values(text, key, source) for key in ("image_width", "image_height"))
    if width.size != 1 or height.size != 1 or not (width[0] >= 1 and height[0] >= 1):
        raise ConfigError(f"{path}: image_width and image_height must be positive integers")
    matrix, distortion, rotation, translation = (_values(text, key, source) for key in _MATRIX_KEYS)
    for key, values, size in (("camera_matrix", matrix, 9), ("plane_rotation", rotation, 9)):
        if values.size != size:
            raise ConfigError(f"{path}: key {key!r} has {values.size} values, expected {size}")
    if translation.size != 3:
        raise ConfigError(f"{path}: key 'plane_translation_m' has {translation.size} values, expected 3")
    if not math.isfinite(matrix[0]) or matrix[0] <= 0 or matrix[4] <= 0:
        raise ConfigError(f"{path}: camera_matrix needs positive focal lengths, got {matrix[0]}, {matrix[4]}")
    return PlaneCalibration(
        matrix.reshape(3, 3),
        distortion,
        (int(width[0]), int(height[0])),
        rotation.reshape(3, 3),
        translation,
        source,
    )
