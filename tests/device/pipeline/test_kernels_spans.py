"""The band of row spans around a chain of points (`spans_around_chain`) against a slow, obvious union of discs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ropecam.device.pipeline import _kernels as K

_NO_PROFILE = np.zeros(0)  # `spans_around_chain` without a measured profile
_NO_MOVED = np.zeros((0, 2), np.float32)  # nor the moved points

pytestmark = pytest.mark.kernel


def _disc_spans(points, margin, motion, rot, fixed, height, width, profile=None):
    """Row spans of the union of the discs of every point (moved, radius margin + ceil(motion * d / d_max); with a
    profile, margin + ceil(min(profile[bin of d / d_max], 2 * motion * d / d_max)) where the bin is finite)."""
    lo = np.full(height, width, np.int64)
    hi = np.full(height, -1, np.int64)
    finite = np.isfinite(points).all(axis=1)
    z = (points[:, 0].astype(np.float64) - fixed[0]) + 1j * (points[:, 1].astype(np.float64) - fixed[1])
    d_max = np.abs(z[finite]).max()
    for k in np.flatnonzero(finite):
        share = abs(z[k]) / d_max
        u = motion * share
        if profile is not None and len(profile):
            cap = profile[min(len(profile) - 1, int(share * len(profile)))]
            if math.isfinite(cap):
                u = min(cap, 2.0 * u)
        m = margin + math.ceil(u)
        q = complex(*rot) * z[k]
        qr, qc = fixed[0] + q.real, fixed[1] + q.imag
        for r in range(max(0, math.ceil(qr - m)), min(height - 1, math.floor(qr + m)) + 1):
            half = math.sqrt(max(0.0, m * m - (r - qr) ** 2))
            c0, c1 = max(0, math.floor(qc - half)), min(width - 1, math.ceil(qc + half))
            if c0 <= c1:
                lo[r], hi[r] = min(lo[r], c0), max(hi[r], c1)
    return lo, hi


def _chain(kind, rng):
    """A closed, 8-connected-like chain of subpixel points (steps about 1 px), as the contour tracer gives."""
    if kind == "rope":  # the outline of a bent rope hanging from (20, 60): down one side, round the tip, up
        s = np.linspace(0.0, 1.0, 160)
        centre = np.column_stack([20 + 150 * s, 60 + 40 * s**2])
        normal = np.column_stack([-80 * s, np.full_like(s, 150.0)])
        normal /= np.hypot(*normal.T)[:, None]
        tip = [centre[-1] + 4 * np.array([math.sin(a), math.cos(a)]) for a in np.linspace(0, math.pi, 12)]
        path = np.vstack([centre + 4 * normal, tip, (centre - 4 * normal)[::-1]])
    elif kind == "flat":  # nearly horizontal
        x = np.linspace(10, 190, 200)
        path = np.column_stack([40 + 0.08 * x + 3 * np.sin(x / 30), x])
    else:  # a wiggly loop
        a = np.linspace(0, 2 * math.pi, 400, endpoint=False)
        path = np.column_stack([90 + (50 + 6 * np.sin(5 * a)) * np.sin(a), 100 + (70 + 6 * np.cos(3 * a)) * np.cos(a)])
    # resample at ~1 px steps, add subpixel jitter
    steps = np.hypot(*np.diff(path, axis=0).T)
    t = np.concatenate([[0], np.cumsum(steps)])
    u = np.arange(0, t[-1], 1.0)
    chain = np.column_stack([np.interp(u, t, path[:, 0]), np.interp(u, t, path[:, 1])])
    return (chain + rng.normal(0, 0.15, chain.shape)).astype(np.float32)


@pytest.mark.parametrize("kind", ["rope", "flat", "loop"])
@pytest.mark.parametrize(("margin", "motion", "rot"), [(4, 0.0, (1.0, 0.0)), (4, 9.0, (0.995, 0.08)),
                                                       (6, 3.0, (1.02, -0.05))])  # fmt: skip
def test_band_holds_every_disc_and_is_hardly_wider(kind, margin, motion, rot) -> None:
    rng = np.random.default_rng(7)
    points = _chain(kind, rng)
    height, width = 200, 220
    fixed = (20.0, 60.0)
    lo = np.zeros(height, np.int32)
    hi = np.zeros(height, np.int32)
    rows = K.spans_around_chain(
        points, len(points), margin, motion, _NO_PROFILE, *rot, *fixed, height, width, lo, hi, _NO_MOVED
    )
    ref_lo, ref_hi = _disc_spans(points, margin, motion, rot, fixed, height, width)
    ref_rows = ref_hi >= ref_lo
    assert rows == np.count_nonzero(hi >= lo)
    assert np.all(hi[ref_rows] >= lo[ref_rows])
    assert np.all(lo[ref_rows] <= ref_lo[ref_rows]) and np.all(hi[ref_rows] >= ref_hi[ref_rows])  # never smaller
    extra_rows = (hi >= lo) & ~ref_rows
    assert np.count_nonzero(extra_rows) <= 6  # the pieces' widening, at the band's ends
    assert np.all(lo[~(hi >= lo)] == 1) and np.all(hi[~(hi >= lo)] == 0)  # empty rows as (1, 0)
    # Hardly wider: inside the discs grown by the largest distance a piece keeps from its points (0.5 px), but
    # for the few pixels of the wedges' bounding boxes.
    wide_lo, wide_hi = _disc_spans(points, margin + 0.5, motion, rot, fixed, height, width)
    band = hi >= lo
    beyond = np.maximum(wide_lo[band] - lo[band], 0).sum() + np.maximum(hi[band] - wide_hi[band], 0).sum()
    assert beyond <= 0.01 * np.sum(np.maximum(ref_hi - ref_lo + 1, 0)) + 5


def test_band_of_a_chain_with_gaps_and_unordered_points() -> None:
    rng = np.random.default_rng(11)
    points = _chain("rope", rng)
    points[50:53] = np.nan  # a gap: two runs
    points = np.vstack([points, rng.uniform([0, 0], [200, 220], (5, 2)).astype(np.float32)])  # stray points
    height, width = 200, 220
    lo = np.zeros(height, np.int32)
    hi = np.zeros(height, np.int32)
    K.spans_around_chain(
        points, len(points), 4, 5.0, _NO_PROFILE, 1.0, 0.0, 20.0, 60.0, height, width, lo, hi, _NO_MOVED
    )
    ref_lo, ref_hi = _disc_spans(points, 4, 5.0, (1.0, 0.0), (20.0, 60.0), height, width)
    ref_rows = ref_hi >= ref_lo
    assert np.all(lo[ref_rows] <= ref_lo[ref_rows]) and np.all(hi[ref_rows] >= ref_hi[ref_rows])
    assert np.count_nonzero((hi >= lo) & ~ref_rows) <= 8


@pytest.mark.parametrize("kind", ["rope", "loop"])
def test_band_with_a_measured_profile_holds_its_discs_and_writes_the_moved_points(kind) -> None:
    rng = np.random.default_rng(5)
    points = _chain(kind, rng)
    height, width = 200, 220
    fixed = (20.0, 60.0)
    rot = (0.995, 0.08)
    profile = np.array([0.0, 1.0, 2.5, np.inf, 3.0, 7.0, 4.0, 0.5])  # some bins below, some above 2 x motion * s
    profile.flags.writeable = False
    lo = np.zeros(height, np.int32)
    hi = np.zeros(height, np.int32)
    moved = np.zeros((len(points), 2), np.float32)
    rows = K.spans_around_chain(points, len(points), 4, 6.0, profile, *rot, *fixed, height, width, lo, hi, moved)
    ref_lo, ref_hi = _disc_spans(points, 4, 6.0, rot, fixed, height, width, profile)
    ref_rows = ref_hi >= ref_lo
    assert rows == np.count_nonzero(hi >= lo)
    assert np.all(lo[ref_rows] <= ref_lo[ref_rows]) and np.all(hi[ref_rows] >= ref_hi[ref_rows])  # never smaller
    wide_lo, wide_hi = _disc_spans(points, 5, 6.0, rot, fixed, height, width, profile)  # grown by 1 px
    band = hi >= lo
    beyond = np.maximum(wide_lo[band] - lo[band], 0).sum() + np.maximum(hi[band] - wide_hi[band], 0).sum()
    assert beyond <= 0.01 * np.sum(np.maximum(ref_hi - ref_lo + 1, 0)) + 5
    z = (points[:, 0].astype(np.float64) - fixed[0]) + 1j * (points[:, 1].astype(np.float64) - fixed[1])
    q = complex(*rot) * z
    np.testing.assert_allclose(moved, np.column_stack([fixed[0] + q.real, fixed[1] + q.imag]), atol=1e-3)
    # A smaller band than without the profile where the profile is small, a larger one where it is large.
    plain_lo = np.zeros(height, np.int32)
    plain_hi = np.zeros(height, np.int32)
    K.spans_around_chain(
        points, len(points), 4, 6.0, _NO_PROFILE, *rot, *fixed, height, width, plain_lo, plain_hi, _NO_MOVED
    )
    width_with = np.maximum(hi - lo + 1, 0)
    width_plain = np.maximum(plain_hi - plain_lo + 1, 0)
    assert np.any(width_with < width_plain) and np.any(width_with > width_plain)


def _radius(d2: float, d_max: float, profile: np.ndarray, margin: int, motion: float) -> tuple[int, int]:
    """(bin, disc radius) of a point at squared distance `d2` from the fixed end, written out plainly."""
    share = math.sqrt(d2) / d_max
    u = motion * share
    k = min(len(profile) - 1, int(share * len(profile))) if len(profile) else 0
    if len(profile) and math.isfinite(profile[k]):
        u = min(profile[k], 2.0 * u)
    return k, margin + math.ceil(u)


@pytest.mark.parametrize("motion", [0.0, 3.0, 12.5])
def test_radius_range_holds_the_radius_of_every_squared_distance_in_it(motion) -> None:
    """`_radius_range` (the band kernel takes the radius of a point in it without computing it) against the radius
    computed at the range's ends, next to them and inside."""
    from ropecam.device.pipeline._kernels.spans import _radius_range

    rng = np.random.default_rng(2)
    d2_max = 157.3**2
    d_max = math.sqrt(d2_max)
    profiles = (np.zeros(0), np.array([2.0, 2.0, 2.0, 3.5, np.inf, np.inf, 1.2, 1.2]), np.full(16, 1.85))
    for profile in profiles:
        profile.flags.writeable = False
        ranges = 0
        for d2 in rng.uniform(0.0, d2_max, 40):
            k, m = _radius(d2, d_max, profile, 4, motion)
            cap = profile[k] if len(profile) else math.inf
            lo, hi = _radius_range(profile, k, cap, m, d_max, d2_max, 4, motion)
            if lo > hi:
                continue
            ranges += 1
            assert lo >= 0.0 and hi <= d2_max
            inside = [lo, hi, np.nextafter(lo, np.inf), np.nextafter(hi, -np.inf), *rng.uniform(lo, hi, 20)]
            assert all(_radius(float(x), d_max, profile, 4, motion)[1] == m for x in inside if lo <= x <= hi)
        assert ranges >= 30  # the range is found for nearly every point (else the kernel computes every radius)


