"""Chessboard targets: geometry, corner detection with a reason when it fails, and a fixed corner order.

Corner order
------------
OpenCV may return a chessboard's corners starting from any end of the grid. We reorder every detection so that the
first corner is the top-left one in the image, rows run towards +u (right) and columns towards +v (down). The board
frame is then x along the rows, y along the columns, z = x cross y pointing away from the camera, which is the plane
frame's convention (x horizontal, y down along gravity) for a board laid level in the motion plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import DataError

__all__ = [
    "Chessboard",
    "Detection",
    "SubpixSettings",
    "detect_corners",
    "order_corners",
    "parse_board",
    "read_gray",
    "refine_saddle",
]

# Largest cornerSubPix half window (OpenCV's samples use 11, i.e. a 23x23 px search region).
MAX_SUBPIX_HALF_WINDOW = 11


@dataclass(frozen=True, slots=True)
class Chessboard:
    """A planar chessboard with ``cols`` x ``rows`` inner corners and square side ``square_m`` (metres)."""

    cols: int
    rows: int
    square_m: float

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2:
            raise ValueError(f"a chessboard needs at least 2x2 inner corners, got {self.cols}x{self.rows}")
        if not math.isfinite(self.square_m) or self.square_m <= 0:
            raise ValueError(f"square_m must be > 0, got {self.square_m!r}")

    @property
    def pattern_size(self) -> tuple[int, int]:
        """OpenCV's ``patternSize`` (corners per row, corners per column)."""
        return (self.cols, self.rows)

    @property
    def n_corners(self) -> int:
        """Number of inner corners."""
        return self.cols * self.rows

    def object_points(self) -> NDArray[np.float32]:
        """Return the inner corners in the board frame, shape (rows*cols, 3), metres, row-major (x fastest)."""
        grid = np.mgrid[0 : self.cols, 0 : self.rows].T.reshape(-1, 2).astype(np.float64) * self.square_m
        return np.column_stack([grid, np.zeros(len(grid))]).astype(np.float32)

    def describe(self) -> str:
        """Return e.g. ``'9x6 inner corners, 25 mm squares'``."""
        return f"{self.cols}x{self.rows} inner corners, {self.square_m * 1000:g} mm squares"


def parse_board(text: str, square_mm: float) -> Chessboard:
    """Parse ``'COLSxROWS'`` (inner corners) and a square size in mm into a `Chessboard`.

    Raises
    ------
    ValueError
        `text` is not two integers >= 2 separated by ``x`` or `square_mm` is not > 0.
    """
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise ValueError(f"board must be COLSxROWS inner corners such as 9x6, got {text!r}")
    if not math.isfinite(square_mm) or square_mm <= 0:
        raise ValueError(f"square size must be > 0 mm, got {square_mm!r}")
    return Chessboard(int(parts[0]), int(parts[1]), square_mm / 1000.0)


@dataclass(frozen=True, slots=True)
class SubpixSettings:
    """`cv2.cornerSubPix` settings.

    ``half_window=None`` sizes the window per view from the corner spacing (at most
    `MAX_SUBPIX_HALF_WINDOW`), so the search region never reaches the neighbouring corners; a window larger than a
    square biases corners on small or distant boards. OpenCV's own sample uses 11 px, 30 iterations, eps 0.1 px.
    ``saddle=True`` then refines each corner as the saddle point of a quadratic fitted to the smoothed image
    (`refine_saddle`), 2-4 times more accurate than `cv2.cornerSubPix` alone on simulated boards.
    """

    half_window: int | None = None
    max_iterations: int = 30
    eps_px: float = 0.01
    saddle: bool = True

    def __post_init__(self) -> None:
        if self.half_window is not None and not 1 <= self.half_window <= 50:
            raise ValueError(f"subpixel half window must be in [1, 50] px, got {self.half_window}")
        if self.max_iterations < 1 or not self.eps_px > 0:
            raise ValueError(
                f"cornerSubPix needs max_iterations >= 1 and eps_px > 0, got {self.max_iterations}, {self.eps_px}"
            )


@dataclass(frozen=True, slots=True)
class Detection:
    """Result of looking for a board in one image.

    ``corners`` (shape (n, 2), float32, distorted pixels, ordered as `order_corners`) is None when the board was not
    found; ``reason`` then says why.
    """

    source: str
    image_size: tuple[int, int]
    corners: NDArray[np.float32] | None
    reason: str = ""
    half_window: int = 0

    @property
    def found(self) -> bool:
        """True when all corners were found."""
        return self.corners is not None


