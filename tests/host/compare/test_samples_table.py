"""`ropecam compare` results in metres: the per-sample table, its in-frame velocities, x(t)/y(t), provenance.

A short version of `ropecam demo`'s data: the same preset (rig-soft, 4 ms exposures at 119 FPS) and rope model,
8 frames around the tip's fastest swing (0.215-0.28 s after the release; the demo's 60 frames start at 0.05 s), and
the simulator's exact camera and plane instead of the checkerboard calibration (on the demo's data both give the
same velocities to 0.01 %: docs/compare.md). The frame set is measured by the device pipeline (the daemon's, run
offline), so the in-frame velocities are measured ones.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.calibration.files import write_plane
from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.host.cli import main
from ropecam.host.demo import MODEL_TOML, TRUE_EI_NM2
from ropecam.host.model.trajectory import Trajectory


def _simulate_and_compare(root: Path, readout_ms: float = 0.0) -> Path:
    """Simulate the short rig-soft run (a rolling shutter with `readout_ms` > 0, measured with the camera's
    ``[capture] readout_us``), write the exact calibration and the true rope model, and compare; returns `root`."""
    sim = ["simulate", "rig-soft", "--out", str(root / "rig"), "--frames", "8", "--first-exposure-ms", "215", "-q"]
    assert main([*sim, "--readout-ms", str(readout_ms)] if readout_ms else sim) == 0
    meta = FrameSet(root / "rig").meta
    camera = CameraModel(
        np.array(meta["camera"]["camera_matrix"]), np.array(meta["camera"]["distortion"]), meta["camera"]["image_size"]
    )
    write_plane(root / "plane.yaml", camera, PlanePose.from_rvec(meta["plane"]["rvec"], meta["plane"]["tvec_m"]))
    (root / "rope.toml").write_text(MODEL_TOML.format(ei=TRUE_EI_NM2))
    command = ["compare", str(root / "rig"), "--plane", str(root / "plane.yaml"), "--model", str(root / "rope.toml"),
               "--release-time-s", "0", "--out", str(root / "report")]  # fmt: skip
    if readout_ms:
        (root / "device.toml").write_text(f"[capture]\nreadout_us = {round(readout_ms * 1000)}\n")
        command += ["--config", str(root / "device.toml")]
    assert main(command) == 0
    return root


@pytest.fixture(scope="module")
def compared(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The demo's rig-soft run, short: simulate, exact calibration, compare with the true rope model."""
    return _simulate_and_compare(tmp_path_factory.mktemp("demo-short"))