def _rectangle_spans(p_r, p_c, u_r, u_c, length, radius, reach, height, width, lo, hi):
    """`_draw_rectangle` written plainly: per row, the columns of the rectangle's two strips, clipped."""
    r0 = max(0, math.ceil(min(p_r, p_r + length * u_r) - reach))
    r1 = min(height - 1, math.floor(max(p_r, p_r + length * u_r) + reach))
    for r in range(r0, r1 + 1):
        y = r - p_r
        x0, x1 = -1e18, 1e18
        if abs(u_c) > 1e-6:  # 0 <= (X - P).u <= length
            t0 = -u_r / u_c * y
            t1 = t0 + length / u_c
            x0, x1 = max(x0, min(t0, t1)), min(x1, max(t0, t1))
        if abs(u_r) > 1e-6:  # |(X - P).n| <= radius
            s = u_c / u_r * y
            x0, x1 = max(x0, s - abs(radius / u_r)), min(x1, s + abs(radius / u_r))
        if x0 <= x1:
            c0, c1 = max(0, math.floor(p_c + x0)), min(width - 1, math.ceil(p_c + x1))
            if c0 <= c1:
                lo[r], hi[r] = min(lo[r], c0), max(hi[r], c1)


def test_draw_rectangle_matches_the_plain_row_loop() -> None:
    """`_draw_rectangle` against the row loop written plainly (a guard for rewrites of its loop; band9 replaced
    its per-row min/max and tests by one loop): the same spans, for rectangles at every angle (on and near the
    axes too), of zero length too, inside, across and outside the image, over spans partly drawn."""
    from ropecam.device.pipeline._kernels.spans import _draw_rectangle

    rng = np.random.default_rng(5)
    height, width = 60, 80
    angles = np.concatenate(
        [rng.uniform(-math.pi, math.pi, 150), np.arange(-4, 5) * (math.pi / 4), [1e-7, -1e-7, math.pi / 2 + 1e-7]]
    )
    for angle in angles:
        u_r, u_c = math.cos(angle), math.sin(angle)
        p_r, p_c = rng.uniform(-20, height + 20), rng.uniform(-20, width + 20)
        length, radius = rng.choice([0.0, rng.uniform(0.0, 40.0)], p=[0.1, 0.9]), rng.uniform(0.5, 9.0)
        lo = np.full(height, width, np.int32)
        hi = np.full(height, -1, np.int32)
        drawn = rng.random(height) < 0.5
        lo[drawn] = rng.integers(0, width, drawn.sum())
        hi[drawn] = lo[drawn] + rng.integers(0, 10, drawn.sum())
        want_lo, want_hi = lo.copy(), hi.copy()
        args = (p_r, p_c, u_r, u_c, length, radius, radius * abs(u_c), height, width)
        _rectangle_spans(*args, want_lo, want_hi)
        _draw_rectangle(*args, lo, hi)
        assert np.array_equal(lo, want_lo) and np.array_equal(hi, want_hi), angle
