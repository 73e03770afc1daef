"""The camera and the motion plane: pinhole + OpenCV distortion, and metres on the plane <-> distorted pixels.

Conventions
-----------
* Pixels are OpenCV's: (u, v) = (column, row), (0, 0) is the centre of the top-left pixel, distorted (as the sensor
  sees them) unless a name says ``undistorted``.
* The plane frame is the paper's: x horizontal (release direction), y along gravity (down), z = x cross y, metres,
  origin at the rope's fixed end. A point (x, y) on the plane is (x, y, 0) in that frame.
* The plane pose is OpenCV's extrinsic: ``X_camera = R @ X_plane + t`` (what `solvePnP` returns for a board whose
  object points are given in the plane frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["CameraModel", "PlanePose", "pixels_to_plane", "plane_to_pixels"]


def _as_points(points: ArrayLike, name: str) -> NDArray[np.float64]:
    array = np.asarray(points, dtype=np.float64)
    if array.ndim < 1 or array.shape[-1] != 2:
        raise ValueError(f"{name} must have shape (..., 2), got {array.shape}")
    return array


def _padded(values: NDArray[np.float64], size: int) -> NDArray[np.float64]:
    return np.concatenate([values, np.zeros(size - values.size)])


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Pinhole intrinsics with OpenCV's distortion model.

    Two models are equal when they have the same image size, the same K and the same distortion coefficients
    (missing trailing coefficients count as zero). Models are not hashable (their arrays are not).

    Parameters
    ----------
    camera_matrix
        K, shape (3, 3): [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels.
    distortion
        OpenCV distortion coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]), any length OpenCV accepts.
    image_size
        (width, height) in pixels.
    """

    camera_matrix: NDArray[np.float64]
    distortion: NDArray[np.float64]
    image_size: tuple[int, int]

    def __post_init__(self) -> None:
        k = np.asarray(self.camera_matrix, dtype=np.float64)
        d = np.asarray(self.distortion, dtype=np.float64).ravel()
        if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0:
            raise ValueError(f"camera_matrix must be a finite 3x3 matrix with fx, fy > 0, got {k.tolist()}")
        if d.size not in (0, 4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
            raise ValueError(f"distortion must hold 4, 5, 8, 12 or 14 finite coefficients, got {d.tolist()}")
        width, height = self.image_size
        if width <= 0 or height <= 0:
            raise ValueError(f"image_size must be (width, height) > 0, got {self.image_size}")
        object.__setattr__(self, "camera_matrix", k)
        object.__setattr__(self, "distortion", d if d.size else np.zeros(5))
        object.__setattr__(self, "image_size", (int(width), int(height)))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CameraModel):
            return NotImplemented
        n = max(self.distortion.size, other.distortion.size)
        return (
            self.image_size == other.image_size
            and np.array_equal(self.camera_matrix, other.camera_matrix)
            and np.array_equal(_padded(self.distortion, n), _padded(other.distortion, n))
        )

    __hash__ = None  # type: ignore[assignment]

    @property
    def fx(self) -> float:
        """Focal length along u in pixels."""
        return float(self.camera_matrix[0, 0])

    @property
    def fy(self) -> float:
        """Focal length along v in pixels."""
        return float(self.camera_matrix[1, 1])

    def undistort(self, pixels: ArrayLike) -> NDArray[np.float64]:
        """Return normalised undistorted image coordinates (x/z, y/z) of distorted `pixels`, shape (..., 2)."""
        uv = _as_points(pixels, "pixels")
        flat = uv.reshape(-1, 1, 2)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        # OpenCV's default stops after 5 fixed-point iterations (pixel-level error with strong distortion); ask
        # for convergence. OpenCV 5 takes the criteria in undistortPoints, 4.x in undistortPointsIter.
        undistort_iter = getattr(cv2, "undistortPointsIter", None)
        if undistort_iter is not None:
            normalised = undistort_iter(flat, self.camera_matrix, self.distortion, None, None, criteria)
        else:
            normalised = cv2.undistortPoints(flat, self.camera_matrix, self.distortion, None, None, None, criteria)
        return normalised.reshape(uv.shape)


@dataclass(frozen=True, eq=False)
class PlanePose:
    """Pose of the motion plane in the camera frame: ``X_camera = rotation @ X_plane + translation_m``.

    Two poses are equal when their rotations and translations are exactly equal; poses are not hashable.
    """

    rotation: NDArray[np.float64]
    translation_m: NDArray[np.float64]

    def __post_init__(self) -> None:
        r = np.asarray(self.rotation, dtype=np.float64)
        t = np.asarray(self.translation_m, dtype=np.float64).ravel()
        if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) < 0:
            raise ValueError(f"rotation must be a proper 3x3 rotation matrix, got {r.tolist()}")
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise ValueError(f"translation_m must hold 3 finite values, got {t.tolist()}")
        object.__setattr__(self, "rotation", r)
        object.__setattr__(self, "translation_m", t)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PlanePose):
            return NotImplemented
        return np.array_equal(self.rotation, other.rotation) and np.array_equal(self.translation_m, other.translation_m)

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def from_rvec(cls, rvec: ArrayLike, tvec: ArrayLike) -> PlanePose:
        """Build a pose from OpenCV's Rodrigues vector and translation (metres)."""
        rotation, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
        return cls(rotation, np.asarray(tvec, dtype=np.float64).ravel())

    @property
    def rvec(self) -> NDArray[np.float64]:
        """OpenCV Rodrigues vector of `rotation`, shape (3,)."""
        vector, _ = cv2.Rodrigues(self.rotation)
        return vector.ravel()


def plane_to_pixels(points_m: ArrayLike, camera: CameraModel, plane: PlanePose) -> NDArray[np.float64]:
    """Project points (x, y) in metres on the plane to distorted pixels (u, v), shape (..., 2).

    Uses `cv2.projectPoints`, so it agrees with OpenCV by construction.
    """
    xy = _as_points(points_m, "points_m")
    flat = xy.reshape(-1, 2)
    xyz = np.column_stack([flat, np.zeros(len(flat))])
    uv, _ = cv2.projectPoints(xyz, plane.rvec, plane.translation_m, camera.camera_matrix, camera.distortion)
    return uv.reshape(xy.shape)


def pixels_to_plane(pixels: ArrayLike, camera: CameraModel, plane: PlanePose) -> NDArray[np.float64]:
    """Convert distorted pixels (u, v) to points (x, y) in metres on the plane, shape (..., 2).

    Undistorts to a viewing ray and intersects it with the plane z = 0 of the plane frame.

    Raises
    ------
    ValueError
        A ray is parallel to the plane or meets it behind the camera.
    """
    uv = _as_points(pixels, "pixels")
    normalised = camera.undistort(uv).reshape(-1, 2)
    rays = np.column_stack([normalised, np.ones(len(normalised))])  # camera frame
    # In the plane frame: X = R^T (lambda * ray - t); solve z = 0 for lambda.
    rays_p = rays @ plane.rotation  # rows: R^T ray
    origin_p = -plane.rotation.T @ plane.translation_m
    denominator = rays_p[:, 2]
    if np.any(np.abs(denominator) < 1e-12):
        raise ValueError("a pixel's viewing ray is parallel to the motion plane")
    scale = -origin_p[2] / denominator
    if np.any(scale <= 0):
        raise ValueError("a pixel's viewing ray meets the motion plane behind the camera")
    points = origin_p[None, :] + scale[:, None] * rays_p
    return points[:, :2].reshape(uv.shape)