def read_gray(path: str | Path) -> NDArray[np.uint8]:
    """Read an image file as 8-bit grayscale.

    Raises
    ------
    DataError
        The file is missing or is not an image OpenCV can decode (the message names the file).
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: image file not found")
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise DataError(f"{path}: cannot read image file: {exc}") from exc
    image = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE) if data.size else None
    if image is None:
        raise DataError(f"{path}: not a readable image (OpenCV cannot decode it)")
    return image


def order_corners(corners: NDArray[np.floating], board: Chessboard) -> NDArray[np.float32]:
    """Reorder detected corners so rows run towards +u and columns towards +v, first corner top-left.

    Parameters
    ----------
    corners
        Shape (rows*cols, 2) or (rows*cols, 1, 2), pixels, in any of OpenCV's row-major orders.
    board
        The board the corners belong to.
    """
    grid = np.asarray(corners, dtype=np.float32).reshape(board.rows, board.cols, 2)
    along_row = np.mean(grid[:, -1] - grid[:, 0], axis=0)
    along_col = np.mean(grid[-1, :] - grid[0, :], axis=0)
    if along_row[0] < 0:
        grid = grid[:, ::-1]
    if along_col[1] < 0:
        grid = grid[::-1, :]
    return np.ascontiguousarray(grid.reshape(-1, 2))


def _spacing_px(corners: NDArray[np.float32], board: Chessboard) -> float:
    grid = corners.reshape(board.rows, board.cols, 2)
    return min(
        float(np.min(np.linalg.norm(np.diff(grid, axis=1), axis=-1))),
        float(np.min(np.linalg.norm(np.diff(grid, axis=0), axis=-1))),
    )


def refine_saddle(image: NDArray[np.uint8], corners: NDArray[np.floating], spacing_px: float) -> NDArray[np.float32]:
    """Refine chessboard corners to the saddle point of a quadratic fitted around each one.

    The image is smoothed with a Gaussian (sigma 1.5 px, 1 px on small boards), a weighted quadratic surface is
    fitted to a (2r+1)^2 patch centred on the current estimate, and the corner moves to the surface's stationary
    point, until it moves less than 1e-4 px (8 passes at most). A corner whose fit is not a saddle, moves more than
    r px or whose patch leaves the image keeps its last good position.

    Parameters
    ----------
    image
        Grayscale image, shape (height, width), uint8.
    corners
        Initial corners (u, v), shape (n, 2), pixels, accurate to well under a pixel.
    spacing_px
        Smallest distance between neighbouring corners, pixels (sizes the patch).

    Returns
    -------
    ndarray
        Refined corners, shape (n, 2), float32.
    """
    radius, sigma = (4, 1.5) if spacing_px >= 12 else (3, 1.0)
    smooth = cv2.GaussianBlur(image.astype(np.float32), (0, 0), sigma)
    height, width = smooth.shape
    oy, ox = np.mgrid[-radius : radius + 1, -radius : radius + 1]
    ox, oy = ox.ravel().astype(np.float64), oy.ravel().astype(np.float64)
    design = np.column_stack([ox**2, ox * oy, oy**2, ox, oy, np.ones_like(ox)])
    weights = np.exp(-(ox**2 + oy**2) / (2 * (radius / 1.5) ** 2))
    solver = np.linalg.pinv(design * weights[:, None]) * weights[None, :]  # (6, patch): coefficients from a patch
    start = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    points = start.copy()
    active = np.ones(len(points), dtype=bool)
    for _ in range(8):
        # The patch is centred on the current estimate (bilinear samples of the smoothed image): a patch centred
        # on the nearest pixel is asymmetric about the corner and biases the fit by up to a few hundredths of a px.
        inside = (
            (points[:, 0] >= radius + 1)
            & (points[:, 0] < width - radius - 2)
            & (points[:, 1] >= radius + 1)
            & (points[:, 1] < height - radius - 2)
        )
        safe = np.where(inside[:, None], points, radius + 1.0)
        patches = _bilinear(smooth, safe[:, None, 0] + ox[None, :], safe[:, None, 1] + oy[None, :])
        a, b, c, d, e, _ = (patches @ solver.T).T
        det = 4 * a * c - b * b
        with np.errstate(divide="ignore", invalid="ignore"):
            du = (-2 * c * d + b * e) / det
            dv = (b * d - 2 * a * e) / det
        ok = active & inside & (det < 0) & np.isfinite(du) & np.isfinite(dv) & (np.hypot(du, dv) <= radius)
        active &= ok
        points = np.where(ok[:, None], points + np.column_stack([du, dv]), points)
        if not np.any(ok & (np.hypot(du, dv) > 1e-4)):
            break
    moved = np.linalg.norm(points - start, axis=1)
    points[moved > radius] = start[moved > radius]
    return points.astype(np.float32)


def _bilinear(image: NDArray[np.float32], u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sample `image` at (u, v) (any shape, inside the image) by bilinear interpolation."""
    u0 = np.floor(u).astype(np.int64)
    v0 = np.floor(v).astype(np.int64)
    fu, fv = u - u0, v - v0
    top = image[v0, u0] * (1 - fu) + image[v0, u0 + 1] * fu
    bottom = image[v0 + 1, u0] * (1 - fu) + image[v0 + 1, u0 + 1] * fu
    return top * (1 - fv) + bottom * fv


