"""FixedEndFinder: where the rope is fixed (row, col), configured or found over the first frames."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import i32, ro
from ropecam.device.pipeline.checks import contour_area_px2
from ropecam.device.pipeline.structure import (
    STRUCTURE_ROPE_RATIO,
    convex_hull,
    fill_polygon,
    grow,
    structure_points,
)
from ropecam.device.pipeline.workspace import FixedEndBuffers

__all__ = ["FIXED_END_FRAMES", "FixedEndFinder"]

FIXED_END_FRAMES = 10
"""Frames over which a fixed end that is not configured is averaged; it does not change afterwards."""
HIDDEN_REACH_PX = 120.0
"""Farthest a rope's axis is followed into a static structure (a clamp) for the structure's far side (px)."""
HIDDEN_GAP_PX = 16.0
"""Longest stretch of unmasked pixels between two edges of one structure along the rope's axis (px): a clamp's
face between its outline and its bolts' is shorter; the plate beyond the clamp's far side is longer."""
_STEP_PX = 0.5
LEARNED_THICK = 0.2
"""A structure found in the learned mask (`FixedEndFinder.learned_structure`) is at its thinnest at least this part
of its extent across (a clamp is a block; the simulated 24 x 14 px clamp on its 10 px rod up to the top border:
0.24); a still stretch of the rope is a line."""
LEARNED_THICK_WIDTHS = 2.5
"""... and at least this many rope widths thick (a still stretch of the rope: its two edges a width apart, each
grown by a pixel, about a width + 2 px)."""
LEARNED_MAX_WIDTH_PX = 4.0
"""The widest rope width the thickness and area limits of `learned_structure` are scaled by (px)."""
STILL_ACROSS_WIDTHS = 0.5
"""Largest difference of the widths across an outline's two ends, in rope widths, of a rope at rest
(`FixedEndFinder.still`): a free end sweeping half a width during the exposure widens its end of the band by about
that much (the simulated tuning scenes' still first frames: at most 0.35 px apart, 1.1 px with gamma 2.6)."""
STILL_BAND = 0.25
"""Smallest part of a still rope's area (half the outline's points x the rope width) an outline encloses that is a
band round the rope (`FixedEndFinder.still`); a line walked out and back (a band's edge broken by noise, simulated
`read noise = 10 DN` from 0.4 s, frame 0: 1 px^2) encloses nothing and shows neither a still rope nor a sweep."""
LEARNED_AREA_WIDTHS = 10.0
"""... and covers at least this many squared rope widths (the smallest clamp simulated, 12 x 7.2 px, its edges
grown: about 16 x 11 px, 26 squared widths of a 2.6 px rope; a speck of dust grown: 2-4)."""


class FixedEndFinder:
    """Find the rope's fixed end (row, col) in its first contours, or keep the configured one.

    Parameters
    ----------
    fixed_end_uv
        The configured fixed end (u, v) = (col, row) px, or None to find it.
    shape
        (height, width) of the frames.
    buffers
        The fixed end and the contour's turning angles (`FixedEndBuffers`).
    """

    def __init__(
        self, fixed_end_uv: tuple[float, float] | None, shape: tuple[int, int], buffers: FixedEndBuffers
    ) -> None:
        self.configured = fixed_end_uv is not None
        self.shape = shape
        self.buffers = buffers
        self.fixed = buffers.fixed
        """The fixed end (row, col) float32: valid once `known`."""
        self.known = self.configured
        """Whether `fixed` holds a fixed end (configured, or guessed on a first contour)."""
        self._confirmed = False  # the guessed end was confirmed: by a structure, or by one end staying still
        self._decided_at: NDArray[np.float32] | None = None  # the end motion confirmed, kept over a `restart`
        self.still = True
        """Whether the outline the fixed end was guessed on showed a rope at rest (`_still`): a frame measured about
        the guess may be reported OK only then, and only with its tips within a rope width (`ResultFinisher`,
        ``fixed_end_guess``). (Both ends of a later outline moving is no sign: a still rope's end found inside a
        structure once the static mask is learned (`hidden_end`) moves too.)"""
        self.frames = 0
        """Contours the found fixed end is averaged over."""
        self._first_ends: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None
        self._structure_at: NDArray[np.float64] | None = None  # where the structure found by `structure` lies
        self.exposure_known = True
        """Whether the frame being measured has a known exposure (set by `RopeLocator.locate`): a stream, where
        a still outline with one thick end is a rope at rest joined to a clamp (`_attached_structure`); a still
        photo (exposure unknown) may show any object at a rope's end, and keeps the narrower-end rule."""
        self.mask: NDArray[np.uint8] | None = None
        """The static mask (non-zero: a static structure's edges, `StaticMask`), or None: an end of the rope at a
        structure is then taken where the rope is last seen (`hidden_end`)."""
        if fixed_end_uv is not None:
            self.fixed[:] = (fixed_end_uv[1], fixed_end_uv[0])

    def restart(self) -> None:
        """Forget a found fixed end (a configured one stays): the next contours find it again. Which end of the
        rope is fixed, once motion decided it (`find`), is kept: the next guess takes the end nearest it."""
        if self.known and self._confirmed and self._first_ends is None and not self.configured:
            self._decided_at = self.fixed.copy()
        self.known = self.configured
        self._confirmed = False
        self.still = True
        self.frames = 0
        self._first_ends = None

    @property
    def confirmed(self) -> bool:
        """Whether the fixed end is more than a guess on one contour: configured; or the end a structure holds
        (a clamp found on the outline or in the learned mask, `structure`, `learned_structure`); or one end of the
        outline stayed where it was while the other moved away (`find`, also before a `restart`); or averaged over
        `FIXED_END_FRAMES` contours, each with an end within reach of it."""
        return self.configured or self._confirmed or self.settled

    @property
    def settled(self) -> bool:
        """Whether the fixed end no longer changes (configured, or averaged over `FIXED_END_FRAMES` contours)."""
        return self.known and (self.configured or self.frames >= FIXED_END_FRAMES)

    def find(self, points: NDArray[np.float32], n: int, width_px: float | None) -> bool:
        """Update the fixed end from a contour (`n` (row, col) `points`) of a rope `width_px` wide (None: 4 px).

        The first contour gives a guess: of the band's two ends the narrower one (the fixed end hardly moves, so
        its end of the band stays one rope wide), or on a tie (a rope at rest) the one nearer the top centre of
        the image (a pendulum hangs below its support, and a rig centres the support so the swing stays in view).
        Over the next contours the end that stays where it was is the fixed end: the guess is corrected as soon
        as one end has moved away and the other has not, and the position is averaged over those contours.

        Returns
        -------
        bool
            True when the guess was wrong and the fixed end starts again from the other end: what was measured
            relative to the wrong end (the rope width, the time order's history) is to be forgotten.
        """
        if self.settled:
            return False
        w = width_px or 4.0
        e1, e2, ends = self._ends(points, n, w)
        if self.mask is not None:
            # Where the rope goes into a masked structure (a clamp), its end is hidden inside it.
            ends = [hidden_end(end, points[:n], w, self.mask) for end in ends]
        if not self.known:
            widths = _across(points, n, e1, e2, w)
            if abs(widths[0] - widths[1]) <= 0.25 * min(widths):
                top_centre = np.array([0.0, 0.5 * (self.shape[1] - 1)])
                far = [float(np.hypot(*(end - top_centre))) for end in ends]
                k = 0 if far[0] <= far[1] else 1
            else:
                k = 0 if widths[0] < widths[1] else 1
            attached = _attached_structure(points[:n], e1, e2, ends, w) if self.exposure_known else None
            held = None  # the end a structure found on the outline holds
            if self._structure_at is not None:
                held = int(np.argmin([np.hypot(*(end - self._structure_at)) for end in ends]))
            if attached is not None:
                k = attached
            elif held is not None:  # the rope is fixed in the structure found on its outline
                k = held
            self._confirmed = k == held
            if self._decided_at is not None:  # the traits learned again: the end motion decided before
                k = int(np.argmin([np.hypot(*(end - self._decided_at)) for end in ends]))
                self._confirmed = True
            self.still = self._confirmed or self._still(points, n, e1, e2, w)
            self.fixed[:] = ends[k]
            self._first_ends = (ends[k].copy(), ends[1 - k].copy())
            self.known = True
            self.frames = 1
            return False
        restarted = False
        if self._first_ends is not None and not self.configured:
            guess, other = self._first_ends
            moved_guess = min(float(np.hypot(*(end - guess))) for end in ends)
            moved_other = min(float(np.hypot(*(end - other))) for end in ends)
            if max(moved_guess, moved_other) > max(2.0 * w, 5.0) and min(moved_guess, moved_other) < w:
                self._first_ends = None  # decided
                self._confirmed = True
                if moved_guess > moved_other:
                    # The guessed end moved: it is the free end. Start again from the other one.
                    self.fixed[:] = other
                    self.frames = 0
                    restarted = True
        d = [float(np.hypot(*(end - self.fixed))) for end in ends]
        chosen = ends[0] if d[0] <= d[1] else ends[1]
        if min(d) > 3.0 * w + 5.0:
            return restarted  # not the rope seen so far (another object, a clipped view): no update
        k = self.frames
        self.fixed[:] = (self.fixed * k + chosen) / (k + 1)
        self.frames += 1
        return restarted

    def _still(self, points: NDArray[np.float32], n: int, e1: int, e2: int, w: float) -> bool:
        """Whether the outline (`n` (row, col) `points`, its ends at contour indices `e1`, `e2`, a rope `w` px wide)
        shows a rope at rest: its two ends as wide across as each other within `STILL_ACROSS_WIDTHS` rope widths (a
        free end that sweeps during the exposure widens its end of the band), and a band round the rope (it encloses
        at least `STILL_BAND` of half its points x the width)."""
        across = _across(points, n, e1, e2, w)
        if abs(across[0] - across[1]) > STILL_ACROSS_WIDTHS * w:
            return False
        return contour_area_px2(points, n) >= STILL_BAND * 0.5 * n * w

    def structure(self, points: NDArray[np.float32], n: int, width_px: float | None) -> NDArray[np.bool_] | None:
        """Return the region of the structure a still rope's outline (`n` (row, col) `points`, a rope `width_px`
        wide, None: 4 px) runs round at one end (a clamp, its rod: `structure.structure_points`): the convex hull
        of its outline and the rope's exit, with the outline's own pixels, grown by a pixel; or None (no end of
        the outline is such a structure)."""
        w = width_px or 4.0
        e1, e2, _ = self._ends(points, n, w)
        outline = points[:n].astype(np.float64)
        found = structure_points(outline, (e1, e2), w)
        if found is None:
            return None
        structure, exit_a, exit_b = found
        corners = convex_hull(np.concatenate([outline[structure], outline[[exit_a, exit_b]]]))
        if self.configured and np.hypot(*(corners - self.fixed).T).min() > HIDDEN_REACH_PX:
            return None  # not where the rope is fixed
        self._structure_at = corners.mean(axis=0)
        region = fill_polygon(corners, self.shape)
        rows = np.clip(np.rint(outline[structure, 0]).astype(np.intp), 0, self.shape[0] - 1)
        cols = np.clip(np.rint(outline[structure, 1]).astype(np.intp), 0, self.shape[1] - 1)
        region[rows, cols] = True
        return grow(region)

    def learned_structure(
        self,
        points: NDArray[np.float32],
        n: int,
        width_px: float | None,
        mask: NDArray[np.uint8],
        first_ends: list[NDArray[np.float32]] | None = None,
    ) -> NDArray[np.bool_] | None:
        """Return the region of the still structure the rope's outline (`n` (row, col) `points`, a rope `width_px`
        wide, None: 4 px) ends at, found in the still structures `mask` (its `K.MASK_STATIC` pixels: the learned
        mask, or `StaticMask.early`'s), or None.

        A rope already swinging when the stream starts does not run round its clamp as a still rope does
        (`structure`: its band is wider than the rope and its fixed end moves along the clamp's edge), and the
        learned mask has the clamp's outline but for the stretch the rope swept while it was learned: a gap where
        the rope leaves the clamp, whose edge pieces join the rope's outline once it swings on, and across which
        `hidden_end` sees no structure. The static pixels connected to an end of the outline (8-neighbours, within
        `HIDDEN_REACH_PX`) are a structure when their convex hull is no line (its thinnest width at least
        `LEARNED_THICK` of its extent and `LEARNED_THICK_WIDTHS` rope widths: a still stretch of the rope itself
        is a thin band), covers `LEARNED_AREA_WIDTHS` squared widths and is at most `STRUCTURE_ROPE_RATIO` of the
        rope's length (half the outline) across; the region is that hull filled, with
        its pixels, grown by a pixel (as `structure`'s).

        With `first_ends` (the ends of the stream's first outline), an end that moved away from both of them while
        the other end stayed within a rope width of one is the free tip: nothing there is taken. A faint rope's
        tip band (simulated `contrast = 30 DN` from 0.3 s, seed 3, frame 1: ~10 DN over the plate where its tip
        swept 7 px) changes by less than the still test's allowance between two frames, and its edge in the middle
        image made a block-like "structure" at the tip: the fixed end was then taken there, confirmed, and the
        frame reported OK with both tips 404 px off."""
        # The width learned on frames whose outline ran round the clamp is the clamp's (8 px on the simulated
        # 24 px clamp, seed 3 from 0.15 s); the matrix's widest rope is 4 px.
        w = min(width_px or 4.0, LEARNED_MAX_WIDTH_PX)
        _, _, ends = self._ends(points, n, w)
        height, width = self.shape
        static = mask == K.MASK_STATIC
        best: tuple[float, NDArray[np.float64], NDArray[np.bool_]] | None = None
        moved = [min(float(np.hypot(*(end - first))) for first in first_ends) for end in ends] if first_ends else []
        for k, end in enumerate(ends):
            if moved and moved[k] > max(2.0 * w, 5.0) and moved[1 - k] < w:
                continue  # the free tip, not where a structure holds the rope
            r, c = round(float(end[0])), round(float(end[1]))
            reach = int(HIDDEN_REACH_PX)
            r0, r1, c0, c1 = max(r - reach, 0), min(r + reach + 1, height), max(c - reach, 0), min(c + reach + 1, width)
            window = static[r0:r1, c0:c1]
            near = round(2.0 * w) + 2
            seed = np.zeros_like(window)
            sr0, sc0 = max(r - near - r0, 0), max(c - near - c0, 0)
            seed[sr0 : r - r0 + near + 1, sc0 : c - c0 + near + 1] = True
            component = seed & window
            if not component.any():
                continue
            while True:  # the 8-connected static pixels reached from the end
                grown = grow(component) & window
                if np.array_equal(grown, component):
                    break
                component = grown
            rows, cols = np.nonzero(component)
            pixels = np.stack([rows + r0, cols + c0], axis=1).astype(np.float64)
            if len(pixels) < 3:
                continue
            hull = convex_hull(pixels)
            if len(hull) < 3:
                continue
            thin, extent = _hull_widths(hull)
            area = 0.5 * abs(
                float(np.dot(hull[:, 0], np.roll(hull[:, 1], -1)) - np.dot(hull[:, 1], np.roll(hull[:, 0], -1)))
            )
            if thin < max(LEARNED_THICK * extent, LEARNED_THICK_WIDTHS * w) or area < LEARNED_AREA_WIDTHS * w * w:
                continue
            if extent > STRUCTURE_ROPE_RATIO * 0.5 * n:
                continue  # no small structure at the rope's end (dust all over a plate, learned as one)
            if self.configured and np.hypot(*(hull - self.fixed).T).min() > HIDDEN_REACH_PX:
                continue
            if best is None or area > best[0]:
                region = fill_polygon(hull, self.shape)
                region[r0:r1, c0:c1] |= component
                best = (area, hull, region)
        if best is None:
            return None
        self._structure_at = best[1].mean(axis=0)
        return grow(best[2])

    def end_points(self, points: NDArray[np.float32], n: int, width_px: float | None) -> list[NDArray[np.float32]]:
        """Return the middles of the rope's two ends on the outline (`n` (row, col) `points`, a rope `width_px` wide,
        None: 4 px; `_ends`)."""
        return self._ends(points, n, width_px or 4.0)[2]

    def _ends(self, points: NDArray[np.float32], n: int, w: float) -> tuple[int, int, list[NDArray[np.float32]]]:
        """The contour indices of the outline's two ends (the sharpest turn, and the point farthest from it) and
        the middles of the rope's ends there (`_cap_centre`)."""
        turn = self.buffers.turn
        K.turning_angles(ro(points), i32(n), i32(max(3, round(w))), turn)
        e1 = int(np.argmax(turn[:n]))
        e2 = int(np.argmax(np.hypot(points[:n, 0] - points[e1, 0], points[:n, 1] - points[e1, 1])))
        return e1, e2, [self._cap_centre(points, n, e, w) for e in (e1, e2)]

    def _cap_centre(self, points: NDArray[np.float32], n: int, e: int, w: float) -> NDArray[np.float32]:
        """The contour point in the middle of the rope end around contour index `e`: the turning-weighted centroid
        of the points within a width and a half of it, snapped to the contour (a flat end has two corners, its
        largest turning angle is at one of them)."""
        m = max(3, round(1.5 * w))
        idx = np.arange(e - m, e + m + 1) % n
        weights = self.buffers.turn[idx].astype(np.float64) ** 2
        if not weights.sum() > 0:
            return points[e].copy()
        centre = (points[idx].astype(np.float64) * weights[:, None]).sum(axis=0) / weights.sum()
        k = idx[int(np.argmin(np.hypot(points[idx, 0] - centre[0], points[idx, 1] - centre[1])))]
        return points[k].copy()


def hidden_end(
    end: NDArray[np.float32], points: NDArray[np.float32], width_px: float, mask: NDArray[np.uint8]
) -> NDArray[np.float32]:
    """Return the rope's end hidden inside the static structure it goes into at `end`, or `end` itself.

    A clamp over the fixed end hides the rope's last part: the rope's outline ends where it leaves the clamp
    (its sides sealed there, `seal_cut_ends`). When the static mask (the structure's edges, grown) lies next to
    `end`, the rope's axis is followed beyond `end` across the structure's edges (masked runs: its outline, its
    bolts') up to its far edge (the last run before `HIDDEN_GAP_PX` of unmasked pixels, within
    `HIDDEN_REACH_PX`), and the end is put halfway between the middles of the first and the last edge: the middle
    of the clamp along the rope, where a clamp centred on the fixed end holds it. Where the axis crosses a filled
    region (`MASK_ALWAYS`: a given mask, or the structure found from the rope's first outlines,
    `FixedEndFinder.structure`), the structure is that region: the end is put halfway between the first and the
    last of its pixels along the axis. Without a far edge (the axis runs up a rod out of the view) or without a
    mask next to `end`, `end` is kept. The plane calibration (or ``fixed_end_uv``) gives the fixed end exactly;
    this is the estimate without it.

    Parameters
    ----------
    end
        (row, col) float32: the rope's end on the contour.
    points
        (n, 2) float32 contour points (row, col).
    width_px
        The rope's edge spacing (px).
    mask
        (height, width) uint8 static mask (non-zero: masked).
    """
    height, width = mask.shape
    r0, c0 = float(end[0]), float(end[1])
    near = round(width_px) + 2
    ri, ci = round(r0), round(c0)
    if not mask[max(ri - near, 0) : ri + near + 1, max(ci - near, 0) : ci + near + 1].any():
        return end
    # The rope's axis at its end: from the middle of its contour points 3-6 widths away to the end.
    d = np.hypot(points[:, 0] - r0, points[:, 1] - c0)
    body = points[(d >= 3.0 * width_px + 3.0) & (d <= 6.0 * width_px + 6.0)]
    if len(body) < 4:
        return end
    axis = np.array([r0, c0]) - body.astype(np.float64).mean(axis=0)
    length = float(np.hypot(*axis))
    if length < 1.0:
        return end
    axis /= length
    runs: list[list[float]] = []  # [start, stop] distances of the masked runs along the axis
    region: list[float] = []  # distances of the pixels of a filled region (`MASK_ALWAYS`) along the axis
    inside = False
    gap = max(HIDDEN_GAP_PX, 4.0 * near)
    t = 0.0
    while t <= HIDDEN_REACH_PX:
        r, c = round(r0 + t * axis[0]), round(c0 + t * axis[1])
        if not (0 <= r < height and 0 <= c < width):
            break
        masked = mask[r, c] != 0
        if mask[r, c] == K.MASK_ALWAYS:
            region.append(t)
        if masked and not inside:
            runs.append([t, t])
        elif masked:
            runs[-1][1] = t
        inside = masked
        if not inside and t - (runs[-1][1] if runs else 0.0) > (gap if runs else near):
            break  # beyond the structure's last edge (or no structure right beyond the end)
        t += _STEP_PX
    if inside:
        return end
    if region:  # a filled region (a given mask, a structure found from the outline): its middle along the axis
        middle = 0.5 * (region[0] + region[-1])
    elif len(runs) >= 2:  # a learned structure's edges: halfway between the first and the last
        middle = 0.25 * (runs[0][0] + runs[0][1] + runs[-1][0] + runs[-1][1])
    else:
        return end
    return np.array([r0 + middle * axis[0], c0 + middle * axis[1]], np.float32)


def _across(points: NDArray[np.float32], n: int, e1: int, e2: int, w: float) -> list[float]:
    """The widths across the outline's (`n` (row, col) `points`) two ends at contour indices `e1`, `e2` (a rope `w` px
    wide): the distance between the points `2 w` (at least 4) contour points either side of each."""
    m = max(4, round(2 * w))
    return [float(np.hypot(*(points[(e - m) % n] - points[(e + m) % n]))) for e in (e1, e2)]


def _attached_structure(
    points: NDArray[np.float32], e1: int, e2: int, ends: list[NDArray[np.float32]], width_px: float
) -> int | None:
    """Which of the outline's two ends (0: at contour index `e1`, 1: `e2`; `ends` their cap centres) is a
    structure the rope is attached to (a clamp), or None.

    The first guess takes the narrower end for the fixed one because the free end sweeps: the band then widens
    along the rope, and its middle is wider than a still rope. An end much thicker than the other (the spread
    across the outline's points within 4 widths of it) on a band whose middle is as narrow as a still rope is no
    sweep: a still rope joined to a clamp, whose end that is. On `clamp size = 24 px` (simulated) the rope at rest
    after the release was measured from its free end (a rope length off) before this rule.
    """
    n = len(points)
    spread = []
    for end in ends:
        near = points[np.hypot(points[:, 0] - end[0], points[:, 1] - end[1]) <= 4.0 * width_px + 4.0]
        if len(near) < 3:
            return None
        spread.append(float(np.sqrt(max(np.linalg.eigvalsh(np.cov(near.astype(np.float64).T))[0], 0.0))))
    wide = 0 if spread[0] > spread[1] else 1
    narrow = spread[1 - wide]
    if not spread[wide] > 2.5 * narrow:
        return None
    # The band's middle: a point half-way round one side, and the nearest point of the other side.
    middle_index = (e1 + ((e2 - e1) % n) // 2) % n
    offset = np.abs((np.arange(n) - middle_index + n // 2) % n - n // 2)
    across = points[offset > 3.0 * width_px] - points[middle_index]
    if len(across) == 0:
        return None
    middle = float(np.hypot(across[:, 0], across[:, 1]).min())
    return wide if middle <= 2.3 * narrow else None


def _hull_widths(hull: NDArray[np.float64]) -> tuple[float, float]:
    """The thinnest width of a convex polygon `hull` ((m, 2) corners in order: over its edges' directions, the
    farthest corner from each edge's line) and its extent (the farthest two corners apart)."""
    edges = np.roll(hull, -1, axis=0) - hull
    lengths = np.hypot(edges[:, 0], edges[:, 1])
    keep = lengths > 0
    normals = np.stack([-edges[keep, 1], edges[keep, 0]], axis=1) / lengths[keep, None]
    depth = np.abs(((hull[None, :, :] - hull[keep][:, None, :]) * normals[:, None, :]).sum(axis=2)).max(axis=1)
    extent = float(np.max(np.hypot(*(hull[:, None, :] - hull[None, :, :]).transpose(2, 0, 1))))
    return float(depth.min()), extent
