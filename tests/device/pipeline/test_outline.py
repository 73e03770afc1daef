"""The outline check: a contour that walks its pixels twice is no band outline (`count_revisits`); short walks
back (spurs and small loops of noise) are taken out of it first (`prune_excursions`)."""

from __future__ import annotations

import numpy as np

from ropecam.device.pipeline import _kernels as K


def _chain(pixels: list[tuple[int, int]]) -> np.ndarray:
    out = np.array(pixels, np.int32)
    out.flags.writeable = False
    return out


def test_a_loop_walks_each_pixel_once_and_a_spur_twice() -> None:
    edges = np.zeros((12, 12), np.uint8)
    loop = [(2, c) for c in range(2, 9)] + [(r, 8) for r in range(3, 6)] + [(5, c) for c in range(7, 1, -1)]
    loop += [(r, 2) for r in range(4, 2, -1)] + [(2, 2)]  # closed on its first pixel
    for r, c in loop:
        edges[r, c] = 1
    before = edges.copy()
    assert K.count_revisits(_chain(loop), np.int32(len(loop)), edges) == 0
    # the same edge pixels walked out along a spur and back (a broken band's tree walk)
    spur = [(2, c) for c in range(2, 9)] + [(2, c) for c in range(7, 1, -1)]
    assert K.count_revisits(_chain(spur), np.int32(len(spur)), edges) == 5  # (2, 3)..(2, 7); (2, 2) closes it
    np.testing.assert_array_equal(edges, before)  # the marks are cleared
    assert K.count_revisits(_chain([(2, 2), (20, 3)]), np.int32(2), edges) == -1
    np.testing.assert_array_equal(edges, before)


def _ring(top: int, left: int, bottom: int, right: int) -> list[tuple[int, int]]:
    """The pixels of a rectangle's outline, clockwise from its top-left corner (not closed)."""
    ring = [(top, c) for c in range(left, right + 1)] + [(r, right) for r in range(top + 1, bottom + 1)]
    ring += [(bottom, c) for c in range(right - 1, left - 1, -1)] + [(r, left) for r in range(bottom - 1, top, -1)]
    return ring


def _prune_reference(chain: list[tuple[int, int]], codes: list[int]) -> tuple[list[tuple[int, int]], list[int]]:
    """`prune_excursions` as its rule reads, on lists: from a point's first visit (not inside a longer walk back
    kept), the walk to its last visit (the chain's last point not counted) dropped when at most MAX_EXCURSION
    points long, enclosing at most EXCURSION_AREA_PX2 plus half a pixel per point, and followed by a point more
    than a pixel from the one before it."""
    n = len(chain)
    if n < 8:
        return chain, codes
    last = {point: k for k, point in enumerate(chain[:-1])}
    if any(
        k < last[chain[k]] and last[chain[k]] >= n - 1 - K.MAX_EXCURSION for k in range(min(K.MAX_EXCURSION, n - 1))
    ):
        return chain, codes  # the trace starts inside a walk out and back that ends with the chain
    kept: list[tuple[int, int]] = []
    kept_codes: list[int] = []
    protect = -1
    k = 0
    while k < n:
        back = last[chain[k]] if k < n - 1 else k
        jump = k
        if back > k > protect:
            walk = chain[k : back + 1]
            area = 0.5 * abs(
                sum(c0 * r1 - c1 * r0 for (r0, c0), (r1, c1) in zip(walk, walk[1:] + walk[:1], strict=True))
            )
            goes_on = k > 0 and back < n - 1 and max(map(abs, np.subtract(chain[back + 1], chain[k - 1]))) > 1
            if back - k <= K.MAX_EXCURSION and area <= K.EXCURSION_AREA_PX2 + 0.5 * (back - k) and goes_on:
                jump = back
            else:
                protect = back
        kept.append(chain[k])
        kept_codes.append(codes[jump])
        k = jump + 1
    return kept, kept_codes


def _prune(chain: list[tuple[int, int]], width: int, codes: list[int] | None = None) -> tuple[list, list[int]]:
    array = np.array(chain, np.int32).reshape(-1, 2)
    code_array = np.array(codes if codes is not None else [k % 8 for k in range(len(chain))], np.int32)
    scratch = np.full(60 * width, -7, np.int32)
    n = K.prune_excursions(array, code_array, np.int32(len(chain)), width, scratch)
    return [tuple(p) for p in array[:n].tolist()], code_array[:n].tolist()


