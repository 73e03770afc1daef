"""Intrinsic calibration from chessboard views: detection over a set of files, `cv2.calibrateCamera`, residuals."""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.board import Chessboard, Detection, SubpixSettings, detect_corners, read_gray
from ropecam.host.calibration.geometry import CameraModel
from ropecam.shared.errors import CalibrationError, DataError

__all__ = ["MIN_VIEWS", "MODELS", "IntrinsicResult", "calibrate_intrinsics", "detect_views"]

log = logging.getLogger(__name__)

# Fewer views leave focal length, principal point and distortion poorly constrained (OpenCV needs 3 at least).
MIN_VIEWS = 4
MODELS = {"standard": 0, "rational": cv2.CALIB_RATIONAL_MODEL}


@dataclass(frozen=True)
class IntrinsicResult:
    """Result of `calibrate_intrinsics`.

    Attributes
    ----------
    camera
        The calibrated camera.
    rms_px
        Total RMS reprojection error, sqrt(sum of squared point errors / number of points) (OpenCV's definition).
    used
        Detections that entered the calibration, in input order.
    failed
        Detections without a board (``reason`` says why).
    per_view_rms_px
        RMS reprojection error of each used view, shape (n_used,).
    residuals_px
        Observed minus reprojected corners of each used view, shape (n_used, n_corners, 2).
    rvecs, tvecs
        Board pose of each used view (Rodrigues vector, metres), shape (n_used, 3).
    flags
        `cv2.calibrateCamera` flags used.
    board
        The board.
    """

    camera: CameraModel
    rms_px: float
    used: list[Detection]
    failed: list[Detection]
    per_view_rms_px: NDArray[np.float64]
    residuals_px: NDArray[np.float64]
    rvecs: NDArray[np.float64]
    tvecs: NDArray[np.float64]
    flags: int
    board: Chessboard


def detect_views(
    paths: Sequence[str | Path],
    board: Chessboard,
    subpix: SubpixSettings | None = None,
    progress: Callable[[int, int, Detection], None] | None = None,
) -> tuple[list[Detection], list[Detection]]:
    """Detect the board in every image file; return (found, failed).

    Raises
    ------
    DataError
        Files are missing or unreadable (all are named), or the images do not all have the same size.
    """
    if not paths:
        raise CalibrationError("no images given")
    images = []
    unreadable = []
    for path in paths:
        try:
            images.append((path, read_gray(path)))
        except DataError as exc:
            unreadable.append(str(exc))
    if unreadable:
        raise DataError(f"{len(unreadable)} of {len(paths)} images cannot be read: " + "; ".join(unreadable))
    first_path, first = images[0]
    first_size = (int(first.shape[1]), int(first.shape[0]))
    for path, image in images:
        size = (int(image.shape[1]), int(image.shape[0]))
        if size != first_size:
            raise DataError(
                f"{path}: image size {size[0]}x{size[1]} differs from {first_size[0]}x{first_size[1]} of {first_path}; "
                "all views of one intrinsic calibration must come from the same camera mode"
            )
    found: list[Detection] = []
    failed: list[Detection] = []
    for index, (path, image) in enumerate(images):
        detection = detect_corners(image, board, str(path), subpix)
        (found if detection.found else failed).append(detection)
        if progress is not None:
            progress(index + 1, len(images), detection)
    return found, failed


def calibrate_intrinsics(
    paths: Sequence[str | Path],
    board: Chessboard,
    fix_aspect_ratio: bool = False,
    model: str = "standard",
    subpix: SubpixSettings | None = None,
    progress: Callable[[int, int, Detection], None] | None = None,
) -> IntrinsicResult:
    """Calibrate a camera's intrinsics (K and distortion) from chessboard images.

    Parameters
    ----------
    paths
        Image files, all the same size.
    board
        The chessboard shown in them.
    fix_aspect_ratio
        Keep fx/fy = 1 (``CALIB_FIX_ASPECT_RATIO`` with an identity initial K, as OpenCV's calibration sample).
    model
        ``"standard"`` (k1, k2, p1, p2, k3) or ``"rational"`` (adds k4, k5, k6).
    subpix
        Corner refinement settings.
    progress
        Called after each image with (done, total, detection).

    Raises
    ------
    DataError
        Unreadable files, mixed image sizes.
    CalibrationError
        Fewer than `MIN_VIEWS` views with a board (lists the failed files and reasons), or OpenCV fails.
    """
    if model not in MODELS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
    used, failed = detect_views(paths, board, subpix, progress)
    if len(used) < MIN_VIEWS:
        details = "; ".join(f"{d.source}: {d.reason}" for d in failed) or "none failed"
        raise CalibrationError(
            f"only {len(used)} of {len(paths)} images show a {board.cols}x{board.rows} board, at least {MIN_VIEWS} are "
            f"needed (failed: {details})"
        )
    size = used[0].image_size
    flags = MODELS[model]
    camera_matrix = np.eye(3)
    if fix_aspect_ratio:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO
    object_points = [board.object_points()] * len(used)
    image_points = [d.corners.reshape(-1, 1, 2) for d in used]
    try:
        rms, k, dist, rvecs, tvecs = cv2.calibrateCamera(
            object_points, image_points, size, camera_matrix, None, flags=flags
        )
    except cv2.error as exc:
        raise CalibrationError(f"cv2.calibrateCamera failed on {len(used)} views: {exc}") from exc
    camera = CameraModel(k, dist.ravel(), size)
    residuals = []
    for view_points, rvec, tvec in zip(image_points, rvecs, tvecs, strict=True):
        projected, _ = cv2.projectPoints(board.object_points(), rvec, tvec, k, dist)
        residuals.append(view_points.reshape(-1, 2) - projected.reshape(-1, 2))
    residuals_px = np.asarray(residuals, dtype=np.float64)
    per_view = np.sqrt(np.mean(np.sum(residuals_px**2, axis=-1), axis=-1))
    if not np.isfinite(rms) or not np.all(np.isfinite(k)):
        raise CalibrationError(f"calibration diverged on {len(used)} views (RMS {rms})")
    log.info("calibrated %d views: RMS %.4f px, fx %.3f fy %.3f", len(used), rms, camera.fx, camera.fy)
    return IntrinsicResult(
        camera=camera,
        rms_px=float(rms),
        used=used,
        failed=failed,
        per_view_rms_px=per_view,
        residuals_px=residuals_px,
        rvecs=np.asarray(rvecs, dtype=np.float64).reshape(-1, 3),
        tvecs=np.asarray(tvecs, dtype=np.float64).reshape(-1, 3),
        flags=flags,
        board=board,
    )
