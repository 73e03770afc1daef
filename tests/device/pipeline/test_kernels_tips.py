"""Tips, local sweeps and modelled offsets of the blur split against slow obvious references and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.edge_model import BandEdgeModel
from ropecam.device.pipeline.edges import gaussian_weights
from ropecam.device.pipeline.width_tables import sweep_index

pytestmark = pytest.mark.kernel

NO_GAINS = np.zeros(0, np.float64)
"""`side_sweeps`' per-point contrast gains: none (the frame's contrast everywhere)."""


def _side_slope_samples(chain, n, i_fix, i_seg, direction, mag, lo_frac, hi_frac) -> np.ndarray:
    """(gradient magnitude, arc fraction) at the chain pixels of one side (from `i_fix` stepping `direction` to
    `i_seg`) whose arc fraction (by index: the chain is 8-connected) lies in [lo_frac, hi_frac), as float32."""
    count = ((i_seg - i_fix) * direction % n + n) % n + 1
    pairs = []
    for k in range(count if count >= 2 else 0):
        frac = k / (count - 1)
        if np.float32(lo_frac) <= frac < np.float32(hi_frac):
            i = (i_fix + k * direction + 4 * n) % n
            pairs.append((mag[chain[i, 0], chain[i, 1]], frac))
    return np.array(pairs, np.float32).reshape(-1, 2)


@pytest.mark.parametrize(("start", "stop", "direction"), [(2, 17, 1), (5, 28, -1), (25, 3, 1)])
def test_side_sweeps_matches_reference(start, stop, direction) -> None:
    rng = np.random.default_rng(2)
    n = 30
    chain = np.stack([np.arange(n) % 6, np.arange(n) // 6], axis=1).astype(np.int32)
    mag = rng.uniform(10, 200, (6, 5)).astype(np.float32)
    ratios = np.linspace(0.1, 2.0, 40)
    sweeps = np.linspace(8.0, 0.0, 40)
    out = np.zeros(n, np.float32)
    count = K.side_sweeps(chain, n, start, stop, direction, mag, np.float32(1 / 100), NO_GAINS, ratios, sweeps, 2,
                          np.zeros(n, np.float32), out)  # fmt: skip
    idx = [(start + k * direction) % n for k in range((stop - start) * direction % n + 1)]
    assert count == len(idx)
    raw = np.interp(mag[chain[idx, 0], chain[idx, 1]] / 100, ratios, sweeps)
    padded = np.concatenate([[raw[0]] * 2, raw, [raw[-1]] * 2])
    np.testing.assert_allclose(out[:count], np.convolve(padded, np.ones(5) / 5, mode="valid"), atol=1e-4)
    assert K.side_sweeps(chain, n, 0, n - 1, 1, mag, np.float32(0.01), NO_GAINS, ratios, sweeps, 2,
                         np.zeros(n, np.float32), np.zeros(5, np.float32)) == K.FULL  # fmt: skip


def _walked_sweep(ratios, sweeps, x) -> np.float32:
    """`side_sweeps`' raw sweep at ratio `x`, the slow obvious way: the last interval whose start is <= x."""
    m = len(ratios)
    if x <= ratios[0]:
        return np.float32(sweeps[0])
    if x >= ratios[m - 1]:
        return np.float32(sweeps[m - 1])
    lo = max(j for j in range(m - 1) if ratios[j] <= x)
    span = ratios[lo + 1] - ratios[lo]
    return np.float32(sweeps[lo] + (x - ratios[lo]) / span * (sweeps[lo + 1] - sweeps[lo]))


