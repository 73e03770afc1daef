"""A rope's look taken from a photograph: its brightness across and along its own centreline, as a texture strip.

`load_rope_strip` reads a photo of a rope lying on a plain background, finds the rope (the mask beside the image,
``../gt_labels/<name>.npy`` as in the mBEST dataset, or else an Otsu threshold, keeping the largest region of the
less common class), thins it to its skeleton, takes the longest path through it, smooths it and samples the photo
across the rope at every pixel of arc length. The result is a strip: rows along the rope, columns across it from
one edge to the other, relative to its mean brightness. `RopeTexture` resamples that strip to the rendered rope's
scale (the photographed diameter becomes the rendered one) and tiles it along the rope by mirroring, so a braided
rope's pattern keeps its period and its slant; the renderer looks it up per pixel from the material coordinate and
the signed distance across the centreline (`ropecam.host.sim._kernels.stamp_centreline`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from ropecam.shared.errors import ConfigError

__all__ = ["PhotoStrip", "RopeTexture", "flat_texture", "load_plate_texture", "load_rope_strip", "rope_texture"]

END_TRIM_DIAMETERS = 3.0
"""Arc length left out at each end of the photographed rope (end caps, frayed ends), in rope diameters."""
SMOOTHING_PX = 4.0
"""Standard deviation of the smoothing of the skeleton path, photo pixels (removes its one-pixel staircase)."""
EDGE_FRACTION = 0.7
"""The strip reaches this fraction of the rope's radius on each side (the outermost pixels mix in background)."""


@dataclass(frozen=True)
class PhotoStrip:
    """The photographed rope, straightened.

    Attributes
    ----------
    strip
        (L, B) float32 brightness relative to its mean: rows one photo pixel apart along the rope, B columns
        across it from one edge to the other. Its mean profile across is symmetric (the photo's one-sided
        lighting removed).
    diameter_px
        The rope's diameter in the photo, pixels (twice the median distance from the skeleton to the background).
    path_px
        (L, 2) the smoothed centreline in the photo, (u, v) pixels.
    """

    strip: NDArray[np.float32]
    diameter_px: float
    path_px: NDArray[np.float64]


