"""PNG reports of the calibrations: view coverage and residuals; the plane's corners, residuals and error map."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ropecam.host.calibration.geometry import plane_to_pixels
from ropecam.host.calibration.intrinsics import IntrinsicResult
from ropecam.host.calibration.plane import PlaneResult
from ropecam.host.calibration.propagation import ErrorMap
from ropecam.shared.errors import DataError

__all__ = ["plot_intrinsics_report", "plot_plane_report"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fig.savefig(path, dpi=110)
    except OSError as exc:
        raise DataError(f"{path}: cannot write report: {exc}") from exc
    finally:
        _pyplot().close(fig)
    return path


def _image_axes(ax, size: tuple[int, int], title: str) -> None:
    width, height = size
    ax.set_xlim(-0.5, width - 0.5)
    ax.set_ylim(height - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    ax.set_title(title, fontsize=10)


def plot_intrinsics_report(result: IntrinsicResult, path: str | Path) -> Path:
    """Write a PNG with the view coverage, the residual vectors and the per-view RMS of an intrinsic calibration."""
    plt = _pyplot()
    camera = result.camera
    fig, axes = plt.subplots(1, 3, figsize=(17, 5.2), gridspec_kw={"width_ratios": [1.25, 1.25, 1]})
    colours = plt.cm.tab20(np.linspace(0, 1, max(len(result.used), 2)))
    ax = axes[0]
    for detection, colour in zip(result.used, colours, strict=False):
        grid = detection.corners.reshape(result.board.rows, result.board.cols, 2)
        outline = np.concatenate([grid[0], grid[1:, -1], grid[-1, ::-1], grid[::-1, 0]])
        ax.fill(outline[:, 0], outline[:, 1], color=colour, alpha=0.18)
        ax.plot(grid[..., 0].ravel(), grid[..., 1].ravel(), ".", ms=2, color=colour)
    _image_axes(ax, camera.image_size, f"coverage: {len(result.used)} views, {result.board.describe()}")
    ax = axes[1]
    points = np.concatenate([d.corners for d in result.used])
    residuals = result.residuals_px.reshape(-1, 2)
    scale_px = max(float(np.percentile(np.linalg.norm(residuals, axis=1), 95)), 1e-6)
    arrow_len = 0.04 * camera.image_size[0]  # a 95th-percentile residual is drawn 4 % of the image width long
    quiver = ax.quiver(
        points[:, 0], points[:, 1], residuals[:, 0], -residuals[:, 1], np.linalg.norm(residuals, axis=1),
        angles="xy", scale_units="xy", scale=scale_px / arrow_len, cmap="viridis", width=0.003,
    )  # fmt: skip
    fig.colorbar(quiver, ax=ax, label="residual (px)", shrink=0.8)
    _image_axes(ax, camera.image_size, f"residuals (detected - reprojected), arrows x{arrow_len / scale_px:.0f}")
    ax = axes[2]
    names = [Path(d.source).name for d in result.used]
    ax.barh(range(len(names)), result.per_view_rms_px, color=colours[: len(names)])
    ax.axvline(result.rms_px, color="k", ls="--", label=f"total RMS {result.rms_px:.4f} px")
    ax.set_yticks(range(len(names)), names, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("per-view RMS reprojection error (px)")
    ax.xaxis.set_major_locator(plt.MaxNLocator(4))
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), fontsize=8, frameon=False)
    k, d = camera.camera_matrix, camera.distortion
    text = f"fx {k[0, 0]:.3f}  fy {k[1, 1]:.3f}\ncx {k[0, 2]:.3f}  cy {k[1, 2]:.3f}\ndist " + " ".join(
        f"{c:.4g}" for c in d
    )
    if result.failed:
        text += "\nno board: " + ", ".join(Path(f.source).name for f in result.failed)
    ax.set_title(text, fontsize=8, loc="left")
    fig.suptitle("ropecam intrinsic calibration", fontsize=12)
    fig.tight_layout()
    return _save(fig, path)


def plot_plane_report(
    result: PlaneResult,
    error_map: ErrorMap,
    table: dict[str, float],
    images: Sequence[NDArray[np.uint8]],
    path: str | Path,
) -> Path:
    """Write a PNG with the plane view (corners, origin, axes), the residual scatter and the error map.

    Parameters
    ----------
    result
        The plane calibration.
    error_map
        `propagate_pixel_error` of the calibrated conversion.
    table
        `error_table` of the corners' mean and max reprojection errors.
    images
        The plane images (grayscale), first image first; several are shown as their pixelwise maximum.
    path
        Output PNG.
    """
    plt = _pyplot()
    camera, report = result.camera, result.report
    fig, axes = plt.subplots(1, 3, figsize=(18, 5.4), gridspec_kw={"width_ratios": [1.4, 0.9, 1.4]})
    ax = axes[0]
    ax.imshow(np.maximum.reduce([np.asarray(image) for image in images]), cmap="gray", vmin=0, vmax=255)
    ax.plot(result.corners_px[:, 0], result.corners_px[:, 1], "*", ms=6, color="tab:orange", label="detected")
    ax.plot(
        result.reprojected_px[:, 0], result.reprojected_px[:, 1], "o", ms=7, mfc="none", color="tab:cyan",
        label="reprojected",
    )  # fmt: skip
    span_m = 4 * result.board.square_m
    axes_px = plane_to_pixels(np.array([[0.0, 0.0], [span_m, 0.0], [0.0, span_m]]), camera, result.plane)
    for end, label in ((axes_px[1], "x"), (axes_px[2], "y (gravity)")):
        ax.annotate("", xy=end, xytext=axes_px[0], arrowprops={"arrowstyle": "->", "color": "red", "lw": 2})
        ax.text(*end, f" {label}", color="red", fontsize=9, bbox={"facecolor": "white", "alpha": 0.7, "lw": 0})
    ax.plot(*axes_px[0], "s", color="red", ms=6, label="origin (rope's fixed end)")
    ax.legend(loc="lower right", fontsize=8)
    shown = f"{len(images)} plane images (brightest of each pixel)" if len(images) > 1 else "plane view"
    _image_axes(ax, camera.image_size, f"{shown}: {result.board.describe()}")
    ax = axes[1]
    residual = result.corners_px - result.reprojected_px
    ax.plot(residual[:, 0], residual[:, 1], "+", color="tab:blue")
    limit = max(float(np.abs(residual).max()) * 1.2, 1e-3)
    ax.set_xlim(-limit, limit)
    ax.set_ylim(limit, -limit)
    ax.set_aspect("equal")
    ax.axhline(0, color="0.7", lw=0.8)
    ax.axvline(0, color="0.7", lw=0.8)
    ax.set_xlabel("error along u (px)")
    ax.set_ylabel("error along v (px)")
    ax.set_title(
        f"corner reprojection errors\nu: mean {report.mean_u_px:.4f}, max {report.max_u_px:.4f} px\n"
        f"v: mean {report.mean_v_px:.4f}, max {report.max_v_px:.4f} px\n"
        f"on plane x: mean {report.mean_x_mm:.4f}, max {report.max_x_mm:.4f} mm\n"
        f"on plane y: mean {report.mean_y_mm:.4f}, max {report.max_y_mm:.4f} mm",
        fontsize=8,
        loc="left",
    )
    ax = axes[2]
    extent = (error_map.u_px[0], error_map.u_px[-1], error_map.v_px[-1], error_map.v_px[0])
    heat = ax.imshow(error_map.sigma_max_mm, extent=extent, cmap="magma", aspect="equal")
    contours = ax.contour(error_map.u_px, error_map.v_px, error_map.sigma_max_mm, colors="w", linewidths=0.7)
    ax.clabel(contours, fmt="%.3g mm", fontsize=7)
    fig.colorbar(heat, ax=ax, label="plane error, major semi-axis (mm)", shrink=0.8)
    ax.plot(*axes_px[0], "s", color="cyan", ms=6)
    _image_axes(
        ax,
        camera.image_size,
        f"error map for pixel sigma u {error_map.sigma_u_px:g} px, v {error_map.sigma_v_px:g} px\n"
        f"Table 3: x avg {table['average_x_mm']:.3f} / max {table['maximum_x_mm']:.3f} mm, "
        f"y avg {table['average_y_mm']:.3f} / max {table['maximum_y_mm']:.3f} mm",
    )
    fig.suptitle("ropecam motion-plane calibration", fontsize=12)
    fig.tight_layout()
    return _save(fig, path)