@pytest.mark.parametrize("kind", ["model", "repeats", "close"])
def test_side_sweeps_indexed_equals_the_walk_bit_for_bit(kind) -> None:
    rng = np.random.default_rng(4)
    if kind == "model":  # the pipeline's table (ratios repeated near its top end)
        tables = BandEdgeModel(gaussian_weights(1.0), 0.6).tables(6.0)
        ratios, sweeps = tables.peak_ratio.copy(), tables.sweeps_px.copy()
    else:  # float32 values (hit exactly below), repeated ratios, some ratios closer than the others
        ratios = np.sort(rng.uniform(0.2, 2.0, 60).astype(np.float32)).astype(np.float64)
        ratios[10:13] = ratios[10]
        ratios[-3:] = ratios[-3]
        if kind == "close":
            ratios[30:33] = ratios[30] + np.array([0.0, 3e-4, 7e-4])
        sweeps = rng.uniform(0.0, 16.0, 60)
    index = sweep_index(ratios)
    assert index.shape[0] >= 128
    values = [
        *ratios.astype(np.float32), *np.nextafter(ratios.astype(np.float32), np.float32(0)),
        *np.nextafter(ratios.astype(np.float32), np.float32(9)), *rng.uniform(-0.5, 2.5, 400).astype(np.float32),
        0.0, ratios[0] - 1, ratios[-1] + 1,
    ]  # fmt: skip
    n = len(values)
    mag = np.array(values, np.float32).reshape(1, n)
    chain = np.stack([np.zeros(n), np.arange(n)], axis=1).astype(np.int32)
    expected = np.array([_walked_sweep(ratios, sweeps, np.float32(x)) for x in values], np.float32)
    for start, stop, direction in ((0, n - 1, 1), (n - 1, 0, -1), (7, 3, 1)):
        args = (chain, n, start, stop, direction, mag, np.float32(1.0), NO_GAINS, ratios, sweeps)
        for half in (0, 3):
            raw_walk, out_walk = np.zeros(n, np.float32), np.zeros(n, np.float32)
            raw_index, out_index = np.zeros(n, np.float32), np.zeros(n, np.float32)
            count = K.side_sweeps(*args, half, raw_walk, out_walk)
            assert K.side_sweeps_indexed(*args, index, half, raw_index, out_index) == count
            assert out_index.tobytes() == out_walk.tobytes()
            # `work` keeps the raw sweeps (before the running average, whose sums round)
            order = [(start + k * direction) % n for k in range(count)]
            assert raw_index[:count].tobytes() == expected[order].tobytes()
    assert K.side_sweeps_indexed(chain, n, 0, n - 1, 1, mag, np.float32(1.0), NO_GAINS, ratios, sweeps, index, 2,
                                 np.zeros(n, np.float32), np.zeros(5, np.float32)) == K.FULL  # fmt: skip


def test_sweep_index_refuses_tables_it_cannot_index() -> None:
    assert sweep_index(np.array([1.0])).shape == (0,)
    assert sweep_index(np.array([1.0, 1.0, 1.0])).shape == (0,)
    assert sweep_index(np.array([1.0, 0.5, 2.0])).shape == (0,)
    assert sweep_index(np.array([0.0, 1e-9, 1.0])).shape == (0,)  # would need 2**30 buckets
    assert sweep_index(np.array([0.0, np.nan, 1.0])).shape == (0,)


@pytest.mark.parametrize("local", [0, 1])
def test_offset_by_table_matches_reference(local) -> None:
    rng = np.random.default_rng(3)
    n = 24
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    points = np.stack([20 + 8 * np.sin(angle), 20 + 8 * np.cos(angle)], axis=1).astype(np.float32)
    chain = np.rint(points).astype(np.int32)
    gx = rng.normal(size=(40, 40)).astype(np.float32)
    gy = rng.normal(size=(40, 40)).astype(np.float32)
    table = np.array([1.5, 1.2, 0.8, 0.3, 0.0], np.float32)
    sweeps = rng.uniform(0, 3, n).astype(np.float32)
    out = np.zeros((n, 2), np.float32)
    count = K.offset_by_table(points, chain, n, 3, 15, 1, gx, gy, np.float32(-1.0), sweeps, local, np.float32(2.5),
                              np.float32(0.5), table, out)  # fmt: skip
    assert count == 13
    idx = np.arange(3, 16)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points[idx].astype(float), axis=0).T))])
    d = sweeps[:count] if local else 2.5 * arc / arc[-1]
    shift = np.interp(d / 0.5, np.arange(5), table)
    g = -np.stack([gy[chain[idx, 0], chain[idx, 1]], gx[chain[idx, 0], chain[idx, 1]]], axis=1)
    expected = points[idx] + shift[:, None] * g / np.hypot(*g.T)[:, None]
    np.testing.assert_allclose(out[:count], expected, atol=1e-4)


