"""`evaluate.py band-track`: the edge-free band tracker follows a rope drawn swinging about its fixed end with a known
width, contrast and noise, from frame 0's truth."""

from __future__ import annotations

import math
import subprocess
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSetWriter

RunTool = Callable[..., subprocess.CompletedProcess[str]]

CONTRAST_DN, WIDTH_PX, NOISE_DN, BLUR_PX = 60.0, 2.0, 4.0, 0.6
FIXED_UV, LENGTH_PX = (20.0, 40.0), 200.0
PERIOD_MS, EXPOSURE_MS = 10.0, 4.0
ALPHA_RAD_MS2 = 7.2e-5
"""The rope's angular acceleration from rest: the tip sweeps about 3 px during frame 5's exposure."""


def _rope(t_ms: float, points: int = 201) -> np.ndarray:
    """The rope at time `t_ms` after its release: a straight line of LENGTH_PX from the fixed end, turned by
    0.5 alpha t^2 from the +u axis towards +v; (points, 2) u, v."""
    angle = 0.5 * ALPHA_RAD_MS2 * t_ms**2
    s = np.linspace(0.0, LENGTH_PX, points)
    return np.stack([FIXED_UV[0] + s * math.cos(angle), FIXED_UV[1] + s * math.sin(angle)], axis=1)


def _coverage(line: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The share of each pixel a rope of WIDTH_PX along the segment `line[0]`..`line[-1]` covers (a ramp of 1 px
    across its side, cut square at both ends)."""
    start, tip = line[0], line[-1]
    axis = (tip - start) / LENGTH_PX
    du, dv = cols - start[0], rows - start[1]
    along = du * axis[0] + dv * axis[1]
    across = np.abs(-du * axis[1] + dv * axis[0])
    side = np.clip(WIDTH_PX / 2 + 0.5 - across, 0.0, 1.0)
    return side * np.clip(along + 0.5, 0.0, 1.0) * np.clip(LENGTH_PX + 0.5 - along, 0.0, 1.0)


def _write_swing_set(root: Path, frames: int = 6) -> None:
    height, width = 120, 250
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)
    rng = np.random.default_rng(5)
    begins, ends = [], []
    with FrameSetWriter(root, (width, height), 1000.0 / PERIOD_MS) as writer:
        for i in range(frames):
            t0 = i * PERIOD_MS
            instants = np.linspace(t0, t0 + EXPOSURE_MS, 24)
            band = np.mean([_coverage(_rope(t), rows, cols) for t in instants], axis=0)
            clean = cv2.GaussianBlur(40.0 + CONTRAST_DN * band, (0, 0), BLUR_PX)
            noisy = clean + rng.normal(0.0, NOISE_DN, clean.shape)
            writer.add(np.clip(np.round(noisy), 0, 255).astype(np.uint8), int(t0 * 1e6), int(EXPOSURE_MS * 1000))
            begins.append(_rope(t0))
            ends.append(_rope(t0 + EXPOSURE_MS))
        begin, end = np.array(begins), np.array(ends)
        writer.write_truth({
            "begin_px": begin, "end_px": end, "tip_begin_px": begin[:, -1], "tip_end_px": end[:, -1],
            "width_px": np.full(frames, WIDTH_PX),
        })  # fmt: skip


def _still_frame() -> tuple[np.ndarray, np.ndarray]:
    """The rope at rest drawn with noise, and the search's evidence of it (minus the plate, smoothed)."""
    from ropecam_tools.eval_band_track import SEARCH_SMOOTH_PX
    from scipy.ndimage import gaussian_filter

    rows, cols = np.mgrid[0:120, 0:250].astype(np.float64)
    clean = cv2.GaussianBlur(40.0 + CONTRAST_DN * _coverage(_rope(0.0), rows, cols), (0, 0), BLUR_PX)
    image = clean + np.random.default_rng(3).normal(0.0, NOISE_DN, clean.shape)
    return image, gaussian_filter(image - 40.0, SEARCH_SMOOTH_PX)


@pytest.mark.parametrize("tip_fit", [True, False], ids=["tip-fit", "straight-tip"])
def test_band_track_follows_the_drawn_swing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, tip_fit: bool) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_track import summarise, track_set

    _write_swing_set(tmp_path / "swing")
    rows = track_set(tmp_path / "swing", frames=6, blur_px=BLUR_PX, tip_fit=tip_fit)
    assert [r["frame"] for r in rows] == [1, 2, 3, 4, 5]
    assert rows[-1]["sweep_px"] == pytest.approx(3.1, abs=0.2)
    # frame 1 is predicted still (one frame known), from frame 2 on the velocity is measured
    assert rows[0]["tip_px"] < 1.5 and rows[0]["curve_px"] < 0.7, rows[0]
    if tip_fit:
        # from the still prediction the sweep's correction starts off 0, where the band (even in it) has no gradient:
        # measured, not left at its prior (0.06 px across the rope; 0.34 px started at 0)
        assert rows[0]["across_sigma_px"] < 0.2, rows[0]
    # the drawn rope's sides are a 1 px ramp blurred, not the model's blurred box: with the exposure integrated
    # exactly, tips 0.24-0.43 px and centrelines 0.32-0.44 px with the tip fit (frame 2 of the straight tip: 0.55 and
    # 0.45 px); with nine instants 0.07-0.32 and 0.21-0.37 px, but frame 1 1.16 px off at the tip
    for row in rows[1:]:
        assert row["tip_px"] < 0.6, row
        assert row["curve_px"] < 0.5, row
    summary = summarise(rows)
    assert summary["lost_from"] is None and summary["silent"] == 0 and summary["frames"] == 5


