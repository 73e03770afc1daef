"""Camera and plane files in OpenCV FileStorage YAML, so OpenCV (C++, Python) reads them as they are.

camera.yaml keeps OpenCV's calibration-sample keys: ``image_width``, ``image_height``, ``camera_matrix``,
``distortion_coefficients``, ``avg_reprojection_error`` (plus ``nframes``, board and per-view errors).
plane.yaml holds the plane pose (``plane_rvec``, ``plane_rotation``, ``plane_translation_m``: X_camera = R X_plane + t)
and a copy of the camera it was measured with, so one file is enough to convert pixels to metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.shared.errors import DataError

__all__ = ["CameraFile", "PlaneFile", "read_camera", "read_plane", "write_camera", "write_plane"]


@dataclass(frozen=True)
class CameraFile:
    """Contents of a camera.yaml: the camera, its RMS reprojection error (px) and optional metadata."""

    camera: CameraModel
    avg_reprojection_error_px: float
    metadata: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class PlaneFile:
    """Contents of a plane.yaml: the camera used, the plane pose, the fixed end and the error report numbers."""

    camera: CameraModel
    plane: PlanePose
    metadata: dict[str, Any] = field(default_factory=dict)


def _open_write(path: Path) -> cv2.FileStorage:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    except (OSError, cv2.error, SystemError) as exc:
        raise DataError(f"{path}: cannot open for writing: {exc}") from exc
    if not storage.isOpened():
        raise DataError(f"{path}: cannot open for writing")
    return storage


def _write_camera_fields(storage: cv2.FileStorage, camera: CameraModel) -> None:
    storage.write("image_width", camera.image_size[0])
    storage.write("image_height", camera.image_size[1])
    storage.write("camera_matrix", camera.camera_matrix)
    storage.write("distortion_coefficients", camera.distortion.reshape(-1, 1))


def _write_metadata(storage: cv2.FileStorage, metadata: dict[str, Any]) -> None:
    for key, value in metadata.items():
        if isinstance(value, str | int | float) and not isinstance(value, bool):
            storage.write(key, value)
        elif isinstance(value, bool):
            storage.write(key, int(value))
        else:
            storage.write(key, np.asarray(value, dtype=np.float64))


def write_camera(path: str | Path, camera: CameraModel, rms_px: float, metadata: dict[str, Any] | None = None) -> Path:
    """Write `camera` to an OpenCV FileStorage YAML file (created with its folder); return the path.

    Parameters
    ----------
    path
        Output ``.yaml`` (or ``.yml``, ``.xml``, ``.json``: FileStorage picks the format from the suffix).
    camera
        The calibrated camera.
    rms_px
        Total RMS reprojection error, written as ``avg_reprojection_error``.
    metadata
        Extra scalar or array entries (``nframes``, ``board_width``, ``per_view_reprojection_errors``...).
    """
    path = Path(path)
    storage = _open_write(path)
    try:
        _write_camera_fields(storage, camera)
        storage.write("avg_reprojection_error", float(rms_px))
        _write_metadata(storage, metadata or {})
    finally:
        storage.release()
    return path


def _open_read(path: Path, what: str) -> cv2.FileStorage:
    if not path.is_file():
        raise DataError(f"{path}: {what} file not found")
    try:
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # the binding reports some parse errors as SystemError
        detail = exc.err if isinstance(exc, cv2.error) else str(exc.__cause__ or exc)
        raise DataError(f"{path}: not an OpenCV FileStorage {what} file ({detail.strip()})") from exc
    if not storage.isOpened():
        raise DataError(f"{path}: not an OpenCV FileStorage {what} file")
    return storage


def _matrix(
    storage: cv2.FileStorage, path: Path, key: str, shape: tuple[int, ...] | None = None
) -> NDArray[np.float64]:
    node = storage.getNode(key)
    value = None if node.empty() else node.mat()
    if value is None:
        raise DataError(f"{path}: key '{key}' is missing or not a matrix")
    value = np.asarray(value, dtype=np.float64)
    if shape is not None and value.size != int(np.prod(shape)):
        raise DataError(f"{path}: key '{key}' must hold {int(np.prod(shape))} values, got shape {value.shape}")
    return value.reshape(shape) if shape is not None else value.ravel()


def _int(storage: cv2.FileStorage, path: Path, key: str) -> int:
    node = storage.getNode(key)
    if node.empty() or (not node.isReal() and not node.isInt()):
        raise DataError(f"{path}: key '{key}' is missing or not a number")
    return int(node.real())


def _read_camera_from(storage: cv2.FileStorage, path: Path) -> CameraModel:
    size = (_int(storage, path, "image_width"), _int(storage, path, "image_height"))
    k = _matrix(storage, path, "camera_matrix", (3, 3))
    dist = _matrix(storage, path, "distortion_coefficients")
    try:
        return CameraModel(k, dist, size)
    except ValueError as exc:
        raise DataError(f"{path}: invalid camera: {exc}") from exc


def read_camera(path: str | Path) -> CameraFile:
    """Read a camera.yaml written by `write_camera` or by OpenCV's calibration sample.

    Raises
    ------
    DataError
        Missing file, not FileStorage, missing or malformed keys (the message names the file and key).
    """
    path = Path(path)
    storage = _open_read(path, "camera")
    try:
        camera = _read_camera_from(storage, path)
        rms_node = storage.getNode("avg_reprojection_error")
        rms = float(rms_node.real()) if not rms_node.empty() else float("nan")
    finally:
        storage.release()
    return CameraFile(camera, rms)


def write_plane(
    path: str | Path, camera: CameraModel, plane: PlanePose, metadata: dict[str, Any] | None = None
) -> Path:
    """Write the plane pose and the camera it was measured with to a FileStorage YAML file; return the path."""
    path = Path(path)
    storage = _open_write(path)
    try:
        _write_camera_fields(storage, camera)
        storage.write("plane_rvec", plane.rvec.reshape(3, 1))
        storage.write("plane_rotation", plane.rotation)
        storage.write("plane_translation_m", plane.translation_m.reshape(3, 1))
        _write_metadata(storage, metadata or {})
    finally:
        storage.release()
    return path


def read_plane(path: str | Path) -> PlaneFile:
    """Read a plane.yaml written by `write_plane`: the camera and the plane pose for `pixels_to_plane`.

    Raises
    ------
    DataError
        Missing file, not FileStorage, missing or malformed keys.
    """
    path = Path(path)
    storage = _open_read(path, "plane")
    try:
        camera = _read_camera_from(storage, path)
        rotation = _matrix(storage, path, "plane_rotation", (3, 3))
        translation = _matrix(storage, path, "plane_translation_m", (3,))
        metadata = {}
        for key in ("origin_board_mm", "origin_px"):
            node = storage.getNode(key)
            value = None if node.empty() else node.mat()
            if value is not None:
                metadata[key] = np.asarray(value, dtype=np.float64).ravel()
    finally:
        storage.release()
    try:
        plane = PlanePose(rotation, translation)
    except ValueError as exc:
        raise DataError(f"{path}: invalid plane pose: {exc}") from exc
    return PlaneFile(camera, plane, metadata)
