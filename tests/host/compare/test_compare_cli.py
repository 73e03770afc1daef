"""`ropecam compare` end to end on a simulated rig recording.

The measurement file here is written from the simulator's pixel ground truth in the extract JSON-lines format, so
these tests check the comparison machinery (pixel -> metre conversion with the calibration files, material-point
tracking, release-time and parameter fits, the report), not the pipeline's measurement accuracy.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.calibration.files import read_plane, write_plane
from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.host.cli import main

EI_TRUE = 4e-5
MODEL_TOML = """[rope]
length_m = 0.411
ei_nm2 = {ei}
[solver]
elements = 8
step_s = 1e-3
"""


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 24-frame simulated rig recording (soft rope), its plane file, model files and truth-made JSON lines."""
    root = tmp_path_factory.mktemp("recording")
    config = root / "sim.toml"
    config.write_text(MODEL_TOML.format(ei=EI_TRUE) + "[scene]\nrender_diameter_m = 0.0025\n")
    args = ["simulate", "rig", "--out", str(root / "set"), "--frames", "24", "--first-exposure-ms", "100"]
    assert main([*args, "--config", str(config), "-q"]) == 0
    frames = FrameSet(root / "set")
    truth = frames.truth()
    assert truth is not None
    camera = CameraModel(
        np.array(frames.meta["camera"]["camera_matrix"]),
        np.array(frames.meta["camera"]["distortion"]),
        tuple(frames.meta["camera"]["image_size"]),
    )
    plane = PlanePose.from_rvec(frames.meta["plane"]["rvec"], frames.meta["plane"]["tvec_m"])
    write_plane(root / "plane.yaml", camera, plane)
    with (root / "truth.jsonl").open("w") as handle:
        for i, record in enumerate(frames.records):
            line = {
                "frame": record.frame,
                "t_ns": int(truth["t_begin_ns"][i]),
                "t_end_ns": int(truth["t_end_ns"][i]),
                "status": "OK",
                "begin": truth["begin_px"][i].tolist(),
                "end": truth["end_px"][i].tolist(),
            }
            handle.write(json.dumps(line) + "\n")
    (root / "true.toml").write_text(MODEL_TOML.format(ei=EI_TRUE))
    (root / "wrong.toml").write_text(MODEL_TOML.format(ei=3 * EI_TRUE))
    return root


def _compare(root: Path, model: str, out: Path, *extra: str) -> int:
    return main(["compare", str(root / "truth.jsonl"), "--plane", str(root / "plane.yaml"),
                 "--model", str(root / model), "--out", str(out), *extra])  # fmt: skip


def test_true_model_matches_and_report_is_written(recording: Path, tmp_path: Path, capsys) -> None:
    assert _compare(recording, "true.toml", tmp_path / "report") == 0
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert max(summary["rms_error_mm"]) < 0.5
    assert abs(summary["release_time_s"]) < 0.5e-3  # the simulator's clock starts at the release
    # The release time is on the recording's clock (a live one counts the device's uptime): the line says how long
    # before the first frame it is.
    lead = summary["first_sample_time_s"] - summary["release_time_s"]
    assert 0 < lead < 1 and f"on the recording's clock ({lead:.4f} s before its first frame)" in capsys.readouterr().out
    for name in ("index.html", "trajectories.png", "error_vs_time.png", "error_per_point.png", "shapes.png"):
        assert (tmp_path / "report" / name).stat().st_size > 1000
    assert "summary.json" in (tmp_path / "report" / "index.html").read_text()