def test_band_track_without_a_second_frame_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_track import track_set

    _write_swing_set(tmp_path / "swing", frames=1)
    with pytest.raises(ValueError, match="at least 2 frames"):
        track_set(tmp_path / "swing", frames=5)


def test_band_track_command_prints_its_table(tmp_path: Path, run_tool_here: RunTool) -> None:
    _write_swing_set(tmp_path / "swing", frames=3)
    done = run_tool_here("evaluate.py", "band-track", str(tmp_path / "swing"), "--frames", "3")
    assert done.returncode == 0, done.stderr
    assert "| 2 |" in done.stdout and "simulated" in done.stdout and "silent" in done.stdout


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (["--blur-px", "-1"], "--blur-px"),
        (["--blur-px", "0"], "--blur-px"),
        (["--windows", "500"], "--windows 500"),
        (["--windows", "0"], "--windows"),
        (["--frames", "1"], "at least 2 frames"),
    ],
)
def test_band_track_refuses_bad_options_naming_them(
    tmp_path: Path, run_tool_here: RunTool, options: list[str], named: str
) -> None:
    _write_swing_set(tmp_path / "swing", frames=3)
    done = run_tool_here("evaluate.py", "band-track", str(tmp_path / "swing"), *options)
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert named in done.stderr and "Traceback" not in done.stderr, done.stderr


def test_band_track_refuses_a_folder_that_is_not_a_frame_set(tmp_path: Path, run_tool_here: RunTool) -> None:
    done = run_tool_here("evaluate.py", "band-track", str(tmp_path / "nowhere"))
    assert done.returncode == 2 and "nowhere" in done.stderr and "truth.npz" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr


def test_band_track_reports_an_unreadable_frame_set_as_a_runtime_error(tmp_path: Path, run_tool_here: RunTool) -> None:
    broken = tmp_path / "broken"
    broken.mkdir()
    np.savez(broken / "truth.npz", begin_px=np.zeros((1, 2, 2)))  # truth, but no frame-set metadata
    done = run_tool_here("evaluate.py", "band-track", str(broken))
    assert done.returncode == 1, (done.stdout, done.stderr)
    assert "band-track: error:" in done.stderr and "broken" in done.stderr and "Traceback" not in done.stderr


