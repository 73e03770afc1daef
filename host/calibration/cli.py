"""`ropecam calibrate intrinsics|plane`: camera intrinsics from chessboard images, then the motion plane's pose."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ropecam.shared.cli import EXIT_USAGE, declare_outputs
from ropecam.shared.errors import CalibrationError, ConfigError

__all__ = ["register"]

INTRINSICS_HELP = """\
Calibrate the camera's intrinsics (K and distortion) from images of a chessboard.

Show the board in 15-30 views: fill the image corners and edges, tilt it 15-45 degrees in different directions,
keep it sharp. Views where the board is not found are listed with the reason and left out.

Writes OpenCV FileStorage YAML (camera_matrix, distortion_coefficients, image_width, image_height,
avg_reprojection_error, per-view errors) and a PNG report (coverage, residual vectors, per-view RMS).

example:
  ropecam calibrate intrinsics calib/*.png --board 8x7 --square-mm 20 --out camera.yaml
  # OpenCV's calibration sample, exactly (its left_intrinsics.yml):
  ropecam calibrate intrinsics left*.jpg --board 9x6 --square-mm 25 --fix-aspect-ratio \\
      --corner-refine subpix --subpix-window 11 --subpix-eps 0.1 --out left.yaml
"""

PLANE_HELP = """\
Find the pose of the rope's motion plane from one image of a chessboard lying level in it (rows horizontal).

The plane frame: x horizontal (to the right in the image), y along gravity (down), origin at the rope's fixed end,
given as a pixel (--origin-px) or in board coordinates from the top-left inner corner (--origin-mm); by default the
top-left inner corner. Negative values need an equals sign: --origin-mm=-30,-60.

A 20 mm board 1.5 m away fixes the plane's tilt to about 0.05 degrees, which is 0.1-0.3 mm at the image edges.
Give more images of the board lying elsewhere in the same plane (left, right, low; any rotation within the plane)
and all boards are fitted together: the first image still sets the axes and the origin.

Prints the paper's error report (corner reprojection errors in u and v, what they are in mm on the plane, Table 3
for the whole image) and writes FileStorage YAML with the pose and the camera, plus a PNG (corners, residuals,
error-propagation map).

example:
  ropecam calibrate plane plane.png --camera camera.yaml --board 8x7 --square-mm 20 --origin-px 512,140 \\
      --out plane.yaml
"""


def _pair(text: str) -> tuple[float, float]:
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 2:
        raise argparse.ArgumentTypeError(f"expected two numbers A,B such as 512,140, got {text!r}")
    return values  # type: ignore[return-value]


def _window(text: str) -> int | None:
    if text == "auto":
        return None
    if not text.isdigit() or not 1 <= int(text) <= 50:
        raise argparse.ArgumentTypeError(f"expected 'auto' or a half window of 1-50 px, got {text!r}")
    return int(text)


def _add_board_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--board", required=True, metavar="COLSxROWS", help="inner corners, e.g. 9x6")
    parser.add_argument("--square-mm", type=float, required=True, help="side of one square in mm")
    parser.add_argument(
        "--corner-refine",
        choices=("saddle", "subpix"),
        default="saddle",
        help="saddle: cv2.cornerSubPix then a saddle-point fit (most accurate; default); subpix: cv2.cornerSubPix only",
    )
    parser.add_argument(
        "--subpix-window",
        type=_window,
        default=None,
        metavar="auto|N",
        help="cornerSubPix half window in px (OpenCV's sample: 11); auto sizes it from the square size (default)",
    )
    parser.add_argument("--subpix-eps", type=float, default=0.01, help="cornerSubPix stop criterion in px (0.01)")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``calibrate`` with its ``intrinsics`` and ``plane`` sub-commands."""
    parser = subparsers.add_parser(
        "calibrate",
        help="camera intrinsics and motion-plane pose from chessboard images",
        description="Calibrate the camera (intrinsics), then the motion plane (pose, origin at the rope's fixed end).",
    )
    commands = parser.add_subparsers(title="steps", metavar="STEP")
    parser.set_defaults(func=lambda _args: parser.print_help(sys.stderr) or EXIT_USAGE)

    intrinsics = commands.add_parser(
        "intrinsics",
        help="K and distortion from chessboard views",
        description=INTRINSICS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    intrinsics.add_argument(
        "images", nargs="+", type=Path, help="chessboard images (all the same size), or folders of them"
    )
    _add_board_arguments(intrinsics)
    intrinsics.add_argument("--fix-aspect-ratio", action="store_true", help="keep fx = fy (CALIB_FIX_ASPECT_RATIO)")
    intrinsics.add_argument(
        "--model", choices=("standard", "rational"), default="standard",
        help="standard: k1 k2 p1 p2 k3; rational: adds k4 k5 k6 (wide-angle lenses)",
    )  # fmt: skip
    intrinsics.add_argument("--out", type=Path, required=True, help="camera file to write (.yaml)")
    intrinsics.add_argument("--report", type=Path, help="PNG report (default: OUT with .png)")
    declare_outputs(intrinsics, "out", derived=_default_report)
    intrinsics.set_defaults(func=run_intrinsics)

    plane = commands.add_parser(
        "plane",
        help="motion-plane pose from a board lying in it",
        description=PLANE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    plane.add_argument("image", type=Path, help="image of the board lying level in the motion plane")
    plane.add_argument(
        "more_images", nargs="*", type=Path, metavar="MORE_IMAGES",
        help="the board lying elsewhere in the same plane (any rotation within it): fixes the plane's tilt better",
    )  # fmt: skip
    plane.add_argument("--camera", type=Path, required=True, help="camera file from `calibrate intrinsics`")
    _add_board_arguments(plane)
    origin = plane.add_mutually_exclusive_group()
    origin.add_argument("--origin-px", type=_pair, metavar="U,V", help="the rope's fixed end as a pixel")
    origin.add_argument(
        "--origin-mm", type=_pair, metavar="X,Y", help="the fixed end in board mm from the top-left inner corner"
    )
    plane.add_argument("--pixel-sigma", type=float, default=1.0, help="pixel uncertainty for the error map (1.0 px)")
    plane.add_argument(
        "--max-rms-px", type=float, default=1.0,
        help="refuse a board that reprojects worse than this: wrong camera file or a bent board (1.0 px)",
    )  # fmt: skip
    plane.add_argument("--out", type=Path, required=True, help="plane file to write (.yaml)")
    plane.add_argument("--report", type=Path, help="PNG report (default: OUT with .png)")
    declare_outputs(plane, "out", derived=_default_report)
    plane.set_defaults(func=run_plane)


def _default_report(args: argparse.Namespace) -> list[Path]:
    """The PNG report written beside the calibration file."""
    return [args.report or args.out.with_suffix(".png")]


IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm")


def _expand_folders(paths: list[Path]) -> list[Path]:
    """Replace each folder by the image files in it (sorted by name)."""
    expanded: list[Path] = []
    for path in paths:
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
            if not found:
                raise CalibrationError(f"{path}: folder holds no images ({', '.join(IMAGE_SUFFIXES)})")
            expanded.extend(found)
        else:
            expanded.append(path)
    return expanded


def _board_and_subpix(args: argparse.Namespace):
    from ropecam.host.calibration.board import SubpixSettings, parse_board

    try:
        board = parse_board(args.board, args.square_mm)
        subpix = SubpixSettings(args.subpix_window, 30, args.subpix_eps, args.corner_refine == "saddle")
    except ValueError as exc:
        raise ConfigError(str(exc)) from exc
    return board, subpix


def run_intrinsics(args: argparse.Namespace) -> int:
    """Run ``calibrate intrinsics``; return the exit code."""
    from ropecam.host.calibration.files import write_camera
    from ropecam.host.calibration.intrinsics import calibrate_intrinsics
    from ropecam.host.calibration.report import plot_intrinsics_report

    board, subpix = _board_and_subpix(args)

    def progress(done: int, total: int, detection) -> None:
        status = f"{board.n_corners} corners" if detection.found else f"NO BOARD: {detection.reason}"
        print(f"[{done}/{total}] {detection.source}: {status}", file=sys.stderr, flush=True)

    images = _expand_folders(args.images)
    result = calibrate_intrinsics(images, board, args.fix_aspect_ratio, args.model, subpix, progress)
    camera = result.camera
    metadata = {
        "nframes": len(result.used),
        "board_width": board.cols,
        "board_height": board.rows,
        "square_size": board.square_m,
        "flags": result.flags,
        "per_view_reprojection_errors": result.per_view_rms_px.reshape(-1, 1),
    }
    out = write_camera(args.out, camera, result.rms_px, metadata)
    report = plot_intrinsics_report(result, args.report or args.out.with_suffix(".png"))
    k = camera.camera_matrix
    print(f"views used: {len(result.used)} of {len(images)}")
    for detection, rms in zip(result.used, result.per_view_rms_px, strict=True):
        print(f"  {detection.source}: RMS {rms:.4f} px")
    for detection in result.failed:
        print(f"  {detection.source}: left out: {detection.reason}")
    print(f"total RMS reprojection error: {result.rms_px:.4f} px")
    print(f"fx {k[0, 0]:.4f}  fy {k[1, 1]:.4f}  cx {k[0, 2]:.4f}  cy {k[1, 2]:.4f}  (px)")
    print("distortion: " + " ".join(f"{c:.6g}" for c in camera.distortion))
    print(f"wrote {out} and {report}")
    return 0


def run_plane(args: argparse.Namespace) -> int:
    """Run ``calibrate plane``; return the exit code."""
    import numpy as np

    from ropecam.host.calibration.board import read_gray
    from ropecam.host.calibration.files import read_camera, write_plane
    from ropecam.host.calibration.geometry import plane_to_pixels
    from ropecam.host.calibration.plane import calibrate_plane
    from ropecam.host.calibration.propagation import error_table, propagate_pixel_error
    from ropecam.host.calibration.report import plot_plane_report

    board, subpix = _board_and_subpix(args)
    if not args.pixel_sigma > 0:
        raise ConfigError(f"--pixel-sigma must be > 0 px, got {args.pixel_sigma}")
    camera = read_camera(args.camera).camera
    image = read_gray(args.image)
    extra = [(str(path), read_gray(path)) for path in args.more_images]
    result = calibrate_plane(
        image, camera, board, args.origin_px, args.origin_mm, str(args.image), subpix, args.max_rms_px,
        str(args.camera), extra,
    )  # fmt: skip
    report = result.report
    table = error_table(camera, result.plane, (report.mean_u_px, report.mean_v_px), (report.max_u_px, report.max_v_px))
    error_map = propagate_pixel_error(camera, result.plane, args.pixel_sigma)
    origin_px = plane_to_pixels(np.zeros(2), camera, result.plane)
    metadata = {
        "camera_file": str(args.camera),
        "plane_image": str(args.image),
        "plane_images": len(result.detections),
        "board_width": board.cols,
        "board_height": board.rows,
        "square_size": board.square_m,
        "origin_board_mm": (result.origin_board_m * 1000.0).reshape(2, 1),
        "origin_px": origin_px.reshape(2, 1),
        "reprojection_error_u_px": np.array([[report.mean_u_px], [report.max_u_px]]),
        "reprojection_error_v_px": np.array([[report.mean_v_px], [report.max_v_px]]),
        "plane_error_x_mm": np.array([[report.mean_x_mm], [report.max_x_mm]]),
        "plane_error_y_mm": np.array([[report.mean_y_mm], [report.max_y_mm]]),
    }
    out = write_plane(args.out, camera, result.plane, metadata)
    images = [image, *(picture for _, picture in extra)]
    png = plot_plane_report(result, error_map, table, images, args.report or args.out.with_suffix(".png"))
    t_mm = result.plane.translation_m * 1000.0
    print(f"plane origin (rope's fixed end): pixel ({origin_px[0]:.2f}, {origin_px[1]:.2f}), board "
          f"({result.origin_board_m[0] * 1000:.2f}, {result.origin_board_m[1] * 1000:.2f}) mm")  # fmt: skip
    print(f"plane pose: rvec {np.round(result.plane.rvec, 6).tolist()}, t ({t_mm[0]:.2f}, {t_mm[1]:.2f}, "
          f"{t_mm[2]:.2f}) mm, distance {np.linalg.norm(t_mm):.1f} mm")  # fmt: skip
    if extra:
        print(f"fitted {len(result.detections)} boards in one plane: {', '.join(d.source for d in result.detections)}")
    for line in report.lines():
        print(line)
    print(
        f"Table 3 (whole image): x average {table['average_x_mm']:.4f} mm, maximum {table['maximum_x_mm']:.4f} mm; "
        f"y average {table['average_y_mm']:.4f} mm, maximum {table['maximum_y_mm']:.4f} mm"
    )
    print(
        f"a pixel error of {args.pixel_sigma:g} px (1 sigma, u and v) is {error_map.sigma_max_mm.min():.3f} to "
        f"{error_map.sigma_max_mm.max():.3f} mm on the plane across the image (major semi-axis)"
    )
    print(f"wrote {out} and {png}")
    return 0