def _rows(report: Path) -> list[dict[str, str]]:
    with open(report / "samples.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def test_table_rows_reproduce_the_summary_rms_per_point(compared: Path) -> None:
    report = compared / "report"
    summary = json.loads((report / "summary.json").read_text())
    rows = _rows(report)
    assert len(rows) == summary["samples"] * len(summary["material_points_s_m"])
    for s, rms in zip(summary["material_points_s_m"], summary["rms_error_m"], strict=True):
        errors = np.array([float(r["error_m"]) for r in rows if float(r["point_s_m"]) == s and r["error_m"]])
        assert errors.size > 0
        assert np.sqrt(np.mean(errors**2)) == pytest.approx(rms, abs=1e-9)
    measured_rows = [r for r in rows if r["measured_x_m"]]  # (a frame not OK, e.g. a first split nothing ordered)
    for row in measured_rows[:8]:  # the error column is |measured - model|
        measured = np.array([float(row["measured_x_m"]), float(row["measured_y_m"])])
        model = np.array([float(row["model_x_m"]), float(row["model_y_m"])])
        assert np.hypot(*(measured - model)) == pytest.approx(float(row["error_m"]), abs=1e-15)
    pyarrow = pytest.importorskip("pyarrow.parquet")
    table = pyarrow.read_table(report / "samples.parquet")
    assert table.num_rows == len(rows) and table.column_names == list(rows[0])


def test_in_frame_velocities_match_the_true_ones_at_mid_exposure(compared: Path) -> None:
    """Measured within one frame: (rope at the exposure end - at its start) / exposure time, against the
    simulator's true velocity at mid-exposure; RMS error relative to the tip's peak true speed."""
    rows = [r for r in _rows(compared / "report") if r["sample"] == "start" and r["in_frame_vx_m_s"]]
    truth = Trajectory.load(compared / "rig" / "trajectory.npz")
    points = sorted({float(r["point_s_m"]) for r in rows})
    tip = max(points)
    peak = 0.0
    errors: dict[float, list[float]] = {s: [] for s in points}
    for row in rows:
        s, mid = float(row["point_s_m"]), float(row["mid_exposure_s"])
        true = truth.velocities([mid], [s])[0, 0]
        measured = np.array([float(row["in_frame_vx_m_s"]), float(row["in_frame_vy_m_s"])])
        errors[s].append(float(np.hypot(*(measured - true))))
        if s == tip:
            peak = max(peak, float(np.hypot(*true)))
        model = np.array([float(row["model_vx_m_s"]), float(row["model_vy_m_s"])])
        assert np.hypot(*(model - true)) < 0.05 * peak + 0.05  # the true model, at the fitted release
    assert peak > 4.0  # m/s: the fastest part of the swing (4.5 m/s at 0.25 s)
    relative = {s: float(np.sqrt(np.mean(np.square(e)))) / peak for s, e in errors.items()}
    assert len(errors[tip]) >= 7
    # #20 acceptance 4: within 2 % at every point (the demo's 60 frames, docs/compare.md: 0.8-1.4 %).
    assert max(relative.values()) < 0.02, relative


def test_in_frame_velocity_of_exact_shapes_is_the_mid_exposure_velocity(compared: Path) -> None:
    """The method alone, on the simulator's exact shapes: the finite difference over one exposure and the tracking
    by arc length with uniform stretch cost 0.01-0.02 % of the tip's peak speed on the demo's data."""
    from ropecam.host.calibration.files import read_plane
    from ropecam.host.compare.measurement import MeasuredFrame, tracks_from_frames

    frames = FrameSet(compared / "rig")
    truth = frames.truth()
    plane = read_plane(compared / "plane.yaml")
    measured = [
        MeasuredFrame(
            i, int(truth["t_begin_ns"][i]), int(truth["t_end_ns"][i]), truth["begin_px"][i], truth["end_px"][i]
        )
        for i in range(len(frames))
    ]
    points = [0.411 * f for f in (0.25, 0.5, 0.75, 1.0)]
    tracks, _ = tracks_from_frames(measured, plane.camera, plane.plane, points, 0.411)
    motion = Trajectory.load(compared / "rig" / "trajectory.npz")
    assert np.all(tracks.mid_exposure_s == tracks.mid_exposure_s[:, :1])  # a global shutter: one time per frame
    true = np.stack([motion.velocities([t], points)[0] for t in tracks.mid_exposure_s[:, 0]])
    peak = float(np.max(np.linalg.norm(true[:, -1], axis=-1)))
    error = np.linalg.norm(tracks.in_frame_velocities_m_s - true, axis=-1)
    assert float(np.sqrt(np.mean(error**2))) / peak < 1e-3


def test_report_has_xy_plots_and_records_its_provenance(compared: Path) -> None:
    report = compared / "report"
    summary = json.loads((report / "summary.json").read_text())
    provenance = summary["provenance"]
    assert provenance["ropecam_version"] and provenance["date_utc"].endswith("+00:00")
    assert provenance["command_line"].startswith("ropecam compare ")
    roles = {f["role"]: f for f in provenance["files"]}
    assert set(roles) == {"plane", "model"}
    import hashlib

    assert roles["plane"]["sha256"] == hashlib.sha256((compared / "plane.yaml").read_bytes()).hexdigest()
    assert (report / "xy_vs_time.png").stat().st_size > 1000
    page = (report / "index.html").read_text()
    assert "samples.csv" in page and roles["plane"]["sha256"] in page


def test_replay_exports_the_measured_points_in_metres(compared: Path, tmp_path: Path) -> None:
    """`replay --frames --export-csv`: the same measured columns as compare's table."""
    out = tmp_path / "points.csv"
    argv = ["replay", "--frames", str(compared / "rig"), "--plane", str(compared / "plane.yaml"),
            "--rope-length-m", "0.411", "--export-csv", str(out)]  # fmt: skip
    assert main(argv) == 0
    with open(out, newline="") as handle:
        exported = list(csv.DictReader(handle))
    compared_rows = _rows(compared / "report")
    assert len(exported) == len(compared_rows)
    for a, b in zip(exported, compared_rows, strict=True):
        for key in ("time_s", "point_s_m", "measured_x_m", "measured_y_m", "in_frame_vx_m_s"):
            assert a[key] == b[key], key


def _errors_against_truth(root: Path) -> tuple[dict[float, float], dict[float, float], float]:
    """Per material point: RMS position error (m) against the simulator's motion at each row's `time_s`, and RMS
    in-frame velocity error at its `mid_exposure_s` relative to the tip's peak speed; and the largest difference
    between a row's `time_s` and the simulator's own time of that point (s; rolling shutter only, else 0)."""
    motion = Trajectory.load(root / "rig" / "trajectory.npz")
    truth = FrameSet(root / "rig").truth()
    rows = _rows(root / "report")
    points = sorted({float(r["point_s_m"]) for r in rows})
    position: dict[float, list[float]] = {s: [] for s in points}
    velocity: dict[float, list[float]] = {s: [] for s in points}
    peak, worst_dt = 0.0, 0.0
    for row in rows:
        if not row["measured_x_m"]:  # not measured (a frame not OK, e.g. a first split nothing ordered)
            continue
        s, t = float(row["point_s_m"]), float(row["time_s"])
        measured = np.array([float(row["measured_x_m"]), float(row["measured_y_m"])])
        position[s].append(float(np.hypot(*(measured - motion.positions([t], [s])[0, 0]))))
        if "begin_point_t_ns" in truth:
            seen_ns = truth["begin_point_t_ns" if row["sample"] == "start" else "end_point_t_ns"][int(row["frame"])]
            worst_dt = max(worst_dt, abs(t - float(np.interp(s, truth["s_m"], seen_ns)) * 1e-9))
        if row["sample"] == "start":
            true = motion.velocities([float(row["mid_exposure_s"])], [s])[0, 0]
            in_frame = np.array([float(row["in_frame_vx_m_s"]), float(row["in_frame_vy_m_s"])])
            velocity[s].append(float(np.hypot(*(in_frame - true))))
            peak = max(peak, float(np.hypot(*true))) if s == points[-1] else peak
    rms = {s: float(np.sqrt(np.mean(np.square(e)))) for s, e in position.items()}
    return rms, {s: float(np.sqrt(np.mean(np.square(e)))) / peak for s, e in velocity.items()}, worst_dt


def test_a_rolling_shutter_measures_as_well_as_a_global_one(compared: Path, tmp_path: Path) -> None:
    """The same run through a rolling shutter (7 ms readout, the last row 7 ms after the first; `[capture]
    readout_us` in the compared frame set's config): every row's `time_s` is when the simulator's camera saw that
    point (to the row convention's 13 us: the simulator spreads the readout over height - 1 rows, the device over
    height), and positions at those times and in-frame velocities at their `mid_exposure_s` are within a small
    margin of the global shutter's. Measured (device pipeline, 8 frames): positions 0.18-0.22 mm RMS (global
    0.10-0.18 mm), velocities 1.5-2.3 % (global 1.0-1.7 %; 1.2-1.8 % and 0.8-1.7 % before the split read the rope's
    own contrast along the band, session 13: the quarter of the rope next to the fixed end) of the tip's peak speed.
    The same frames read as a global shutter are 1-24 mm off."""
    rolling = _simulate_and_compare(tmp_path, readout_ms=7.0)
    position, velocity, worst_dt = _errors_against_truth(rolling)
    position_global, velocity_global, _ = _errors_against_truth(compared)
    assert worst_dt < 20e-6
    for s in position:
        assert position[s] < position_global[s] + 0.08e-3, (s, position, position_global)
        assert velocity[s] < velocity_global[s] + 0.010, (s, velocity, velocity_global)
    assert velocity[max(velocity)] < 0.02
    summary = json.loads((rolling / "report" / "summary.json").read_text())
    assert max(summary["rms_error_m"]) < 0.5e-3  # against the model, at the fitted release


@pytest.mark.parametrize("capture", ["readout_us = -1", "readout_us = 9000"])  # negative; longer than 8.4 ms
def test_a_bad_readout_in_the_config_is_refused_naming_it(
    compared: Path, tmp_path: Path, capture: str, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "device.toml"
    config.write_text(f"[capture]\n{capture}\n")
    command = ["compare", str(compared / "rig"), "--plane", str(compared / "plane.yaml"), "--config", str(config),
               "--out", str(tmp_path / "report")]  # fmt: skip
    assert main(command) == 2
    assert "[capture] readout_us" in capsys.readouterr().err
    assert not (tmp_path / "report").exists()