def test_identification_recovers_ei_and_release_time(recording: Path, tmp_path: Path) -> None:
    assert _compare(recording, "wrong.toml", tmp_path / "report", "--fit", "ei", "--no-plots") == 0
    assert not list((tmp_path / "report").glob("*.png"))  # the numbers, tables and HTML only
    fit = json.loads((tmp_path / "report" / "summary.json").read_text())["fit"]
    assert fit["values"]["ei"] == pytest.approx(EI_TRUE, rel=0.05)
    assert abs(fit["values"]["t0"]) < 0.5e-3
    assert fit["rms_after_mm"] < fit["rms_before_mm"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--fit", "stiffness"], "unknown parameter 'stiffness'"),
        (["--points", "0.2,0.9"], r"--points must lie in \[0, 0.411\]"),
    ],
)
def test_bad_options_are_named(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert _compare(recording, "true.toml", tmp_path / "r", *args) == 2
    assert __import__("re").search(message, capsys.readouterr().err)


def test_bad_measurement_line_is_named(recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    broken = tmp_path / "broken.jsonl"
    broken.write_text((recording / "truth.jsonl").read_text().splitlines()[0] + "\n{not json\n")
    code = main(["compare", str(broken), "--plane", str(recording / "plane.yaml"), "--out", str(tmp_path / "r")])
    assert code == 1  # bad data: a runtime error
    assert f"{broken}:2" in capsys.readouterr().err


@pytest.mark.slow
def test_batch_on_local_dask_gives_the_single_run_numbers(recording: Path, tmp_path: Path) -> None:
    lines = (recording / "truth.jsonl").read_text().splitlines()
    runs = tmp_path / "runs"
    runs.mkdir()
    # Two runs of different frames on two workers: each run's numbers are its own (a run per worker, none mixed).
    for name, part in {"a": lines[:12], "b": lines[10:]}.items():
        (runs / f"{name}.jsonl").write_text("\n".join(part) + "\n")
    common = ["--plane", str(recording / "plane.yaml"), "--model", str(recording / "true.toml"), "--no-plots"]
    assert main(["compare", str(runs), *common, "--out", str(tmp_path / "batch"), "--workers", "2"]) == 0
    batch = json.loads((tmp_path / "batch" / "summary.json").read_text())
    assert sorted(batch) == ["a", "b"]
    assert batch["a"]["samples"] != batch["b"]["samples"] or batch["a"]["rms_error_mm"] != batch["b"]["rms_error_mm"]
    for name in batch:
        assert main(["compare", str(runs / f"{name}.jsonl"), *common, "--out", str(tmp_path / name)]) == 0
        single = json.loads((tmp_path / name / "summary.json").read_text())
        for key in ("release_time_s", "rms_error_mm", "max_error_mm", "overall_rms_error_mm", "samples"):
            assert batch[name][key] == single[key], (name, key)


def test_no_measured_shape_is_a_clear_error_not_a_traceback(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    empty = tmp_path / "empty.jsonl"
    empty.write_text('{"frame": 0, "t_ns": 0, "t_end_ns": 4, "status": "NO_ROPE", "begin": null, "end": null}\n')
    code = main(["compare", str(empty), "--plane", str(recording / "plane.yaml"), "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert code == 1 and f"{empty}: no frame has a measured rope shape" in err and "Traceback" not in err


def test_a_wild_shape_is_skipped_with_a_warning_and_the_rest_compared(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lines = [json.loads(line) for line in (recording / "truth.jsonl").read_text().splitlines()]
    lines[3]["end"] = [[500.0, 100.0], [500.0, 1e7]]  # far beyond the horizon of the tilted plane: misses it
    (tmp_path / "m.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    # The rig lens's distortion folds far pixels back into view; without it the wild pixel's ray misses the plane.
    plane_file = read_plane(recording / "plane.yaml")
    camera = CameraModel(plane_file.camera.camera_matrix, np.zeros(5), plane_file.camera.image_size)
    write_plane(tmp_path / "plane.yaml", camera, plane_file.plane)
    (tmp_path / "true.toml").write_text((recording / "true.toml").read_text())
    out = tmp_path / "report"
    code = main(["compare", str(tmp_path / "m.jsonl"), "--plane", str(tmp_path / "plane.yaml"),
                 "--model", str(tmp_path / "true.toml"), "--out", str(out), "--no-plots"])  # fmt: skip
    assert code == 0
    err = capsys.readouterr().err
    assert f"warning: frame {lines[3]['frame']} " in err and "skipped (off the plane)" in err
    summary = json.loads((out / "summary.json").read_text())
    assert all(np.isfinite(summary["rms_error_mm"]))
    assert "1 shapes skipped" in (out / "index.html").read_text()


def test_mcap_frame_set_and_extract_jsonl_give_the_same_comparison(recording: Path, tmp_path: Path) -> None:
    """The three measurement kinds of one run: raw frames measured now, the MCAP of their stream, its JSONL."""
    frames = recording / "set"
    mcap = tmp_path / "run.mcap"
    assert main(["replay", "--frames", str(frames), "--record", str(mcap)]) == 0
    assert main(["replay", str(mcap), "--export-jsonl", str(tmp_path / "run.jsonl")]) == 0
    numbers = []
    for name, source in (("set", frames), ("mcap", mcap), ("jsonl", tmp_path / "run.jsonl")):
        assert _compare_path(recording, source, tmp_path / name, "--no-plots") == 0
        numbers.append(json.loads((tmp_path / name / "summary.json").read_text()))
    for other in numbers[1:]:
        assert other["rms_error_mm"] == numbers[0]["rms_error_mm"]
        assert other["release_time_s"] == numbers[0]["release_time_s"]
    assert all(np.isfinite(numbers[0]["rms_error_mm"]))


def test_unknown_measurement_kinds_and_devices_are_named(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "notes.txt").write_text("hello\n")
    assert _compare_path(recording, tmp_path / "notes.txt", tmp_path / "r1") != 0
    assert "notes.txt: unknown measurement kind '.txt'" in capsys.readouterr().err
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.md").write_text("nothing here\n")
    assert _compare_path(recording, empty, tmp_path / "r2") != 0
    assert "no measurements in this folder" in capsys.readouterr().err


def _compare_path(root: Path, source: Path, out: Path, *extra: str) -> int:
    return main(["compare", str(source), "--plane", str(root / "plane.yaml"),
                 "--model", str(root / "true.toml"), "--out", str(out), *extra])  # fmt: skip
