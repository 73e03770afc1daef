"""Simulated chessboard views with ground truth: the calibration sets of the simulated rig.

Every output pixel is traced exactly: its supersampled positions are undistorted to viewing rays (OpenCV's iterative
inverse of the distortion model, run to convergence), each ray is intersected with the board plane, and the board's
printed pattern (anti-aliased by the supersampling) gives the grey level. A mild Gaussian blur stands in for the lens
PSF, then seeded Gaussian sensor noise is added. The rays depend only on the camera, so a whole set shares them.

A calibration set is a list of views covering the field of view with tilts of 15-45 degrees, plus one view of a board
lying level in the motion plane, together with the true camera, the true plane pose and the rope's fixed end.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.board import Chessboard
from ropecam.host.calibration.geometry import CameraModel, PlanePose, plane_to_pixels
from ropecam.shared.errors import DataError

__all__ = [
    "BoardArt",
    "CalibrationSet",
    "RenderSettings",
    "View",
    "make_calibration_set",
    "paper_camera",
    "pixel_rays",
    "read_calibration_set",
    "render_board_view",
    "write_calibration_set",
]

TRUTH_FILE = "truth.json"


def paper_camera() -> CameraModel:
    """Return the paper's recalibrated camera: 1024x544 px, fx 1495.2, fy 1483.3, k1 -0.1793, k2 0.3891."""
    k = np.array([[1495.2341, 0.0, 508.0598], [0.0, 1483.2726, 275.6076], [0.0, 0.0, 1.0]])
    return CameraModel(k, np.array([-0.1793, 0.3891, 0.0, 0.0, 0.0]), (1024, 544))


@dataclass(frozen=True, slots=True)
class BoardArt:
    """A printed chessboard: the pattern, the white paper margin around the squares and the grey levels."""

    board: Chessboard = field(default_factory=lambda: Chessboard(8, 7, 0.020))
    margin_m: float = 0.015
    dark: float = 25.0
    light: float = 215.0
    background: float = 70.0

    def __post_init__(self) -> None:
        if self.margin_m < 0:
            raise ValueError(f"margin_m must be >= 0, got {self.margin_m}")


@dataclass(frozen=True, slots=True)
class RenderSettings:
    """Rendering options: ``supersample`` x ``supersample`` samples per pixel, blur and noise in grey levels."""

    supersample: int = 1
    blur_sigma_px: float = 0.5
    noise_std: float = 2.0

    def __post_init__(self) -> None:
        if not 1 <= self.supersample <= 8:
            raise ValueError(f"supersample must be in [1, 8], got {self.supersample}")
        if self.blur_sigma_px < 0 or self.noise_std < 0:
            raise ValueError(f"blur_sigma_px and noise_std must be >= 0, got {self.blur_sigma_px}, {self.noise_std}")


def _coverage(x: NDArray[np.float64], half: NDArray[np.float64], lo: float, hi: float) -> NDArray[np.float64]:
    """Fraction of [x - half, x + half] inside [lo, hi]."""
    with np.errstate(invalid="ignore"):
        overlap = np.minimum(x + half, hi) - np.maximum(x - half, lo)
        return np.nan_to_num(np.clip(overlap / (2 * half), 0.0, 1.0))


