"""The motion plane: its pose from a board lying in it, the rope's fixed end as origin, and the paper's error report.

The board is laid level in the plane, its rows horizontal; its frame (x along the rows towards +u, y along the
columns towards +v, see `ropecam.host.calibration.board`) is therefore the plane frame up to the origin, which is
moved to the rope's fixed end (paper, section "Experimental platform"). The error report follows the paper's
Fig. 15-16 and Table 3: reprojection errors of the corners in u and v (pixels) and what they are on the plane (mm).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.board import Chessboard, Detection, SubpixSettings, detect_corners
from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.shared.errors import CalibrationError

__all__ = ["DEFAULT_MAX_RMS_PX", "PlaneErrorReport", "PlaneResult", "calibrate_plane", "move_origin"]

# A board that reprojects worse than this with a good camera file means the camera file does not match the image.
DEFAULT_MAX_RMS_PX = 2.0


@dataclass(frozen=True)
class PlaneErrorReport:
    """The paper's error figures for the plane pose (absolute values; mean and max over the corners).

    ``*_px`` are reprojection errors (detected minus reprojected corner) along u and v; ``*_mm`` are the same
    errors mapped onto the plane (detected corner converted to the plane minus its true board position) along x, y.
    ``rotation_sigma_deg`` and ``translation_sigma_mm`` are 1-sigma pose uncertainties from the residuals.
    """

    mean_u_px: float
    max_u_px: float
    mean_v_px: float
    max_v_px: float
    rms_px: float
    mean_x_mm: float
    max_x_mm: float
    mean_y_mm: float
    max_y_mm: float
    rotation_sigma_deg: float
    translation_sigma_mm: NDArray[np.float64]

    def lines(self) -> list[str]:
        """Return the report as human-readable lines."""
        return [
            f"reprojection error u: mean {self.mean_u_px:.4f} px, max {self.max_u_px:.4f} px",
            f"reprojection error v: mean {self.mean_v_px:.4f} px, max {self.max_v_px:.4f} px"
            f"  (RMS {self.rms_px:.4f} px)",
            f"on the plane      x: mean {self.mean_x_mm:.4f} mm, max {self.max_x_mm:.4f} mm",
            f"on the plane      y: mean {self.mean_y_mm:.4f} mm, max {self.max_y_mm:.4f} mm",
            f"pose 1-sigma: rotation {self.rotation_sigma_deg:.4f} deg, translation "
            + ", ".join(f"{v:.3f}" for v in self.translation_sigma_mm)
            + " mm (x, y, z camera)",
        ]


@dataclass(frozen=True)
class PlaneResult:
    """Result of `calibrate_plane`.

    ``plane`` maps the plane frame (origin at the rope's fixed end) to the camera; ``board_pose`` maps the board
    frame (origin at the top-left inner corner); ``origin_board_m`` is the fixed end in board coordinates.
    ``corners_px`` are detected and ``reprojected_px`` reprojected corners, shape (n, 2).
    """

    camera: CameraModel
    board: Chessboard
    detection: Detection
    board_pose: PlanePose
    plane: PlanePose
    origin_board_m: NDArray[np.float64]
    corners_px: NDArray[np.float64]
    reprojected_px: NDArray[np.float64]
    report: PlaneErrorReport


def move_origin(board_pose: PlanePose, origin_board_m: NDArray[np.float64]) -> PlanePose:
    """Return the pose of the frame with the same axes as `board_pose` and its origin at `origin_board_m` (x, y)."""
    origin = np.array([origin_board_m[0], origin_board_m[1], 0.0])
    return PlanePose(board_pose.rotation, board_pose.translation_m + board_pose.rotation @ origin)


def _pose_sigma(
    object_points: NDArray[np.float32],
    rvec: NDArray[np.float64],
    tvec: NDArray[np.float64],
    camera: CameraModel,
    sse: float,
) -> tuple[float, NDArray[np.float64]]:
    _, jacobian = cv2.projectPoints(object_points, rvec, tvec, camera.camera_matrix, camera.distortion)
    j = jacobian[:, :6]
    dof = max(j.shape[0] - 6, 1)
    try:
        covariance = np.linalg.inv(j.T @ j) * (sse / dof)
    except np.linalg.LinAlgError:
        return float("nan"), np.full(3, np.nan)
    rotation_sigma_deg = float(np.degrees(np.sqrt(np.trace(covariance[:3, :3]))))
    return rotation_sigma_deg, np.sqrt(np.diag(covariance[3:, 3:])) * 1000.0


def calibrate_plane(
    image: NDArray[np.uint8],
    camera: CameraModel,
    board: Chessboard,
    origin_px: tuple[float, float] | None = None,
    origin_mm: tuple[float, float] | None = None,
    source: str = "<image>",
    subpix: SubpixSettings | None = None,
    max_rms_px: float = DEFAULT_MAX_RMS_PX,
    camera_source: str = "the camera file",
) -> PlaneResult:
    """Find the motion plane's pose from one image of a board lying level in it.

    Parameters
    ----------
    image
        Grayscale image, shape (height, width), uint8, from the calibrated camera in the same mode.
    camera
        The calibrated camera.
    board
        The board in the image.
    origin_px, origin_mm
        The rope's fixed end, as a distorted pixel (u, v) or in board coordinates (x, y) in mm from the top-left
        inner corner. At most one; default: the top-left inner corner.
    source
        Name used in messages (the file name).
    subpix
        Corner refinement settings.
    max_rms_px
        Refuse a pose whose corners reproject worse than this (the camera file does not fit the image).
    camera_source
        Name of the camera file, for messages.

    Raises
    ------
    CalibrationError
        Size mismatch between image and camera, no board, a poor fit, or a fixed end off the plane.
    """
    if origin_px is not None and origin_mm is not None:
        raise ValueError("give the fixed end either as origin_px or as origin_mm, not both")
    size = (int(image.shape[1]), int(image.shape[0]))
    if size != camera.image_size:
        raise CalibrationError(
            f"{source} is {size[0]}x{size[1]} px but {camera_source} was calibrated at "
            f"{camera.image_size[0]}x{camera.image_size[1]} px; use the camera file of this camera mode"
        )
    detection = detect_corners(image, board, source, subpix)
    if detection.corners is None:
        raise CalibrationError(f"{source}: {detection.reason}")
    corners = detection.corners.astype(np.float64)
    object_points = board.object_points()
    ok, rvec, tvec = cv2.solvePnP(
        object_points, corners, camera.camera_matrix, camera.distortion, flags=cv2.SOLVEPNP_IPPE
    )
    if not ok:
        raise CalibrationError(f"{source}: cv2.solvePnP found no pose for the board")
    rvec, tvec = cv2.solvePnPRefineLM(object_points, corners, camera.camera_matrix, camera.distortion, rvec, tvec)
    board_pose = PlanePose.from_rvec(rvec, tvec)
    if board_pose.translation_m[2] <= 0:
        raise CalibrationError(f"{source}: the board pose puts the board behind the camera")
    reprojected, _ = cv2.projectPoints(object_points, rvec, tvec, camera.camera_matrix, camera.distortion)
    reprojected = reprojected.reshape(-1, 2)
    residual = corners - reprojected
    sse = float(np.sum(residual**2))
    rms_px = float(np.sqrt(sse / len(corners)))
    if rms_px > max_rms_px:
        raise CalibrationError(
            f"{source}: the board reprojects with {rms_px:.2f} px RMS (limit {max_rms_px} px); {camera_source} does "
            "not match this image (another camera, lens, focus or image mode?)"
        )
    on_plane_m = pixels_to_plane(corners, camera, board_pose)
    plane_error_mm = (on_plane_m - object_points[:, :2]) * 1000.0
    rotation_sigma_deg, translation_sigma_mm = _pose_sigma(object_points, rvec, tvec, camera, sse)
    abs_res, abs_mm = np.abs(residual), np.abs(plane_error_mm)
    report = PlaneErrorReport(
        mean_u_px=float(abs_res[:, 0].mean()),
        max_u_px=float(abs_res[:, 0].max()),
        mean_v_px=float(abs_res[:, 1].mean()),
        max_v_px=float(abs_res[:, 1].max()),
        rms_px=rms_px,
        mean_x_mm=float(abs_mm[:, 0].mean()),
        max_x_mm=float(abs_mm[:, 0].max()),
        mean_y_mm=float(abs_mm[:, 1].mean()),
        max_y_mm=float(abs_mm[:, 1].max()),
        rotation_sigma_deg=rotation_sigma_deg,
        translation_sigma_mm=translation_sigma_mm,
    )
    if origin_px is not None:
        try:
            origin_board_m = pixels_to_plane(np.asarray(origin_px, dtype=np.float64), camera, board_pose)
        except ValueError as exc:
            raise CalibrationError(f"--origin-px {origin_px}: {exc}") from exc
    elif origin_mm is not None:
        origin_board_m = np.asarray(origin_mm, dtype=np.float64) / 1000.0
    else:
        origin_board_m = np.zeros(2)
    if not np.all(np.isfinite(origin_board_m)):
        raise CalibrationError(f"the fixed end {origin_px or origin_mm} is not a finite point on the plane")
    return PlaneResult(
        camera=camera,
        board=board,
        detection=detection,
        board_pose=board_pose,
        plane=move_origin(board_pose, origin_board_m),
        origin_board_m=origin_board_m,
        corners_px=corners,
        reprojected_px=reprojected,
        report=report,
    )