def _thin(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Zhang-Suen thinning of a binary image (vectorised; the border pixels must be background)."""
    image = np.pad(mask.astype(np.uint8), 1)
    while True:
        changed = False
        for step in (0, 1):
            p = image
            n = [p[:-2, 1:-1], p[:-2, 2:], p[1:-1, 2:], p[2:, 2:], p[2:, 1:-1], p[2:, :-2], p[1:-1, :-2], p[:-2, :-2]]
            count = sum(x.astype(np.int32) for x in n)
            ring = [*n, n[0]]
            transitions = sum(((a == 0) & (b == 1)).astype(np.int32) for a, b in itertools.pairwise(ring))
            if step == 0:
                c1, c2 = n[0] * n[2] * n[4], n[2] * n[4] * n[6]
            else:
                c1, c2 = n[0] * n[2] * n[6], n[0] * n[4] * n[6]
            remove = (p[1:-1, 1:-1] == 1) & (count >= 2) & (count <= 6) & (transitions == 1) & (c1 == 0) & (c2 == 0)
            if remove.any():
                image[1:-1, 1:-1][remove] = 0
                changed = True
        if not changed:
            return image[1:-1, 1:-1].astype(bool)


def _longest_path(skeleton: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Return the (u, v) pixels of the longest shortest path through an 8-connected skeleton."""
    rows, cols = np.nonzero(skeleton)
    index = -np.ones(skeleton.shape, dtype=np.int64)
    index[rows, cols] = np.arange(rows.size)
    src, dst, length = [], [], []
    height, width = skeleton.shape
    for dr, dc in ((0, 1), (1, -1), (1, 0), (1, 1)):
        r2, c2 = rows + dr, cols + dc
        ok = (r2 >= 0) & (r2 < height) & (c2 >= 0) & (c2 < width)
        ok[ok] = index[r2[ok], c2[ok]] >= 0
        src.append(index[rows[ok], cols[ok]])
        dst.append(index[r2[ok], c2[ok]])
        length.append(np.full(ok.sum(), math.hypot(dr, dc)))
    graph = coo_matrix((np.concatenate(length), (np.concatenate(src), np.concatenate(dst))), (rows.size, rows.size))
    far = dijkstra(graph, directed=False, indices=0)
    start = int(np.argmax(np.where(np.isfinite(far), far, -1)))
    far, previous = dijkstra(graph, directed=False, indices=start, return_predecessors=True)
    node = int(np.argmax(np.where(np.isfinite(far), far, -1)))
    path = []
    while node >= 0:
        path.append(node)
        node = previous[node]
    return np.stack([cols[path], rows[path]], axis=-1).astype(np.float64)


def _read_grey(path: Path, key: str, what: str, expected: str) -> NDArray[np.uint8]:
    """Read `path` as grey, or raise `ConfigError` naming `key`, the path and what was expected."""
    if not path.is_file():
        raise ConfigError(
            f"{key}: {what} {str(path)!r} not found (give a path to {expected}; a relative path is read from "
            "scene.photo_dir, which --photo-dir sets)"
        )
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise ConfigError(f"{key}: {str(path)!r} is not an image OpenCV can read")
    return image


def _rope_mask(image: NDArray[np.uint8], photo: Path) -> NDArray[np.bool_]:
    mask_file = photo.parent.parent / "gt_labels" / f"{photo.stem}.npy"
    if mask_file.is_file():
        mask = np.load(mask_file, allow_pickle=False) > 0
        if mask.shape != image.shape:
            raise ConfigError(f"{mask_file}: mask of shape {mask.shape} does not match {photo} ({image.shape})")
    else:
        _, high = cv2.threshold(cv2.GaussianBlur(image, (5, 5), 0), 0, 1, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        mask = high.astype(bool)
        if mask.mean() > 0.5:  # the rope is the smaller class
            mask = ~mask
    mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if count < 2:
        raise ConfigError(f"{photo}: no rope found in the photo")
    largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return labels == largest


def load_rope_strip(photo: str | Path, key: str = "scene.rope_photo") -> PhotoStrip:
    """Read `photo` and return its rope's brightness strip.

    Parameters
    ----------
    photo
        Image file (any format OpenCV reads; converted to grey).
    key
        Configuration key named in errors.

    Raises
    ------
    ConfigError
        The file is missing or unreadable, or holds no rope long enough (errors name `key` and the path).
    """
    path = Path(photo)
    image = _read_grey(path, key, "rope photo", "an image of a rope")
    mask = _rope_mask(image, path)
    distance = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, 5)
    path_px = _longest_path(_thin(mask))
    radius = float(np.median(distance[path_px[:, 1].astype(int), path_px[:, 0].astype(int)]))
    smooth = gaussian_filter1d(path_px, SMOOTHING_PX, axis=0, mode="nearest")
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(smooth, axis=0), axis=1))])
    trim = END_TRIM_DIAMETERS * 2 * radius
    if arc[-1] < 2 * trim + 10 * radius:
        raise ConfigError(f"{key}: the rope in {str(path)!r} is too short ({arc[-1]:.0f} px) to take a texture from")
    along = np.arange(trim, arc[-1] - trim, 1.0)
    centre = np.stack([np.interp(along, arc, smooth[:, 0]), np.interp(along, arc, smooth[:, 1])], axis=-1)
    tangent = np.gradient(centre, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=-1)
    columns = max(3, 2 * round(EDGE_FRACTION * radius) + 1)
    across = np.linspace(-EDGE_FRACTION * radius, EDGE_FRACTION * radius, columns)
    grid = centre[:, None, :] + across[None, :, None] * normal[:, None, :]
    strip = cv2.remap(image.astype(np.float32), grid[..., 0].astype(np.float32), grid[..., 1].astype(np.float32),
                      cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)  # fmt: skip
    # The photo's light came from one side; the mean profile across is made symmetric, so that the rope's mean
    # brightness centre is its axis (the braid's local slant stays).
    profile = strip.mean(axis=0)
    strip *= (0.5 * (profile + profile[::-1]) / np.maximum(profile, 1e-6))[None, :]
    strip /= max(float(strip.mean()), 1e-6)
    return PhotoStrip(strip=strip.astype(np.float32), diameter_px=2 * radius, path_px=centre)