@pytest.mark.parametrize(("start", "stop", "direction", "head", "tail"),
                         [(3, 22, 1, 4, 3), (20, 2, -1, 1, 1), (18, 6, 1, 2, 5), (3, 8, 1, 9, 9)])  # fmt: skip
def test_offset_by_table_thinned_keeps_the_dense_points(start, stop, direction, head, tail) -> None:
    rng = np.random.default_rng(4)
    n = 24
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    points = np.stack([20 + 8 * np.sin(angle), 20 + 8 * np.cos(angle)], axis=1).astype(np.float32)
    chain = np.rint(points).astype(np.int32)
    gx = rng.normal(size=(40, 40)).astype(np.float32)
    gy = rng.normal(size=(40, 40)).astype(np.float32)
    table = np.array([1.5, 1.2, 0.8, 0.3, 0.0], np.float32)
    sweeps = rng.uniform(0, 3, n).astype(np.float32)
    dense = np.zeros((n, 2), np.float32)
    count = K.offset_by_table(points, chain, n, start, stop, direction, gx, gy, np.float32(1.0), sweeps, 1,
                              np.float32(0.0), np.float32(0.5), table, dense)  # fmt: skip
    thin = np.zeros((n, 2), np.float32)
    got = K.offset_by_table_thinned(points, chain, n, start, stop, direction, gx, gy, np.float32(1.0), sweeps,
                                    np.float32(0.5), table, head, tail, thin)  # fmt: skip
    keep = [k for k in range(count) if k < head or k >= count - tail or (k - head) % 2 == 0]
    assert keep[0] == 0 and keep[-1] == count - 1
    assert got == len(keep)
    np.testing.assert_array_equal(thin[:got], dense[keep])
    assert (
        K.offset_by_table_thinned(
            points,
            chain,
            n,
            start,
            stop,
            direction,
            gx,
            gy,
            np.float32(1.0),
            sweeps,
            np.float32(0.5),
            table,
            head,
            tail,
            np.zeros((3, 2), np.float32),
        )
        == K.FULL
    )


def _band_image(tip_col: float, row: float = 20.0, width_px: float = 3.0, blur: float = 1.1) -> np.ndarray:
    """A horizontal rope from column 5 to `tip_col` (flat end), Gaussian-blurred (closed form), as float32."""
    rows, cols = np.mgrid[0:40, 0:70].astype(float)
    s = blur * math.sqrt(2)
    across = 0.5 * (erf((rows - row + width_px / 2) / s) - erf((rows - row - width_px / 2) / s))
    along = 0.5 * (erf((cols - 5.0) / s) - erf((cols - tip_col) / s))
    return (30 + 150 * across * along).astype(np.float32)


@pytest.mark.parametrize("tip", [50.0, 50.3, 50.75])
def test_half_level_crossing_finds_a_blurred_flat_end(tip) -> None:
    image = _band_image(tip)
    found = K.half_level_crossing(image, np.float32(20.0), np.float32(10.0), np.float32(0.0), np.float32(1.0),
                                  np.float32(tip - 10.0 + 0.6), np.float32(4.0), np.float32(2.0))  # fmt: skip
    assert 10.0 + found == pytest.approx(tip, abs=0.05)
    flat = np.full((40, 70), 50.0, np.float32)
    f = np.float32
    assert math.isnan(K.half_level_crossing(flat, f(20.0), f(10.0), f(0.0), f(1.0), f(40.0), f(4.0), f(2.0)))


