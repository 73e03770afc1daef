"""The motion plane: its pose from a board lying in it, the rope's fixed end as origin, and the paper's error report.

The board is laid level in the plane, its rows horizontal; its frame (x along the rows towards +u, y along the
columns towards +v, see `ropecam.host.calibration.board`) is therefore the plane frame up to the origin, which is
moved to the rope's fixed end (paper, section "Experimental platform"). The error report follows the paper's
Fig. 15-16 and Table 3: reprojection errors of the corners in u and v (pixels) and what they are on the plane (mm).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.board import Chessboard, Detection, SubpixSettings, detect_corners
from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.shared.errors import CalibrationError

__all__ = ["DEFAULT_MAX_RMS_PX", "PlaneErrorReport", "PlaneResult", "calibrate_plane", "move_origin"]

# A board that reprojects worse than this with a good camera file means the camera file does not match the image.
DEFAULT_MAX_RMS_PX = 1.0


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
    frame (origin at the top-left inner corner of the first image's board); ``origin_board_m`` is the fixed end in
    those board coordinates. ``corners_px`` are detected and ``reprojected_px`` reprojected corners of all boards
    (first image first), shape (n_boards * n_corners, 2).
    """

    camera: CameraModel
    board: Chessboard
    detections: list[Detection]
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


