"""Accuracy of the calibration on simulated sets against their ground truth (acceptance 2 of issue 8).

For each seed: render a calibration set (paper camera, 8x7 board, 20 mm), calibrate the intrinsics from the views
and the plane from the plane view (origin given as the true fixed-end pixel), and compare with the truth: fx, fy,
principal point, plane rotation and translation, and ground-truth pixels converted to metres over the whole image.

    python tools/evaluate.py calibration --seeds 0 1 2 3 4 [--views 30] [--extra-planes 2]
"""

from __future__ import annotations

import argparse
import glob
import tempfile
import time

import numpy as np

from ropecam.host.calibration.board import parse_board, read_gray
from ropecam.host.calibration.geometry import pixels_to_plane, plane_to_pixels
from ropecam.host.calibration.intrinsics import calibrate_intrinsics
from ropecam.host.calibration.plane import calibrate_plane
from ropecam.host.sim.boards import make_calibration_set, read_calibration_set, write_calibration_set


def _grid_errors_mm(true_camera, true_plane, camera, plane) -> np.ndarray:
    xs, ys = np.meshgrid(np.linspace(-0.42, 0.42, 43), np.linspace(-0.1, 0.42, 27))
    points = np.stack([xs, ys], axis=-1).reshape(-1, 2)
    pixels = plane_to_pixels(points, true_camera, true_plane)
    width, height = true_camera.image_size
    seen = (pixels[:, 0] >= 0) & (pixels[:, 0] <= width - 1) & (pixels[:, 1] >= 0) & (pixels[:, 1] <= height - 1)
    return np.linalg.norm(pixels_to_plane(pixels[seen], camera, plane) - points[seen], axis=1) * 1000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--views", type=int, default=50, help="intrinsic calibration views per set (default 50)")
    parser.add_argument("--extra-planes", type=int, default=2, help="extra plane views to use (0-2)")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    board = parse_board("8x7", 20)
    print("seed  rms_px  fx_err%  fy_err%  cx_err  cy_err  rot_deg  dt_mm  dt_inplane_mm  m_err_max_mm  "
          "m_err_mean_mm  | true-K: rot_deg dt_mm m_err_max_mm  | s")  # fmt: skip
    for seed in args.seeds:
        start = time.perf_counter()
        with tempfile.TemporaryDirectory() as folder:
            write_calibration_set(make_calibration_set(n_views=args.views, seed=seed), folder)
            true_camera, true_plane, truth = read_calibration_set(folder)
            result = calibrate_intrinsics(sorted(glob.glob(f"{folder}/view_*.png")), board)
            image = read_gray(f"{folder}/plane.png")
            extra = [(p, read_gray(p)) for p in sorted(glob.glob(f"{folder}/plane_*.png"))][: args.extra_planes]
            rows = []
            for camera in (result.camera, true_camera):
                plane = calibrate_plane(
                    image, camera, board, origin_px=tuple(truth["origin_px"]), extra_images=extra
                ).plane
                delta = plane.rotation @ true_plane.rotation.T
                rot_deg = np.degrees(np.arccos(np.clip((np.trace(delta) - 1) / 2, -1, 1)))
                dt = (plane.translation_m - true_plane.translation_m) * 1000
                inplane = np.linalg.norm((true_plane.rotation.T @ dt)[:2])
                errors = _grid_errors_mm(true_camera, true_plane, camera, plane)
                rows.append((rot_deg, np.linalg.norm(dt), inplane, errors.max(), errors.mean()))
        k, k0 = result.camera.camera_matrix, true_camera.camera_matrix
        (rot, dt, inplane, emax, emean), (rot0, dt0, _, emax0, _) = rows
        print(
            f"{seed:4d}  {result.rms_px:.4f}  {100 * (k[0, 0] / k0[0, 0] - 1):+.4f}"
            f"  {100 * (k[1, 1] / k0[1, 1] - 1):+.4f}"
            f"  {k[0, 2] - k0[0, 2]:+.3f}  {k[1, 2] - k0[1, 2]:+.3f}  {rot:.4f}  {dt:.3f}  {inplane:.3f}  {emax:.4f}"
            f"  {emean:.4f}  | {rot0:.4f} {dt0:.3f} {emax0:.4f}  | {time.perf_counter() - start:.1f}"
        )
    return 0