def test_extend_to_band_end_carries_the_straight_axis_to_the_end() -> None:
    tip = 50.3
    image = _band_image(tip)
    # The side polyline: on the axis, but its last 3 px bend inward as a rounded corner does.
    cols = np.arange(8.0, 49.0, 1.0)
    rows = 20.0 + np.where(cols > 45.0, 0.4 * (cols - 45.0), 0.0)
    poly = np.zeros((100, 2), np.float32)
    poly[: cols.size] = np.stack([rows, cols], axis=1)
    # The contour of the band: its outline, 1.5 px either side of the axis and across the end.
    top = np.stack([np.full(45, 18.5), np.arange(5.0, 50.0)], axis=1)
    end = np.stack([np.arange(18.5, 21.6, 0.5), np.full(7, 49.8)], axis=1)
    bottom = np.stack([np.full(45, 21.5), np.arange(49.0, 4.0, -1.0)], axis=1)
    contour = np.concatenate([top, end, bottom]).astype(np.float32)
    count = K.extend_to_band_end(poly, cols.size, contour, len(contour), image, 3.0, 0.0, 5.0, 9.0, 1.0, 0.0, 0.0)
    assert count < cols.size + 1
    np.testing.assert_allclose(poly[count - 1], [20.0, tip], atol=0.05)
    assert np.all(np.abs(poly[: count - 1, 0] - 20.0) < 1e-4)  # the bent corner was cut away
    # A round end: the tip stays `cap_px` short of the band's end (the contour's farthest point along the axis).
    poly[: cols.size] = np.stack([rows, cols], axis=1)
    count = K.extend_to_band_end(poly, cols.size, contour, len(contour), image, 3.0, 1.5, 5.0, 9.0, 1.0, 0.0, 0.0)
    np.testing.assert_allclose(poly[count - 1], [20.0, 49.8 - 1.5], atol=0.05)


def test_extend_to_band_end_bounds_the_crossing_of_a_wide_sweep_only() -> None:
    # The band's outline ends at column 49.8 (its corner rounded by the smoothing), but along the axis the level
    # falls slowly from column 42 to 50 (near the corner of a wide sweep the rope covers the axis for a small part
    # of the exposure and a textured plate sets the level): the half-level crossing lies near column 47.4, 2.4 px
    # short of the outline.
    rows, cols = np.mgrid[0:40, 0:70].astype(np.float64)
    along = np.clip((50.0 - cols) / 8.0, 0.0, 1.0)
    across = np.exp(-0.5 * ((rows - 20.0) / 1.5) ** 2)
    image = (30.0 + 30.0 * across * along).astype(np.float32)
    f = np.float32
    crossing = 10.0 + K.half_level_crossing(image, f(20.0), f(10.0), f(0.0), f(1.0), f(39.8), f(4.0), f(2.0))
    assert crossing < 49.8 - 2.0
    cols_axis = np.arange(8.0, 49.0, 1.0)
    top = np.stack([np.full(45, 18.5), np.arange(5.0, 50.0)], axis=1)
    end = np.stack([np.arange(18.5, 21.6, 0.5), np.full(7, 49.8)], axis=1)
    bottom = np.stack([np.full(45, 21.5), np.arange(49.0, 4.0, -1.0)], axis=1)
    contour = np.concatenate([top, end, bottom]).astype(np.float32)
    width = 3.0
    # The band's far corners (the segmentation points) 3.5 widths apart across the axis: the tip goes no nearer
    # the fixed end than the outline's end less `blur_px` (1 px), whichever way the gap points.
    for gap_r, gap_c in ((3.5 * width, 0.0), (-3.5 * width, 2.0)):
        poly = np.zeros((100, 2), np.float32)
        poly[: cols_axis.size] = np.stack([np.full(cols_axis.size, 20.0), cols_axis], axis=1)
        count = K.extend_to_band_end(poly, cols_axis.size, contour, len(contour), image, width, 0.0, 5.0, 9.0, 1.0,
                                     gap_r, gap_c)  # fmt: skip
        np.testing.assert_allclose(poly[count - 1], [20.0, 49.8 - 1.0], atol=0.01)
    # Corners 2.5 widths apart, or a gap along the axis (a whipping tip: its band ends in a ramp its outline runs
    # beyond): the crossing stands.
    for gap_r, gap_c in ((2.5 * width, 0.0), (0.0, 8.0 * width)):
        poly = np.zeros((100, 2), np.float32)
        poly[: cols_axis.size] = np.stack([np.full(cols_axis.size, 20.0), cols_axis], axis=1)
        count = K.extend_to_band_end(poly, cols_axis.size, contour, len(contour), image, width, 0.0, 5.0, 9.0, 1.0,
                                     gap_r, gap_c)  # fmt: skip
        np.testing.assert_allclose(poly[count - 1], [20.0, crossing], atol=0.01)


