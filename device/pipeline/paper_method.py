"""PaperSegmenter: the paper's motion-blur segmentation (``method = "paper"``), as literally as the text allows.

Closed single-pixel edge chain -> segmentation operator tau (eqs. 1-7) -> knots (tau != 0) scored with Features 1-3
(Table 1) -> candidates (score >= 2) clustered -> the two segmentation points at the free end -> the chain from the
fixed end to each of them is the rope at one instant of the exposure (integer pixels, as in the paper). The
ambiguities of the OCR-damaged text and how they are read are listed in docs/pipeline.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import f32, i32, ro
from ropecam.device.pipeline.centerline import CenterlineExtractor
from ropecam.device.pipeline.result import Method, SplitOutcome

__all__ = ["PaperSegmenter", "PaperSplit", "split_by_comparison"]

CANDIDATE_SCORE = 2.0
"""Table 1's first two grades (2.5 and 2) are the candidate segmentation points."""


@dataclass(slots=True)
class PaperSplit:
    """The two shapes found by the paper's method (views into the segmenter's buffers, valid until its next call).

    `shape_a` and `shape_b` are (k, 2) float32 (row, col) polylines on the integer edge chain, fixed end first,
    not yet in time order. `segmentation_points` (2, 2) are their free ends; `sweep_px` the distance between them;
    `radius_px` the Feature 3 threshold T used; `candidates` the number of knots that scored >= 2.
    """

    shape_a: NDArray[np.float32]
    shape_b: NDArray[np.float32]
    segmentation_points: NDArray[np.float32]
    sweep_px: float
    radius_px: float
    candidates: int