def _inplane(params: NDArray[np.float64], board: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation and translation (m) taking board `board`'s frame into the first board's frame, within the plane.

    Board 0 is the reference; board i > 0 has (angle about z in rad, x, y) at params[3 + 3 i : 6 + 3 i].
    """
    if board == 0:
        return np.eye(3), np.zeros(3)
    angle, x, y = params[3 + 3 * board : 6 + 3 * board]
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.array([x, y, 0.0])


def _project_all(params: NDArray[np.float64], object_points: NDArray[np.float64], camera: CameraModel, n_boards: int):
    """Project every board's corners; params = plane rvec (3), t (3), then (angle, x, y) per extra board."""
    r_plane, _ = cv2.Rodrigues(params[:3])
    t_plane = params[3:6]
    projected = []
    for i in range(n_boards):
        r_in, t_in = _inplane(params, i)
        rvec, _ = cv2.Rodrigues(r_plane @ r_in)
        tvec = r_plane @ t_in + t_plane
        uv, _ = cv2.projectPoints(object_points, rvec, tvec, camera.camera_matrix, camera.distortion)
        projected.append(uv.reshape(-1, 2))
    return np.concatenate(projected)


def _single_pose(corners: NDArray[np.float64], object_points: NDArray[np.float64], camera: CameraModel, source: str):
    ok, rvec, tvec = cv2.solvePnP(
        object_points, corners, camera.camera_matrix, camera.distortion, flags=cv2.SOLVEPNP_IPPE
    )
    if not ok:
        raise CalibrationError(f"{source}: cv2.solvePnP found no pose for the board")
    rvec, tvec = cv2.solvePnPRefineLM(object_points, corners, camera.camera_matrix, camera.distortion, rvec, tvec)
    if tvec.ravel()[2] <= 0:
        raise CalibrationError(f"{source}: the board pose puts the board behind the camera")
    return PlanePose.from_rvec(rvec, tvec)


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
    extra_images: Sequence[tuple[str, NDArray[np.uint8]]] = (),
) -> PlaneResult:
    """Find the motion plane's pose from an image of a board lying level in it (and optionally more placements).

    Parameters
    ----------
    image
        Grayscale image, shape (height, width), uint8, from the calibrated camera in the same mode. Its board
        gives the plane's axes (x along its rows) and, with `origin_px`/`origin_mm`, the origin.
    camera
        The calibrated camera.
    board
        The board in the images.
    origin_px, origin_mm
        The rope's fixed end, as a distorted pixel (u, v) or in board coordinates (x, y) in mm from the top-left
        inner corner of the board in `image`. At most one; default: that corner.
    source
        Name of `image` used in messages (the file name).
    subpix
        Corner refinement settings.
    max_rms_px
        Refuse a board whose corners reproject worse than this (the camera file does not fit the image).
    camera_source
        Name of the camera file, for messages.
    extra_images
        (name, image) pairs showing the same board lying elsewhere in the same plane (any in-plane rotation). All
        boards are fitted together: one plane pose plus an in-plane offset per extra board. A small board far from
        the camera fixes the plane's tilt poorly (the paper's board: about 0.05 degrees); boards spread over the
        field of view fix it several times better.

    Raises
    ------
    CalibrationError
        Size mismatch between an image and the camera, no board, a poor fit, or a fixed end off the plane.
    """
    if origin_px is not None and origin_mm is not None:
        raise ValueError("give the fixed end either as origin_px or as origin_mm, not both")
    object_points = board.object_points().astype(np.float64)  # float32 points project to float32 pixels
    detections = []
    for name, picture in [(source, image), *extra_images]:
        size = (int(picture.shape[1]), int(picture.shape[0]))
        if size != camera.image_size:
            raise CalibrationError(
                f"{name} is {size[0]}x{size[1]} px but {camera_source} was calibrated at "
                f"{camera.image_size[0]}x{camera.image_size[1]} px; use the camera file of this camera mode"
            )
        detection = detect_corners(picture, board, name, subpix)
        if detection.corners is None:
            raise CalibrationError(f"{name}: {detection.reason}")
        detections.append(detection)
    corner_sets = [d.corners.astype(np.float64) for d in detections]
    poses = [_single_pose(c, object_points, camera, d.source) for c, d in zip(corner_sets, detections, strict=True)]
    for corners, pose, detection in zip(corner_sets, poses, detections, strict=True):
        single = _project_all(np.concatenate([pose.rvec, pose.translation_m]), object_points, camera, 1)
        rms_px = float(np.sqrt(np.mean(np.sum((corners - single) ** 2, axis=1))))
        if rms_px > max_rms_px:
            raise CalibrationError(
                f"{detection.source}: the board reprojects with {rms_px:.2f} px RMS (limit {max_rms_px} px); "
                f"{camera_source} does not match this image (another camera, lens, focus or image mode?)"
            )
    # Initial in-plane offsets of the extra boards from their own poses, expressed in the first board's frame.
    first = poses[0]
    initial = [first.rvec, first.translation_m]
    for pose in poses[1:]:
        relative_r = first.rotation.T @ pose.rotation
        relative_t = first.rotation.T @ (pose.translation_m - first.translation_m)
        initial.append(np.array([np.arctan2(relative_r[1, 0], relative_r[0, 0]), relative_t[0], relative_t[1]]))
    observed = np.concatenate(corner_sets)
    params = np.concatenate(initial)
    n_boards = len(detections)
    if n_boards > 1:
        from scipy.optimize import least_squares

        fit = least_squares(
            lambda p: (_project_all(p, object_points, camera, n_boards) - observed).ravel(), params, method="lm"
        )
        params = fit.x
    reprojected = _project_all(params, object_points, camera, n_boards)
    residual = observed - reprojected
    sse = float(np.sum(residual**2))
    board_pose = PlanePose.from_rvec(params[:3], params[3:6])
    rotation_sigma_deg, translation_sigma_mm = _pose_sigma(params, object_points, camera, n_boards, sse)
    in_plane = [object_points @ r_in.T + t_in for r_in, t_in in (_inplane(params, i) for i in range(n_boards))]
    plane_error_mm = (pixels_to_plane(observed, camera, board_pose) - np.concatenate(in_plane)[:, :2]) * 1000.0
    abs_res, abs_mm = np.abs(residual), np.abs(plane_error_mm)
    report = PlaneErrorReport(
        mean_u_px=float(abs_res[:, 0].mean()),
        max_u_px=float(abs_res[:, 0].max()),
        mean_v_px=float(abs_res[:, 1].mean()),
        max_v_px=float(abs_res[:, 1].max()),
        rms_px=float(np.sqrt(sse / len(observed))),
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
        detections=detections,
        board_pose=board_pose,
        plane=move_origin(board_pose, origin_board_m),
        origin_board_m=origin_board_m,
        corners_px=observed,
        reprojected_px=reprojected,
        report=report,
    )


def _pose_sigma(
    params: NDArray[np.float64], object_points: NDArray[np.float64], camera: CameraModel, n_boards: int, sse: float
) -> tuple[float, NDArray[np.float64]]:
    """1-sigma rotation (deg) and translation (mm) of the plane pose from a numerical Jacobian of the fit."""
    step = 1e-6  # rad and m: far above float64 noise of the projection, far below its curvature
    base = _project_all(params, object_points, camera, n_boards).ravel()
    columns = []
    for i in range(len(params)):
        shifted = params.copy()
        shifted[i] += step
        columns.append((_project_all(shifted, object_points, camera, n_boards).ravel() - base) / step)
    jacobian = np.column_stack(columns)
    dof = max(jacobian.shape[0] - jacobian.shape[1], 1)
    try:
        covariance = np.linalg.inv(jacobian.T @ jacobian) * (sse / dof)
    except np.linalg.LinAlgError:
        return float("nan"), np.full(3, np.nan)
    rotation_sigma_deg = float(np.degrees(np.sqrt(np.trace(covariance[:3, :3]))))
    return rotation_sigma_deg, np.sqrt(np.diag(covariance[3:6, 3:6])) * 1000.0