def _ramp_image(inner: float, outer: float, blur: float = 0.7) -> np.ndarray:
    """A horizontal band (row 20, 3 px wide) from column 5 whose end is a ramp: covered for the whole exposure up to
    column `inner`, for none of it beyond `outer`, linearly between (a tip sliding along the rope from `outer` to
    `inner`), blurred across (closed form) and along (numerically), as float32."""
    rows, cols = np.mgrid[0:40, 0:70].astype(float)
    s = blur * math.sqrt(2)
    across = 0.5 * (erf((rows - 20.0 + 1.5) / s) - erf((rows - 20.0 - 1.5) / s))
    fine = np.arange(0.0, 70.0, 0.05)
    coverage = np.clip((outer - fine) / (outer - inner), 0.0, 1.0) * (fine >= 5.0)
    kernel = np.exp(-0.5 * (np.arange(-100, 101) * 0.05 / blur) ** 2)
    blurred = np.convolve(coverage, kernel / kernel.sum(), mode="same")
    along = np.interp(cols, fine, blurred)
    return (30 + 150 * across * along).astype(np.float32)


def test_ramp_end_crossing_reads_the_middle_of_a_sliding_tips_ramp() -> None:
    f = np.float32
    reach = f(3 * 0.5 + 1)
    # A tip that slid 10 px along the rope (columns 50 -> 40): the crossing within the usual reach of the outline's
    # end (column 49) is still on the ramp, past its middle (column 45, the tip at mid-exposure).
    image = _ramp_image(40.0, 50.0)
    end = K.half_level_crossing(image, f(20.0), f(10.0), f(0.0), f(1.0), f(39.0), reach, f(2.0))
    assert 10.0 + end > 47.0
    ramp = K.ramp_end_crossing(image, f(20.0), f(10.0), f(0.0), f(1.0), end, reach, f(2.0))
    assert 45.0 <= 10.0 + ramp < 45.5  # its deep level 6-8 px behind is at the ramp's inner end
    # A ramp of 8 px (columns 51 -> 43): the deep level is the band's, the crossing the ramp's middle.
    image = _ramp_image(43.0, 51.0)
    end = K.half_level_crossing(image, f(20.0), f(10.0), f(0.0), f(1.0), f(40.0), reach, f(2.0))
    ramp = K.ramp_end_crossing(image, f(20.0), f(10.0), f(0.0), f(1.0), end, reach, f(2.0))
    assert 10.0 + ramp == pytest.approx(47.0, abs=0.1)
    # A flat end that did not slide (or slid less than the reach): no ramp, the crossing stands.
    for image in (_band_image(50.3, blur=0.7), _ramp_image(48.5, 50.5)):
        end = K.half_level_crossing(image, f(20.0), f(10.0), f(0.0), f(1.0), f(39.5), reach, f(2.0))
        assert math.isnan(K.ramp_end_crossing(image, f(20.0), f(10.0), f(0.0), f(1.0), end, reach, f(2.0)))
    # Through the tip fit: the outline ends at column 49.5, the tip goes to the ramp's middle.
    image = _ramp_image(40.0, 50.0)
    cols = np.arange(8.0, 46.0, 1.0)
    poly = np.zeros((100, 2), np.float32)
    poly[: cols.size] = np.stack([np.full(cols.size, 20.0), cols], axis=1)
    top = np.stack([np.full(45, 18.5), np.arange(5.0, 50.0)], axis=1)
    tip = np.stack([np.arange(18.5, 21.6, 0.5), np.full(7, 49.5)], axis=1)
    bottom = np.stack([np.full(45, 21.5), np.arange(49.0, 4.0, -1.0)], axis=1)
    contour = np.concatenate([top, tip, bottom]).astype(np.float32)
    count = K.extend_to_band_end(poly, cols.size, contour, len(contour), image, 3.0, 0.0, 5.0, 9.0, 0.5, 0.0, 0.0)
    assert poly[count - 1, 0] == pytest.approx(20.0, abs=1e-4) and 45.0 <= poly[count - 1, 1] < 45.6  # not 47-48


