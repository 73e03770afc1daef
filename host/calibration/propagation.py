"""Error propagation: what a pixel error means in millimetres on the motion plane, across the field of view.

The local Jacobian J = d(x, y)/d(u, v) of `pixels_to_plane` (central differences, mm per px) maps pixel errors
to plane errors. Independent errors with standard deviations (sigma_u, sigma_v) give
sigma_x = sqrt((J_xu sigma_u)^2 + (J_xv sigma_v)^2) (and likewise y); the paper's "maximum transformation range"
of an error (du, dv) is the worst case |J_xu| du + |J_xv| dv.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.shared.errors import CalibrationError

__all__ = ["ErrorMap", "error_table", "mm_per_px", "propagate_pixel_error"]

_STEP_PX = 0.5


def mm_per_px(pixels: ArrayLike, camera: CameraModel, plane: PlanePose) -> NDArray[np.float64]:
    """Return the Jacobian d(x, y)/d(u, v) of the pixel-to-plane conversion in mm per px, shape (..., 2, 2).

    ``J[..., 0, 1]`` is dx/dv: how many mm along the plane's x one pixel along v moves the point.

    Raises
    ------
    CalibrationError
        A pixel's ray does not meet the plane in front of the camera.
    """
    uv = np.asarray(pixels, dtype=np.float64)
    flat = uv.reshape(-1, 2)
    shifts = np.array([[_STEP_PX, 0.0], [-_STEP_PX, 0.0], [0.0, _STEP_PX], [0.0, -_STEP_PX]])
    probes = (flat[:, None, :] + shifts[None, :, :]).reshape(-1, 2)
    try:
        xy = pixels_to_plane(probes, camera, plane).reshape(-1, 4, 2) * 1000.0
    except ValueError as exc:
        raise CalibrationError(f"cannot propagate errors: {exc}") from exc
    d_du = (xy[:, 0] - xy[:, 1]) / (2 * _STEP_PX)
    d_dv = (xy[:, 2] - xy[:, 3]) / (2 * _STEP_PX)
    jacobian = np.stack([d_du, d_dv], axis=-1)  # (n, 2 [x, y], 2 [u, v])
    return jacobian.reshape(*uv.shape[:-1], 2, 2)


@dataclass(frozen=True)
class ErrorMap:
    """Plane-position uncertainty on a pixel grid.

    ``u_px`` (nu,), ``v_px`` (nv,) are the grid; ``sigma_x_mm``, ``sigma_y_mm`` (nv, nu) the 1-sigma errors along
    the plane's x and y for independent pixel errors ``sigma_u_px``, ``sigma_v_px``; ``sigma_max_mm`` the major
    semi-axis of the error ellipse.
    """

    u_px: NDArray[np.float64]
    v_px: NDArray[np.float64]
    sigma_u_px: float
    sigma_v_px: float
    sigma_x_mm: NDArray[np.float64]
    sigma_y_mm: NDArray[np.float64]
    sigma_max_mm: NDArray[np.float64]


def _grid(camera: CameraModel, step_px: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    width, height = camera.image_size
    u = np.linspace(0.0, width - 1.0, max(2, round((width - 1) / step_px) + 1))
    v = np.linspace(0.0, height - 1.0, max(2, round((height - 1) / step_px) + 1))
    return u, v


def propagate_pixel_error(
    camera: CameraModel, plane: PlanePose, sigma_u_px: float, sigma_v_px: float | None = None, step_px: float = 16.0
) -> ErrorMap:
    """Map independent pixel errors (sigma_u, sigma_v; px) to plane errors (mm) over the whole image.

    Parameters
    ----------
    camera, plane
        The conversion (as in `pixels_to_plane`).
    sigma_u_px, sigma_v_px
        Pixel uncertainty along u and v; `sigma_v_px` defaults to `sigma_u_px`.
    step_px
        Grid spacing in pixels.
    """
    sigma_v_px = sigma_u_px if sigma_v_px is None else sigma_v_px
    if sigma_u_px < 0 or sigma_v_px < 0 or step_px <= 0:
        raise ValueError(f"pixel sigmas must be >= 0 and step_px > 0, got {sigma_u_px}, {sigma_v_px}, {step_px}")
    u, v = _grid(camera, step_px)
    uu, vv = np.meshgrid(u, v)
    j = mm_per_px(np.stack([uu, vv], axis=-1), camera, plane)
    scaled = j * np.array([sigma_u_px, sigma_v_px])  # columns scaled by the pixel sigmas
    sigma_x = np.hypot(scaled[..., 0, 0], scaled[..., 0, 1])
    sigma_y = np.hypot(scaled[..., 1, 0], scaled[..., 1, 1])
    sigma_max = np.linalg.svd(scaled, compute_uv=False)[..., 0]
    return ErrorMap(u, v, float(sigma_u_px), float(sigma_v_px), sigma_x, sigma_y, sigma_max)


def error_table(
    camera: CameraModel,
    plane: PlanePose,
    mean_uv_px: tuple[float, float],
    max_uv_px: tuple[float, float],
    step_px: float = 16.0,
) -> dict[str, float]:
    """The paper's Table 3: plane errors (mm) caused by the mean and the maximum pixel errors, over the image.

    ``average_x_mm`` is the mean over the image of the worst-case x error of a (mean_u, mean_v) pixel error;
    ``maximum_x_mm`` the largest over the image of the worst-case x error of a (max_u, max_v) pixel error.
    """
    u, v = _grid(camera, step_px)
    uu, vv = np.meshgrid(u, v)
    j = np.abs(mm_per_px(np.stack([uu, vv], axis=-1), camera, plane))
    mean_err = j @ np.asarray(mean_uv_px, dtype=np.float64)
    max_err = j @ np.asarray(max_uv_px, dtype=np.float64)
    return {
        "average_x_mm": float(mean_err[..., 0].mean()),
        "maximum_x_mm": float(max_err[..., 0].max()),
        "average_y_mm": float(mean_err[..., 1].mean()),
        "maximum_y_mm": float(max_err[..., 1].max()),
    }