def _auto_half_window(corners: NDArray[np.float32], board: Chessboard) -> int:
    spacing = _spacing_px(corners, board)
    # The (2w+1)^2 region must stay inside the four squares around a corner: 2w+1 <= spacing, with a margin.
    return int(max(2, min(MAX_SUBPIX_HALF_WINDOW, math.floor(0.4 * spacing))))


def detect_corners(
    image: NDArray[np.uint8],
    board: Chessboard,
    source: str = "<image>",
    subpix: SubpixSettings | None = None,
) -> Detection:
    """Find the inner corners of `board` in a grayscale image, refined to subpixel accuracy.

    Uses `cv2.findChessboardCorners` (adaptive threshold, normalised image, fast check, as OpenCV's calibration sample)
    then `cv2.cornerSubPix`; falls back to `cv2.findChessboardCornersSB` when the classic detector fails.

    Parameters
    ----------
    image
        Grayscale image, shape (height, width), uint8.
    board
        The board to look for.
    source
        Name used in messages (usually the file name).
    subpix
        Subpixel refinement settings; default `SubpixSettings()`.

    Returns
    -------
    Detection
        With ``corners`` ordered by `order_corners`, or ``corners=None`` and a ``reason``.
    """
    subpix = subpix or SubpixSettings()
    if image.ndim != 2 or image.dtype != np.uint8:
        raise ValueError(f"{source}: expected a 2-D uint8 grayscale image, got shape {image.shape} {image.dtype}")
    size = (int(image.shape[1]), int(image.shape[0]))
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
    found, corners = cv2.findChessboardCorners(image, board.pattern_size, None, flags)
    refine = True
    if not found:
        found, corners = cv2.findChessboardCornersSB(image, board.pattern_size, None, cv2.CALIB_CB_NORMALIZE_IMAGE)
        refine = False  # SB corners are already subpixel-accurate
    if not found or corners is None or len(corners) != board.n_corners:
        transposed, _ = cv2.findChessboardCorners(image, (board.rows, board.cols), None, flags)
        if transposed:
            hint = f"; a {board.rows}x{board.cols} board is visible: swap the --board numbers"
        else:
            hint = "; check --board (inner corners, not squares), focus, lighting and that the whole board is in view"
        return Detection(source, size, None, f"no {board.cols}x{board.rows} chessboard found{hint}")
    half_window = 0
    if refine:
        half_window = subpix.half_window or _auto_half_window(corners.reshape(-1, 2), board)
        criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, subpix.max_iterations, subpix.eps_px)
        corners = cv2.cornerSubPix(image, corners, (half_window, half_window), (-1, -1), criteria)
        if subpix.saddle:
            corners = refine_saddle(image, corners.reshape(-1, 2), _spacing_px(corners.reshape(-1, 2), board))
    ordered = order_corners(corners, board)
    if not np.all(np.isfinite(ordered)):
        return Detection(source, size, None, "corner refinement produced non-finite coordinates")
    return Detection(source, size, ordered, "", half_window)