class PaperSegmenter:
    """Split a rope's closed edge chain with the paper's operator and scoring.

    Parameters
    ----------
    capacity
        Maximum number of chain pixels.
    endpoint_radius_px
        Threshold T of Feature 3 (the paper: 15 px).
    radius_scaled
        When true, T is ``max(endpoint_radius_px, band width at the tip + rope width)``: the segmentation points
        lie up to a band width from the centreline's free end, which at long exposures is more than 15 px.
        When false, T is `endpoint_radius_px` as printed. A public attribute (the pipeline sets it from
        ``paper_endpoint_radius_scaled``).
    cluster_px
        Candidates following each other along the chain closer than this (px) are one cluster.
    output_step_px
        Spacing of the returned polylines (px).
    """

    def __init__(
        self,
        capacity: int,
        endpoint_radius_px: float = 15.0,
        radius_scaled: bool = True,
        cluster_px: float = 5.0,
        output_step_px: float = 2.0,
    ) -> None:
        if capacity < 8:
            raise ValueError(f"capacity must be >= 8 chain pixels, got {capacity}")
        for name, value in (("endpoint_radius_px", endpoint_radius_px), ("cluster_px", cluster_px)):
            if not value > 0:
                raise ValueError(f"{name} must be > 0, got {value}")
        self.endpoint_radius_px = float(endpoint_radius_px)
        self.radius_scaled = bool(radius_scaled)
        self.cluster_px = float(cluster_px)
        self.step = f32(output_step_px)
        self.centerline = CenterlineExtractor(capacity, output_step_px)
        """The centreline whose ends and width Feature 3 uses (extract it first); also `method = "centerline"`."""
        self.thin = np.zeros((capacity, 2), np.int32)
        self.thin_index = np.zeros(capacity, np.int32)
        self.thin_f = np.zeros((capacity, 2), np.float32)
        self.tau = np.zeros(capacity, np.int32)
        self.knots = np.zeros(capacity, np.int32)
        self.scores = np.zeros(capacity, np.float32)
        self.side_a = np.zeros((capacity, 2), np.float32)
        self.side_b = np.zeros((capacity, 2), np.float32)
        self.out_a = np.zeros((capacity, 2), np.float32)
        self.out_b = np.zeros((capacity, 2), np.float32)
        self.seg = np.zeros((2, 2), np.float32)
        self.count = 0
        self.knot_count = 0
        self.radius_px = float(endpoint_radius_px)
        self.clusters_rc = np.zeros((0, 2), np.float32)
        """The kept candidate of each cluster near the free end in the last call, (k, 2) (row, col)."""

    def segment(
        self,
        chain: NDArray[np.int32],
        n: int,
        fixed_rc: tuple[float, float],
        e1_rc: tuple[float, float],
        e2_rc: tuple[float, float],
        band_width_px: float,
        rope_width_px: float,
    ) -> PaperSplit | None:
        """Find the two segmentation points at the free end and the two shapes.

        Parameters
        ----------
        chain
            (capacity, 2) int32 (row, col) closed edge chain; the first `n` pixels are used (read only).
        n
            Number of chain pixels.
        fixed_rc
            The fixed end (row, col) px: both shapes start at the chain pixel nearest to it.
        e1_rc, e2_rc
            The ends of the centreline (row, col) px (Feature 3): the fixed end and the band's free end.
        band_width_px
            Widest distance across the band (rope width + sweep, from the centreline), for the scaled T.
        rope_width_px
            Rope width (px).

        Returns
        -------
        PaperSplit or None
            None when fewer than two candidate clusters lie near the free end (no split: the paper then uses the
            centreline, as for slow motion).
        """
        self.clusters_rc = self.clusters_rc[:0]
        m = int(K.thin_chain(ro(chain), i32(n), self.thin, self.thin_index))
        self.count = max(m, 0)
        if m < 8:
            return None
        thin = ro(self.thin)
        K.apply_operator(thin, i32(m), self.tau)
        radius = self.endpoint_radius_px
        if self.radius_scaled and np.isfinite(band_width_px):
            radius = max(radius, float(band_width_px) + float(rope_width_px))
        self.radius_px = radius
        e1_r, e1_c, e2_r, e2_c = (f32(v) for v in (*e1_rc, *e2_rc))
        k = int(K.score_knots(thin, ro(self.tau), i32(m), e1_r, e1_c, e2_r, e2_c, f32(radius), self.knots, self.scores))
        self.knot_count = max(k, 0)
        if k < 2:
            return None
        self.thin_f[:m] = self.thin[:m]
        pos = self.thin_f[self.knots[:k]]
        scores = self.scores[:k]
        d_e1 = np.hypot(pos[:, 0] - e1_rc[0], pos[:, 1] - e1_rc[1])
        d_e2 = np.hypot(pos[:, 0] - e2_rc[0], pos[:, 1] - e2_rc[1])
        # Candidates near the free end; those near the fixed end are the shapes' start points, which for a pinned
        # rope coincide with the fixed end.
        tip = np.flatnonzero((scores >= CANDIDATE_SCORE) & (d_e2 < radius) & (d_e2 < d_e1))
        i_fix = int(np.argmin(np.hypot(self.thin_f[:m, 0] - fixed_rc[0], self.thin_f[:m, 1] - fixed_rc[1])))
        i_far = int(np.argmax(np.hypot(self.thin_f[:m, 0] - fixed_rc[0], self.thin_f[:m, 1] - fixed_rc[1])))
        # The free end's two segmentation points bound the tip's track, which holds the band's far point: one lies
        # on each side of the contour (fixed end -> far point forward, and backward). Each side keeps its best
        # cluster.
        # Walk order from the fixed end: each side is then one run of candidates, whatever the chain's start.
        tip = tip[np.argsort((self.knots[tip] - i_fix) % m, kind="stable")]
        ahead = (self.knots[tip] - i_fix) % m <= (i_far - i_fix) % m
        chain_to_far = np.minimum((self.knots[tip] - i_far) % m, (i_far - self.knots[tip]) % m)
        picks = []
        kept = []
        for side in (ahead, ~ahead):
            clusters = self._cluster(tip[side], pos, scores, chain_to_far[side])
            kept.extend(c for c, _ in clusters)
            if clusters:
                picks.append(min(clusters, key=lambda item: item[1])[0])
        self.clusters_rc = pos[kept]
        if len(picks) < 2:
            return None
        ia, ib = int(self.knots[picks[0]]), int(self.knots[picks[1]])
        thin_f = ro(self.thin_f)
        zero = f32(0.0)
        na = K.offset_side(thin_f, i32(m), i32(i_fix), i32(ia), i32(1), f32(1.0), zero, zero, i32(1), self.side_a)
        nb = K.offset_side(thin_f, i32(m), i32(i_fix), i32(ib), i32(-1), f32(1.0), zero, zero, i32(1), self.side_b)
        if na < 2 or nb < 2:
            return None
        ca = int(K.resample_polyline(ro(self.side_a), i32(na), self.step, self.out_a))
        cb = int(K.resample_polyline(ro(self.side_b), i32(nb), self.step, self.out_b))
        if ca < 2 or cb < 2:
            return None
        self.seg[0] = self.thin_f[ia]
        self.seg[1] = self.thin_f[ib]
        sweep = float(np.hypot(*(self.seg[0] - self.seg[1])))
        return PaperSplit(self.out_a[:ca], self.out_b[:cb], self.seg, sweep, radius, len(tip))

    def _cluster(
        self,
        candidates: NDArray[np.intp],
        pos: NDArray[np.float32],
        scores: NDArray[np.float32],
        chain_to_far: NDArray[np.intp],
    ) -> list[tuple[int, tuple[float, float, int]]]:
        """Group candidates (knot numbers, in walk order) that follow each other closer than `cluster_px`; keep
        one per group: the best score, ties to the member in the middle.

        Returns (kept knot, rank key) per group; the smallest key is the best group: highest member score, then
        highest total score (a corner yields several candidates, noise one), then nearest the far point along the
        chain.
        """
        groups: list[list[tuple[int, int]]] = []
        for j, c in enumerate(candidates.tolist()):
            if groups and np.hypot(*(pos[c] - pos[groups[-1][-1][0]])) < self.cluster_px:
                groups[-1].append((c, j))
            else:
                groups.append([(c, j)])
        kept = []
        for g in groups:
            top = max(float(scores[c]) for c, _ in g)
            best = [(c, j) for c, j in g if scores[c] == top]
            c, j = best[len(best) // 2]
            total = sum(float(scores[c]) for c, _ in g)
            kept.append((c, (-top, -total, int(chain_to_far[j]))))
        return kept


def split_by_comparison(
    method: str,
    paper: PaperSegmenter,
    points: NDArray[np.float32],
    chain: NDArray[np.int32],
    n: int,
    fixed_rc: tuple[float, float],
    width_px: float,
) -> tuple[SplitOutcome | None, float | None]:
    """Split a contour (`n` subpixel `points`, chain pixels `chain`) by a comparison method: ``centerline``
    (`CenterlineExtractor`, one shape) or ``paper`` (`PaperSegmenter`, which scores the knots against the
    centreline's ends, Feature 3; where it finds no two segmentation points, slow motion whose blur is too
    narrow to split, it reports the centreline, as the paper does).

    Returns the outcome (None: no centreline) and the sweep (px) that sizes the next frame's ROI (None: none
    measured).
    """
    dist = np.hypot(points[:n, 0] - fixed_rc[0], points[:n, 1] - fixed_rc[1])
    i_fix, i_far = int(np.argmin(dist)), int(np.argmax(dist))
    centerline = paper.centerline
    line = centerline.extract(points, n, i_fix, i_far)
    if line is None:
        return None, None
    # The band is a rope width plus the sweep wide at its widest: the sweep sizes the next frame's ROI.
    sweep_px = max(0.0, centerline.band_width_px - width_px)
    centre = SplitOutcome(Method.CENTERLINE, line, line, None, width_px, sweep_px)
    if method == "centerline":
        return centre, sweep_px
    e1 = (float(line[0, 0]), float(line[0, 1]))
    e2 = (float(line[-1, 0]), float(line[-1, 1]))
    found = paper.segment(chain, n, fixed_rc, e1, e2, centerline.band_width_px, width_px)
    if found is None:
        return centre, sweep_px
    outcome = SplitOutcome(
        Method.PAPER, found.shape_a, found.shape_b, found.segmentation_points, width_px, found.sweep_px
    )
    return outcome, found.sweep_px