@dataclass(frozen=True)
class RopeTexture:
    """A texture strip at the rendered rope's scale, as the renderer's kernel reads it.

    Attributes
    ----------
    table
        (A, B) float32 relative brightness: rows along the rope (periodic), columns across it from one edge to the
        other; (1, 1) holding 1.0 for a plain rope.
    rows_per_sample
        Rows of `table` per centreline sample (the samples are uniform in arc length).
    """

    table: NDArray[np.float32]
    rows_per_sample: float


def flat_texture() -> RopeTexture:
    """Return the plain rope's texture (no lookup: the brightness is the level along the rope only)."""
    return RopeTexture(np.ones((1, 1), dtype=np.float32), 0.0)


def rope_texture(
    strip: PhotoStrip, contrast: float, diameter_m: float, sample_spacing_m: float, width_px: float
) -> RopeTexture:
    """Scale a photo strip to a rope of `diameter_m` drawn `width_px` wide, with its variation scaled by `contrast`.

    The strip is resampled (area-averaged) to about two rows and two columns per image pixel, mirrored to make it
    periodic along the rope, and set to ``1 + contrast * (strip - 1)``, clipped at 0.

    Parameters
    ----------
    strip
        From `load_rope_strip`.
    contrast
        Scale of the photographed variation (0: flat, 1: as photographed).
    diameter_m
        Drawn diameter of the simulated rope, metres (the photo's diameter maps onto it).
    sample_spacing_m
        Arc-length spacing of the renderer's centreline samples, metres.
    width_px
        Apparent width of the simulated rope, pixels (sets the resolution kept).
    """
    photo_px_per_m = strip.diameter_px / diameter_m
    rows = max(2, round(strip.strip.shape[0] * 2 * width_px / strip.diameter_px))
    cols = max(3, round(2 * width_px) | 1)
    table = cv2.resize(strip.strip, (cols, rows), interpolation=cv2.INTER_AREA)
    table = np.concatenate([table, table[::-1]], axis=0)
    table = np.clip(1.0 + contrast * (table / table.mean() - 1.0), 0.0, None).astype(np.float32)
    rows_per_m = rows / (strip.strip.shape[0] / photo_px_per_m)
    return RopeTexture(np.ascontiguousarray(table), rows_per_m * sample_spacing_m)


def load_plate_texture(photo: str | Path, size: tuple[int, int], key: str = "scene.plate_photo") -> NDArray[np.float32]:
    """Return a (H, W) float32 surface texture with mean 0 from the rope-free part of a photo of a plain surface.

    The photo's rope (found as by `load_rope_strip`) is masked out with a margin and the largest band of rows free
    of it is kept; its slow shading is divided out (a 25 px Gaussian), leaving the surface's own grain, smudges
    and the camera's noise at 1:1 scale, relative to the local brightness. The band is mirrored to fill `size`
    (width, height), so no seam shows.

    Raises
    ------
    ConfigError
        The file is missing or unreadable, or has no rope-free band at least 32 rows high.
    """
    path = Path(photo)
    image = _read_grey(path, key, "plate photo", "an image of a plain surface")
    rope = cv2.dilate(_rope_mask(image, path).astype(np.uint8), np.ones((41, 41), np.uint8)) > 0
    free_rows = ~rope.any(axis=1)
    best, run_start = (0, 0), None
    for row, free in enumerate([*free_rows, False]):
        if free and run_start is None:
            run_start = row
        elif not free and run_start is not None:
            if row - run_start > best[1] - best[0]:
                best = (run_start, row)
            run_start = None
    if best[1] - best[0] < 32:
        raise ConfigError(f"{key}: {str(path)!r} has no band of 32 rows clear of the rope to take a texture from")
    band = image[best[0] : best[1]].astype(np.float32)
    shading = cv2.GaussianBlur(band, (0, 0), 25.0, borderType=cv2.BORDER_REFLECT)
    relative = band / np.maximum(shading, 1.0) - 1.0
    width, height = size
    tiles_v = -(-height // relative.shape[0])
    tiles_u = -(-width // relative.shape[1])
    column = np.concatenate([relative if k % 2 == 0 else relative[::-1] for k in range(tiles_v)], axis=0)
    tiled = np.concatenate([column if k % 2 == 0 else column[:, ::-1] for k in range(tiles_u)], axis=1)
    out = tiled[:height, :width]
    return np.ascontiguousarray(out - out.mean(), dtype=np.float32)