def test_band_edge_model_limits() -> None:
    model = BandEdgeModel(gaussian_weights(1.0), 0.5)
    # A wide rope's edges sit on its outline; blur pushes the edges of a thin one apart.
    assert model.edge_spacing(12.0) == pytest.approx(12.0, abs=0.05)
    assert model.edge_spacing(2.5) > 2.9
    tables = model.tables(3.2)
    assert model.edge_spacing(tables.width_px) == pytest.approx(3.2, abs=0.03)
    offsets = tables.offset_px
    assert offsets[0] == pytest.approx(1.6, abs=0.03)  # still rope: half the edge spacing
    assert np.all(np.diff(offsets) <= 1e-4)
    beyond = round((tables.width_px + 4.0) / tables.sweep_step_px)
    assert offsets[beyond] < 0.02  # swept well beyond its width: the edge is on the axis
    assert np.all(np.diff(tables.peak_ratio) >= 0)
    # The gradient's height falls as contrast / d once the ramp is wider than the blur.
    big = np.interp([8.0, 16.0], tables.sweeps_px[::-1], tables.peak_ratio[::-1])
    assert big[0] / big[1] == pytest.approx(2.0, rel=0.05)


def test_slant_gain_closed_form_without_blur() -> None:
    # No smoothing and no lens: only the pixel's area (variance v = 1/12). On the ramp m(x) = (x + w/2) / 2, and
    # the coverage-weighted mean of x under a narrow blur is v c'(0) / c(0) = 2 v / w: m averages w / 4 + v / w.
    model = BandEdgeModel(np.ones(1), 0.0)
    for width in (4.0, 8.0):
        assert model.slant_gain(width) == pytest.approx(width / 4 + 1 / 12 / width, abs=0.005)