def _square_wave_mean(q: NDArray[np.float64], half: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean over [q - half, q + half] of the square wave that is +1 where floor(q) is even, -1 where odd."""

    def integral(t: NDArray[np.float64]) -> NDArray[np.float64]:  # triangle wave: 0 at even, 1 at odd integers
        return 1.0 - np.abs(np.mod(t, 2.0) - 1.0)

    with np.errstate(invalid="ignore"):
        mean = (integral(q + half) - integral(q - half)) / (2 * half)
        # Footprints narrower than float resolution: the point value.
        point = np.where(np.mod(np.floor(q), 2.0) == 0, 1.0, -1.0)
        return np.nan_to_num(np.where(half > 1e-6, mean, point))


def pixel_rays(camera: CameraModel, supersample: int) -> NDArray[np.float64]:
    """Return normalised undistorted coordinates of every sub-pixel sample, shape (H, s, W, s, 2).

    Sample (row, i, col, j) sits at u = col + (j + 0.5)/s - 0.5, v = row + (i + 0.5)/s - 0.5.
    """
    width, height = camera.image_size
    s = supersample
    offsets = (np.arange(s) + 0.5) / s - 0.5
    u = (np.arange(width)[:, None] + offsets[None, :]).ravel()
    v = (np.arange(height)[:, None] + offsets[None, :]).ravel()
    uu, vv = np.meshgrid(u, v)
    normalised = camera.undistort(np.stack([uu, vv], axis=-1))
    return normalised.reshape(height, s, width, s, 2)


def render_board_view(
    camera: CameraModel,
    pose: PlanePose,
    art: BoardArt,
    rng: np.random.Generator,
    settings: RenderSettings | None = None,
    rays: NDArray[np.float64] | None = None,
) -> NDArray[np.uint8]:
    """Render a grayscale image of a chessboard at `pose` seen by `camera`.

    Parameters
    ----------
    camera
        The camera (with distortion) that sees the board.
    pose
        Board pose: ``X_camera = R @ X_board + t`` (metres); board frame as `Chessboard.object_points`.
    art
        The printed board.
    rng
        Noise source (seed it for reproducible views).
    settings
        Supersampling, blur and noise; default `RenderSettings()`.
    rays
        Precomputed `pixel_rays(camera, settings.supersample)`, to share between views.

    Returns
    -------
    ndarray
        Shape (height, width), uint8.
    """
    settings = settings or RenderSettings()
    if rays is None:
        rays = pixel_rays(camera, settings.supersample)
    width, height = camera.image_size
    if rays.shape[:4] != (height, settings.supersample, width, settings.supersample):
        raise ValueError(f"rays have shape {rays.shape}, expected pixel_rays(camera, {settings.supersample})")
    r, t = pose.rotation, pose.translation_m
    origin_b = -r.T @ t
    # Direction in the board frame of ray (x, y, 1): R^T @ ray, written out to avoid an (N, 3) temporary.
    dx = rays[..., 0] * r[0, 0] + rays[..., 1] * r[1, 0] + r[2, 0]
    dy = rays[..., 0] * r[0, 1] + rays[..., 1] * r[1, 1] + r[2, 1]
    dz = rays[..., 0] * r[0, 2] + rays[..., 1] * r[1, 2] + r[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = -origin_b[2] / dz
    x = origin_b[0] + depth * dx
    y = origin_b[1] + depth * dy
    board = art.board
    sq = board.square_m
    h, ss, w = rays.shape[0], rays.shape[1], rays.shape[2]
    x = x.reshape(h * ss, w * ss)
    y = y.reshape(h * ss, w * ss)
    behind = ~(depth.reshape(h * ss, w * ss) > 0)
    x[behind] = np.inf
    y[behind] = np.inf
    # Each sample is box-filtered over its footprint on the board (half widths from the local Jacobian), so edges
    # and corners are exact to first order instead of quantised by the sample grid.
    with np.errstate(invalid="ignore"):
        half_x = 0.5 * (np.abs(np.gradient(x, axis=0)) + np.abs(np.gradient(x, axis=1))) + 1e-12
        half_y = 0.5 * (np.abs(np.gradient(y, axis=0)) + np.abs(np.gradient(y, axis=1))) + 1e-12
    lo_x, hi_x = -sq - art.margin_m, board.cols * sq + art.margin_m
    lo_y, hi_y = -sq - art.margin_m, board.rows * sq + art.margin_m
    paper = _coverage(x, half_x, lo_x, hi_x) * _coverage(y, half_y, lo_y, hi_y)
    squares = _coverage(x, half_x, -sq, board.cols * sq) * _coverage(y, half_y, -sq, board.rows * sq)
    # Square (i, j) (floor of x/sq, y/sq) is dark when i + j is even: the top-left square is dark.
    darkness = 0.5 + 0.5 * _square_wave_mean(x / sq, half_x / sq) * _square_wave_mean(y / sq, half_y / sq)
    samples = art.background + paper * (art.light - art.background) - squares * darkness * (art.light - art.dark)
    samples = np.where(behind, art.background, samples).reshape(h, ss, w, ss)
    image = samples.mean(axis=(1, 3))
    if settings.blur_sigma_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), settings.blur_sigma_px)
    if settings.noise_std > 0:
        image = image + rng.normal(0.0, settings.noise_std, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class View:
    """One rendered view and its true board pose."""

    name: str
    image: NDArray[np.uint8]
    pose: PlanePose


@dataclass(frozen=True)
class CalibrationSet:
    """Intrinsic views, the motion-plane views and the truth.

    ``plane_view`` shows the board lying level near the rope's fixed end; ``extra_plane_views`` show it lying
    elsewhere in the same plane (rotated a little within the plane), to pin the plane's tilt down.

    ``plane_pose`` maps the plane frame (origin at the rope's fixed end, x horizontal, y down) to the camera;
    ``origin_mm`` is the fixed end in board coordinates of the plane view, ``origin_px`` its true distorted pixel.
    """

    camera: CameraModel
    art: BoardArt
    views: list[View]
    plane_view: View
    extra_plane_views: list[View]
    plane_pose: PlanePose
    origin_mm: tuple[float, float]
    origin_px: tuple[float, float]
    seed: int


def _rotation(tilt_x_rad: float, tilt_y_rad: float, roll_rad: float) -> NDArray[np.float64]:
    rx, _ = cv2.Rodrigues(np.array([tilt_x_rad, 0.0, 0.0]))
    ry, _ = cv2.Rodrigues(np.array([0.0, tilt_y_rad, 0.0]))
    rz, _ = cv2.Rodrigues(np.array([0.0, 0.0, roll_rad]))
    return rz @ rx @ ry


def _paper_outline(art: BoardArt) -> NDArray[np.float64]:
    s, b = art.board.square_m, art.board
    lo_x, hi_x = -s - art.margin_m, b.cols * s + art.margin_m
    lo_y, hi_y = -s - art.margin_m, b.rows * s + art.margin_m
    xs, ys = np.linspace(lo_x, hi_x, 9), np.linspace(lo_y, hi_y, 9)
    edge = [(x, lo_y) for x in xs] + [(x, hi_y) for x in xs] + [(lo_x, y) for y in ys] + [(hi_x, y) for y in ys]
    return np.array(edge)


def _fits(camera: CameraModel, pose: PlanePose, art: BoardArt, margin_px: float) -> bool:
    outline = _paper_outline(art)
    camera_z = (outline @ pose.rotation[:, :2].T + pose.translation_m)[:, 2]
    if np.any(camera_z <= 0.05):
        return False
    uv = plane_to_pixels(outline, camera, pose)
    width, height = camera.image_size
    return bool(
        np.all(uv[:, 0] >= margin_px)
        and np.all(uv[:, 0] <= width - 1 - margin_px)
        and np.all(uv[:, 1] >= margin_px)
        and np.all(uv[:, 1] <= height - 1 - margin_px)
    )


def _intrinsic_poses(camera: CameraModel, art: BoardArt, n_views: int, rng: np.random.Generator) -> list[PlanePose]:
    """Poses whose boards cover the image: targets on a grid, tilts of 15-45 degrees in varied directions."""
    width, height = camera.image_size
    board = art.board
    centre_b = np.array([(board.cols - 1) * board.square_m / 2, (board.rows - 1) * board.square_m / 2, 0.0])
    board_span_m = max(board.cols + 1, board.rows + 1) * board.square_m + 2 * art.margin_m
    # Distance at which the board's longer side spans about 90 % of the image's shorter side.
    base_distance_m = min(camera.fx, camera.fy) * board_span_m / (0.90 * min(width, height))
    grid_u = np.linspace(0.22, 0.78, 4) * width
    grid_v = np.linspace(0.35, 0.65, 2) * height
    targets = [(u, v) for v in grid_v for u in grid_u]
    poses: list[PlanePose] = []
    attempts = failures = 0
    while len(poses) < n_views:
        attempts += 1
        if attempts > 300 * n_views:
            raise ValueError(f"could not place {n_views} boards of {board.describe()} in a {width}x{height} image")
        u, v = targets[len(poses) % len(targets)]
        u += rng.uniform(-0.05, 0.05) * width
        v += rng.uniform(-0.05, 0.05) * height
        tilt_rad = math.radians(rng.uniform(15.0, 45.0))
        direction = rng.uniform(0.0, 2.0 * math.pi) if len(poses) >= 4 else len(poses) * math.pi / 2
        rotation = _rotation(tilt_rad * math.cos(direction), tilt_rad * math.sin(direction), rng.uniform(-0.2, 0.2))
        # Step back a little after each run of boards that did not fit (small or square images).
        distance_m = base_distance_m * rng.uniform(0.85, 1.25) * (1.0 + 0.05 * (failures // 10))
        ray = np.append(camera.undistort([u, v]), 1.0)
        pose = PlanePose(rotation, distance_m * ray / np.linalg.norm(ray) - rotation @ centre_b)
        if _fits(camera, pose, art, margin_px=4.0):
            poses.append(pose)
            failures = 0
        else:
            failures += 1
    return poses


def make_calibration_set(
    camera: CameraModel | None = None,
    art: BoardArt | None = None,
    n_views: int = 50,
    plane_distance_m: float = 1.5,
    seed: int = 0,
    settings: RenderSettings | None = None,
    n_extra_plane_views: int = 2,
    plane_pose: PlanePose | None = None,
) -> CalibrationSet:
    """Render a complete calibration set with its ground truth.

    Parameters
    ----------
    camera
        True camera; default `paper_camera()`.
    art
        Printed board; default 8x7 inner corners, 20 mm squares, 15 mm white margin.
    n_views
        Number of intrinsic views (>= 4).
    plane_distance_m
        Distance from the camera to the rope's fixed end in the motion plane.
    seed
        Seeds poses and noise.
    settings
        Rendering options.
    n_extra_plane_views
        Further views of the board lying in the motion plane, left and right of the first (0-2).
    plane_pose
        The motion plane (origin at the rope's fixed end), e.g. a simulator preset's, so that rope frames and
        calibration set share one plane; default: a nearly fronto-parallel plane at `plane_distance_m`, drawn from
        the seed.

    Returns
    -------
    CalibrationSet
        The motion plane is almost fronto-parallel (a few degrees of tilt and roll); the plane board lies level in
        it, its top-left inner corner 30 mm right of and 60 mm below the rope's fixed end, which sits a little above
        the image centre.
    """
    camera = camera or paper_camera()
    art = art or BoardArt()
    settings = settings or RenderSettings()
    if n_views < 4:
        raise ValueError(f"n_views must be >= 4, got {n_views}")
    rng = np.random.default_rng(seed)
    rays = pixel_rays(camera, settings.supersample)
    views = [
        View(f"view_{i:02d}", render_board_view(camera, pose, art, rng, settings, rays), pose)
        for i, pose in enumerate(_intrinsic_poses(camera, art, n_views, rng))
    ]
    width, height = camera.image_size
    fixed_end_px = np.array([0.5 * width + rng.uniform(-20, 20), 0.3 * height + rng.uniform(-10, 10)])
    ray = np.append(camera.undistort(fixed_end_px), 1.0)
    plane_rotation = _rotation(
        math.radians(rng.uniform(-4, 4)), math.radians(rng.uniform(-4, 4)), rng.uniform(-0.02, 0.02)
    )
    if plane_pose is None:
        plane_pose = PlanePose(plane_rotation, plane_distance_m * ray / np.linalg.norm(ray))
    else:
        plane_rotation = plane_pose.rotation
        plane_distance_m = float(np.linalg.norm(plane_pose.translation_m))
    board_origin_in_plane_m = np.array([0.030, 0.060, 0.0])
    board_pose = PlanePose(plane_rotation, plane_pose.translation_m + plane_rotation @ board_origin_in_plane_m)
    plane_view = View("plane", render_board_view(camera, board_pose, art, rng, settings, rays), board_pose)
    if not 0 <= n_extra_plane_views <= 2:
        raise ValueError(f"n_extra_plane_views must be 0, 1 or 2, got {n_extra_plane_views}")
    extra_plane_views = []
    half_width_m = 0.5 * width / camera.fx * plane_distance_m
    board_width_m = (art.board.cols + 1) * art.board.square_m + 2 * art.margin_m
    for index, side in enumerate((-1.0, 1.0)[:n_extra_plane_views]):
        angle = math.radians(rng.uniform(-6.0, 6.0))
        rotation_in_plane = _rotation(0.0, 0.0, angle)
        for reach in np.linspace(0.85, 0.3, 12):  # as far out as the image allows
            x0 = side * reach * half_width_m - (0.5 + 0.5 * side) * board_width_m * 0.8
            corner_in_plane = np.array([x0, 0.13, 0.0])
            pose = PlanePose(
                plane_rotation @ rotation_in_plane, plane_pose.translation_m + plane_rotation @ corner_in_plane
            )
            if _fits(camera, pose, art, margin_px=4.0):
                break
        else:
            raise ValueError(f"no room for a second board in the plane in a {width}x{height} image")
        image = render_board_view(camera, pose, art, rng, settings, rays)
        extra_plane_views.append(View(f"plane_{index + 1:02d}", image, pose))
    origin_px = plane_to_pixels(np.zeros(2), camera, plane_pose)
    return CalibrationSet(
        camera=camera,
        art=art,
        views=views,
        plane_view=plane_view,
        extra_plane_views=extra_plane_views,
        plane_pose=plane_pose,
        origin_mm=(-board_origin_in_plane_m[0] * 1000, -board_origin_in_plane_m[1] * 1000),
        origin_px=(float(origin_px[0]), float(origin_px[1])),
        seed=seed,
    )


def _pose_json(pose: PlanePose) -> dict[str, list[float]]:
    return {"rvec": pose.rvec.tolist(), "tvec_m": pose.translation_m.tolist(), "rotation": pose.rotation.tolist()}


def write_calibration_set(calib_set: CalibrationSet, folder: str | Path) -> Path:
    """Write the views as PNG files and the truth as ``truth.json`` into `folder` (created); return the JSON path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for view in [*calib_set.views, calib_set.plane_view, *calib_set.extra_plane_views]:
        path = folder / f"{view.name}.png"
        if not cv2.imwrite(str(path), view.image):
            raise DataError(f"{path}: cannot write image")
    camera, board = calib_set.camera, calib_set.art.board
    truth = {
        "what": "ropecam simulated calibration set: intrinsic views view_*.png, the motion-plane view plane.png (board "
        "level near the rope's fixed end) and plane_NN.png (the board elsewhere in the same plane)",
        "seed": calib_set.seed,
        "image_width": camera.image_size[0],
        "image_height": camera.image_size[1],
        "camera_matrix": camera.camera_matrix.tolist(),
        "distortion_coefficients": camera.distortion.tolist(),
        "board": {"cols": board.cols, "rows": board.rows, "square_mm": board.square_m * 1000},
        "views": {view.name: _pose_json(view.pose) for view in calib_set.views},
        "plane_board_pose": _pose_json(calib_set.plane_view.pose),
        "extra_plane_board_poses": {view.name: _pose_json(view.pose) for view in calib_set.extra_plane_views},
        "plane_pose": _pose_json(calib_set.plane_pose),
        "origin_mm": list(calib_set.origin_mm),
        "origin_px": list(calib_set.origin_px),
        "conventions": "X_camera = R X + t; plane frame: x horizontal, y down, origin at the rope's fixed end, metres",
    }
    path = folder / TRUTH_FILE
    path.write_text(json.dumps(truth, indent=1))
    return path


def read_calibration_set(folder: str | Path) -> tuple[CameraModel, PlanePose, dict]:
    """Read the true camera and plane pose (and the whole truth mapping) of a set written by `write_calibration_set`.

    Raises
    ------
    DataError
        ``truth.json`` is missing or malformed (the message names it).
    """
    path = Path(folder) / TRUTH_FILE
    try:
        truth = json.loads(path.read_text())
        camera = CameraModel(
            np.array(truth["camera_matrix"]),
            np.array(truth["distortion_coefficients"]),
            (truth["image_width"], truth["image_height"]),
        )
        plane = PlanePose.from_rvec(truth["plane_pose"]["rvec"], truth["plane_pose"]["tvec_m"])
    except FileNotFoundError as exc:
        raise DataError(f"{path}: truth file not found") from exc
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DataError(f"{path}: malformed truth file: {exc}") from exc
    return camera, plane, truth