def test_prune_excursions_takes_out_a_spur_and_a_small_loop_hung_on_an_outline() -> None:
    ring = _ring(10, 10, 40, 70)
    spur = [(11 + t, 30) for t in range(12)]  # 12 px into the band from the top side
    loop = [(39, 49), (38, 49), (37, 50), (37, 51), (38, 52), (39, 51)]  # a small ring on the bottom side
    top = ring.index((10, 30))
    bottom = ring.index((40, 50))
    chain = ring[: top + 1] + spur + spur[-2::-1] + [(10, 30)]  # out along the spur and back to the side
    chain += ring[top + 1 : bottom + 1] + loop + ring[bottom:]  # round the loop and back to the side
    codes = [k % 8 for k in range(len(chain))]
    got, got_codes = _prune(chain, 80, codes)
    assert got == ring  # the spur and the loop taken out, each junction kept once
    back_from_spur = top + 2 * len(spur)  # the junction's last visit
    assert got_codes[top] == codes[back_from_spur] and got_codes[top + 1] == codes[back_from_spur + 1]
    assert (got, got_codes) == _prune_reference(chain, codes)


def test_prune_excursions_keeps_an_outline_walked_once_and_a_long_walk_back_whole() -> None:
    ring = _ring(10, 10, 40, 70)
    assert _prune(ring, 80) == (ring, [k % 8 for k in range(len(ring))])
    # A side walked out and back for longer than MAX_EXCURSION (a broken band edge), with a short spur on it:
    # kept whole, not eaten from its far end, for the outline check.
    line = [(10, c) for c in range(10, 10 + K.MAX_EXCURSION)]
    spur = [(11, 40), (12, 40), (11, 40)]
    chain = line[:31] + spur + line[30:] + line[-2:0:-1]
    got, _ = _prune(chain, 200)
    assert got == chain
    # A clamp's outline (12 px) hung on the rope's at one pixel: a wide loop, kept (the clamp's search reads it).
    top = ring.index((10, 30))
    clamp = [(r, 30) for r in range(9, 3, -1)] + [(4, c) for c in range(31, 37)] + [(r, 36) for r in range(5, 10)]
    clamp += [(9, c) for c in range(35, 30, -1)]
    chain = ring[: top + 1] + clamp + ring[top:]
    assert _prune(chain, 200)[0] == chain
    # A closed chain that ends on its first pixel: that is no walk back.
    closed = ring + ring[:1]
    assert _prune(closed, 80)[0] == closed


def test_prune_excursions_matches_a_slow_reference() -> None:
    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(1, 400))
        side = int(rng.integers(3, 12))  # few pixels: many revisits, near and far
        chain = [(int(r), int(c)) for r, c in rng.integers(0, side, (n, 2))]
        if rng.random() < 0.3:
            chain = list(dict.fromkeys(chain))  # no pixel twice
        codes = rng.integers(0, 8, len(chain)).tolist()
        assert _prune(chain, 30, codes) == _prune_reference(chain, codes)
    # a pixel outside the scratch map: nothing taken out
    outside = [(0, 0), (1, 0), (0, 0)] * 4 + [(99, 0), (2, 0)]
    assert _prune(outside, 30)[0] == outside


def _band_with_side_gap(gap: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 60 x 200 edge map: a band's outline (rows 20-30, cols 10-180) whose lower side has a gap of `gap` px
    starting at column 120, with the full-frame spans."""
    edges = np.zeros((60, 200), np.uint8)
    for r, c in _ring(20, 10, 30, 180):
        if not (r == 30 and 120 <= c < 120 + gap):
            edges[r, c] = 1
    lo = np.zeros(60, np.int32)
    hi = np.full(60, 199, np.int32)
    return edges, lo, hi


def test_rejoin_gap_closes_a_gap_in_a_bands_side_and_leaves_a_wide_one() -> None:
    """Noise or texture breaks one side of a sweeping band where it is faint: the outline is walked out and back
    (its two sides then differ in length and the split is rejected). `ContourTracer.rejoin_gap` joins the gap's two
    ends within its reach and traces a ring again; a gap beyond the reach is left, and the chain with it."""
    from types import SimpleNamespace

    from ropecam.device.pipeline._views import ro
    from ropecam.device.pipeline.contour import ContourTracer

    for gap, joined in ((14, True), (30, False)):
        edges, lo, hi = _band_with_side_gap(gap)
        planes = np.ones((60, 200), np.float32)
        tracer = ContourTracer(60, 200, 4000, 10)
        n = tracer.trace(edges.copy(), lo, hi, planes, planes, planes)
        component = int(edges.sum())
        assert n > 1.3 * component  # the side's pieces walked out and back
        before = tracer.chain[:n].copy()
        detector = SimpleNamespace(
            edges=edges, spans=(ro(lo), ro(hi)), mag_ro=ro(planes), gx_ro=ro(planes), gy_ro=ro(planes)
        )
        m = tracer.rejoin_gap(detector, 20)  # type: ignore[arg-type]
        if joined:
            ring = 2 * (180 - 10) + 2 * (30 - 20)
            assert abs(m - ring) <= 4, (m, ring)
            assert K.count_revisits(ro(tracer.chain), np.int32(m), edges) <= K.JOINED_REVISITS * m
            assert tracer.count == m
        else:
            assert m == 0
            np.testing.assert_array_equal(tracer.chain[:n], before)
        np.testing.assert_array_equal(edges, _band_with_side_gap(gap)[0])  # the detector's map is left as it was