@pytest.mark.parametrize(("start", "stop", "direction"), [(2, 57, 1), (50, 1, -1)])
def test_slope_sweep_median_matches_numpy(start, stop, direction) -> None:
    rng = np.random.default_rng(5)
    n = 60
    chain = np.stack([np.arange(n) % 6, np.arange(n) // 6], axis=1).astype(np.int32)
    mag = rng.uniform(10, 200, (6, 10)).astype(np.float32)
    ratios = np.concatenate([np.linspace(0.1, 1.0, 20), [1.0], np.linspace(1.1, 2.0, 19)])  # a tie, as tables have
    sweeps = np.linspace(8.0, 0.0, 40)
    pairs = _side_slope_samples(chain, n, start, stop, direction, mag, 0.5, 0.85)
    m = len(pairs)
    contrast = 97.3
    local = np.interp(pairs[:, 0] / contrast, ratios, sweeps)
    expected = float(np.median(local / pairs[:, 1]))
    got = K.slope_sweep_median(chain, n, start, stop, direction, mag, np.float32(0.5), np.float32(0.85),
                               np.float32(contrast), ratios, sweeps, np.int32(1), np.zeros(n))  # fmt: skip
    assert m >= 6
    assert got == pytest.approx(expected, rel=1e-12)
    # to_tip 0: the local sweeps' median, not extrapolated to the tip
    got_local = K.slope_sweep_median(chain, n, start, stop, direction, mag, np.float32(0.5), np.float32(0.85),
                                     np.float32(contrast), ratios, sweeps, np.int32(0), np.zeros(n))  # fmt: skip
    assert got_local == pytest.approx(float(np.median(local)), rel=1e-12)
    few = K.slope_sweep_median(chain, n, 0, 8, 1, mag, np.float32(0.5), np.float32(0.85), np.float32(contrast),
                               ratios, sweeps, np.int32(1), np.zeros(n))  # fmt: skip
    assert math.isnan(few)  # fewer than 6 samples


def test_body_sweep_is_the_largest_stretch_median_of_either_side() -> None:
    rng = np.random.default_rng(11)
    n = 120
    chain = np.stack([np.arange(n) % 12, np.arange(n) // 12], axis=1).astype(np.int32)
    mag = rng.uniform(10, 200, (12, 10)).astype(np.float32)
    mag[:, 3] = 15.0  # a stretch of side a with a shallow edge: a wide local sweep there
    ratios = np.linspace(0.1, 2.0, 40)
    sweeps = np.linspace(8.0, 0.0, 40)
    contrast = 97.3
    i_fix, seg_a, seg_b = 0, 55, 65
    expected = -np.inf
    for i_seg, direction in ((seg_a, 1), (seg_b, -1)):
        for lo, hi in zip(K.BODY_WINDOWS[:-1], K.BODY_WINDOWS[1:], strict=True):
            pairs = _side_slope_samples(chain, n, i_fix, i_seg, direction, mag, lo, hi)
            if len(pairs) >= 6:
                expected = max(expected, float(np.median(np.interp(pairs[:, 0] / contrast, ratios, sweeps))))
    got = K.body_sweep(chain, n, i_fix, seg_a, seg_b, mag, np.float32(contrast), K.BODY_WINDOWS, ratios, sweeps,
                       np.zeros(n))  # fmt: skip
    assert got == pytest.approx(expected, rel=1e-12)
    assert got > 6.0  # the shallow stretch's, not the median of the whole side
    assert math.isnan(K.body_sweep(chain, n, 0, 8, 112, mag, np.float32(contrast), K.BODY_WINDOWS, ratios, sweeps,
                                   np.zeros(n)))  # fmt: skip  # sides too short for 6 samples in a stretch


def test_select_finds_the_rank_as_sorting_does() -> None:
    from ropecam.device.pipeline._kernels.offsets import _select

    rng = np.random.default_rng(9)
    for trial in range(300):
        m = int(rng.integers(1, 40))
        values = rng.integers(0, 5, m).astype(np.float64) if trial % 2 else rng.normal(size=m)  # ties, or none
        rank = int(rng.integers(0, m))
        work = np.concatenate([values, [np.inf]])  # beyond m: never read or moved
        got = _select(work, m, rank)
        assert got == np.sort(values)[rank]
        assert np.all(work[:rank] <= got) and np.all(work[rank + 1 : m] >= got)
        np.testing.assert_array_equal(np.sort(work[:m]), np.sort(values))
        assert work[m] == np.inf


def test_extend_to_band_end_near_equals_the_full_search() -> None:
    # The band of the test above, rotated and moved about a fixed end, the contour in random order (the search
    # must not depend on where the near points sit in the list), plus far points: the same polyline as the
    # full search, whatever the fixed end; a `fixed_dist` shorter than the contour checks every point.
    rng = np.random.default_rng(7)
    image = _band_image(50.3)
    cols = np.arange(8.0, 49.0, 1.0)
    rows = 20.0 + np.where(cols > 45.0, 0.4 * (cols - 45.0), 0.0)
    top = np.stack([np.full(45, 18.5), np.arange(5.0, 50.0)], axis=1)
    end = np.stack([np.arange(18.5, 21.6, 0.5), np.full(7, 49.8)], axis=1)
    bottom = np.stack([np.full(45, 21.5), np.arange(49.0, 4.0, -1.0)], axis=1)
    contour = np.concatenate([top, end, bottom, rng.uniform(0.0, 40.0, (30, 2))])
    contour = contour[rng.permutation(len(contour))].astype(np.float32)
    f = np.float32
    for fixed in ((20.0, 5.0), (20.0, 80.0), (0.0, 0.0), (39.0, 50.0)):
        fixed_r, fixed_c = f(fixed[0]), f(fixed[1])
        dist = np.hypot(contour[:, 0] - fixed_r, contour[:, 1] - fixed_c).astype(np.float64)
        for cap in (0.0, 1.5):
            expected = np.zeros((100, 2), np.float32)
            expected[: cols.size] = np.stack([rows, cols], axis=1)
            got = expected.copy()
            n_expected = K.extend_to_band_end(
                expected, cols.size, contour, len(contour), image, 3.0, cap, 5.0, 9.0, 1.0, 14.0, 0.0
            )
            for fixed_dist in (dist, dist[:0]):
                got[: cols.size] = np.stack([rows, cols], axis=1)
                n_got = K.extend_to_band_end_near(
                    got, cols.size, contour, len(contour), image, f(3.0), f(cap), f(5.0), f(9.0), f(1.0), f(14.0),
                    f(0.0), fixed_dist, fixed_r, fixed_c,
                )  # fmt: skip
                assert n_got == n_expected
                np.testing.assert_array_equal(got, expected)
    # Nothing near the axis: unchanged, as the full search.
    poly = np.zeros((100, 2), np.float32)
    poly[: cols.size] = np.stack([rows, cols], axis=1)
    far = contour[:1] + f(300.0)
    dist = np.hypot(far[:, 0], far[:, 1]).astype(np.float64)
    assert (
        K.extend_to_band_end_near(poly, cols.size, far, 1, image, 3.0, 0.0, 5.0, 9.0, 1.0, 0.0, 0.0, dist, 0.0, 0.0)
        == cols.size
    )