def test_search_finds_a_turned_rope_without_the_track(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_track import bent, search_rope

    shape = _rope(0.0)
    truth = bent(shape, math.radians(6.0), math.radians(-4.0))
    rows, cols = np.mgrid[0:160, 0:250].astype(np.float64)
    # evidence: a band 8 px wide round the turned and bent line (its distance to the line's points)
    distance = np.min(np.hypot(cols[..., None] - truth[:, 0], rows[..., None] - truth[:, 1]), axis=-1)
    evidence = cv2.GaussianBlur(np.where(distance < 4.0, 1.0, 0.0), (0, 0), 2.0)
    found, score = search_rope(evidence, shape)
    assert score > 0.8
    assert np.hypot(*(found - truth).T).max() < 1.0


def test_band_track_reseeds_a_lost_track_and_does_not_trust_it_meanwhile(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools import eval_band_track
    from ropecam_tools.eval_band_track import bent, summarise, track_set

    _write_swing_set(tmp_path / "swing", frames=8)
    real = eval_band_track.BandTracker

    def lost_from_the_start(seed: np.ndarray, *args: object) -> object:
        # seeded 5 degrees off (the tip 17 px away, beyond the fit's reach): the track starts lost
        return real(bent(seed, math.radians(-5.0), 0.0), *args)

    monkeypatch.setattr(eval_band_track, "BandTracker", lost_from_the_start)
    rows = track_set(tmp_path / "swing", frames=8, blur_px=BLUR_PX)
    summary = summarise(rows)
    assert summary["silent"] == 0
    assert not rows[0]["locked"] and not rows[0]["trusted"]
    assert summary["reseeds"] >= 1
    reseeded = next(r["frame"] for r in rows if r["reseeded"])
    after = [r for r in rows if r["frame"] > reseeded]  # the first frame after it is searched before it is fitted
    assert after, rows
    for row in after:
        assert row["locked"] and row["curve_px"] < 0.5 and row["tip_px"] < 1.0, row


def test_tip_fit_measures_a_curled_tip_and_its_far_end(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_track import RESAMPLE_POINTS, _frame_normals, fit_tip, resample_to

    # a still rope whose outer 60 px curl towards +v (a circle of radius 400 px); predicted straight and 3 px short
    s = np.linspace(0.0, LENGTH_PX, 401)
    bend = np.clip(s - (LENGTH_PX - 60.0), 0.0, None)
    angle = bend / 400.0
    du, dv = np.cos(angle), np.sin(angle)
    rope = np.stack([FIXED_UV[0] + np.cumsum(du) * (s[1] - s[0]), FIXED_UV[1] + np.cumsum(dv) * (s[1] - s[0])], axis=1)
    rope -= rope[0] - np.array(FIXED_UV)
    rows, cols = np.mgrid[0:80, 0:250].astype(np.float64)
    inner = rope[:-4]  # the far end cut square: its last 2 px (about the radius) left to the round cap of the distance
    distance = np.min(np.hypot(cols[..., None] - inner[:, 0], rows[..., None] - inner[:, 1]), axis=-1)
    cover = np.clip(WIDTH_PX / 2 + 0.5 - distance, 0.0, 1.0)
    image = cv2.GaussianBlur(40.0 + CONTRAST_DN * cover, (0, 0), BLUR_PX)
    image = image + np.random.default_rng(2).normal(0.0, 1.0, image.shape)
    true_length = LENGTH_PX - 4 * (s[1] - s[0]) + WIDTH_PX / 2
    straight = resample_to(_rope(0.0), LENGTH_PX)
    normal, _ = _frame_normals(straight)
    zero = np.zeros(RESAMPLE_POINTS)
    start = RESAMPLE_POINTS - 40
    q, covariance, shifts = fit_tip(image, straight, normal, zero, zero, start, true_length - 3.0, WIDTH_PX, BLUR_PX)
    # where the rope is at the carried length (3 px short of its end), across the straight prediction
    at = np.interp(true_length - 3.0, s, np.arange(len(s)))
    tip_v = float(np.interp(at, np.arange(len(s)), rope[:, 1])) - FIXED_UV[1]
    assert tip_v > 3.0  # the curl: a straight extrapolation of the part's start is this far off
    assert q[2] == pytest.approx(tip_v * float(normal[-1, 1]), abs=0.5), q
    assert q[6] == pytest.approx(3.0, abs=0.6), q
    assert math.sqrt(covariance[2, 2]) < 0.3 and math.sqrt(covariance[6, 6]) < 0.5, covariance
    assert len(shifts) == RESAMPLE_POINTS - start


def test_a_reseeded_track_measures_the_far_end_afresh(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_track import BandTracker

    image, evidence = _still_frame()
    short = _rope(0.0)[:195]  # the carried length 6 px short of the rope's (a length a lost track left wrong)
    tracker = BandTracker(short, WIDTH_PX, BLUR_PX, PERIOD_MS * 1e6, 10)
    kept = tracker.track(image, EXPOSURE_MS * 1e6, evidence)
    assert kept["cap_px"] == pytest.approx(6.0, abs=1.0) and tracker.length_px < LENGTH_PX - 4.0  # beyond the gate
    assert not kept["trusted"]
    tracker.reseed(short, short)
    after = tracker.track(image, EXPOSURE_MS * 1e6, evidence)
    assert tracker.length_px == pytest.approx(LENGTH_PX, abs=1.0)
    assert math.hypot(*(after["begin"][-1] - _rope(0.0)[-1])) < 1.0, after["begin"][-1]


def test_a_far_end_outside_the_length_gate_is_a_doubt(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_track import BandTracker

    image, evidence = _still_frame()
    short = _rope(0.0)[:195]  # the carried length 6 px short: every far end lies beyond the length's gate
    tracker = BandTracker(short, WIDTH_PX, BLUR_PX, PERIOD_MS * 1e6, 10)
    seeded = tracker.reference.copy()
    first = tracker.track(image, EXPOSURE_MS * 1e6, evidence)
    # the line itself lies on the band (locked), but its far end is refused: not a reference for the search
    assert first["locked"] and not first["in_gate"] and not first["trusted"] and not first["reseeded"]
    np.testing.assert_array_equal(tracker.reference, seeded)
    second = tracker.track(image, EXPOSURE_MS * 1e6, evidence)
    assert not second["in_gate"] and second["reseeded"]  # two doubts in a row: restarted, the length measured afresh
    tracker.track(image, EXPOSURE_MS * 1e6, evidence)
    assert tracker.length_px == pytest.approx(LENGTH_PX, abs=1.0)


@pytest.mark.parametrize("sweep_px", [0.0, 1e-7, 0.4, 3.0, 17.0])
def test_band_profile_integrates_the_exposure(monkeypatch: pytest.MonkeyPatch, sweep_px: float) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_track import band_profile
    from scipy.special import ndtr

    t = np.arange(-14.0, 14.01, 0.25)
    begin = np.array([-sweep_px / 2 + 0.3])
    end = begin + sweep_px
    # the exposure as 4001 instants: the rope's sides blurred at each, averaged
    at = begin[0] + np.linspace(0.0, 1.0, 4001)[:, None] * sweep_px
    slow = (ndtr((t - at + WIDTH_PX / 2) / BLUR_PX) - ndtr((t - at - WIDTH_PX / 2) / BLUR_PX)).mean(0)
    fast = band_profile(t[None, :], begin[:, None], end[:, None], WIDTH_PX, BLUR_PX)[0]
    assert fast == pytest.approx(slow, abs=2e-4)
    if sweep_px >= 10.0:  # a band much wider than the rope and its blur: its plateau is the rope's share of the sweep
        assert fast[np.argmin(np.abs(t - (begin[0] + sweep_px / 2)))] == pytest.approx(WIDTH_PX / sweep_px, rel=1e-3)


def test_a_reseeded_track_is_not_trusted_while_searched_lines_predict_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_track import HISTORY, BandTracker

    image, evidence = _still_frame()
    tracker = BandTracker(_rope(0.0), WIDTH_PX, BLUR_PX, PERIOD_MS * 1e6, 10)
    assert tracker.track(image, EXPOSURE_MS * 1e6, evidence)["trusted"]  # a still rope, seeded right
    tracker.reseed(_rope(0.0), _rope(0.0))
    after = [tracker.track(image, EXPOSURE_MS * 1e6, evidence) for _ in range(HISTORY + 1)]
    for fitted in after:
        assert fitted["locked"] and fitted["in_gate"] and fitted["tip_sigma_px"] < 0.5, fitted
        assert math.hypot(*(fitted["begin"][-1] - _rope(0.0)[-1])) < 1.5  # the far end measured afresh
    # right, but not trusted until the prediction's history holds fitted lines only
    assert [f["trusted"] for f in after] == [False] * HISTORY + [True]
