"""`ropecam simulate` end to end: tiny sets from a saved trajectory, readable by the frame-set reader; clear errors."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.cli import main
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import SimConfig
from ropecam.host.sim.generate import write_frameset

SMALL_CAMERA = """
[camera]
fx_px = 500.0
fy_px = 495.0
cx_px = 160.0
cy_px = 100.0
width_px = 320
height_px = 200
plane_tvec_m = [0.0, -0.12, 1.5]
[scene]
render_diameter_m = 0.006
"""


@pytest.fixture
def rod_file(tmp_path: Path, rod_factory: Callable[..., Trajectory]) -> Path:
    path = tmp_path / "rod.npz"
    rod_factory(0.411, 0.1).save(path)
    return path


@pytest.fixture
def small_toml(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(SMALL_CAMERA)
    return path


def test_simulate_writes_a_readable_set(
    tmp_path: Path, rod_file: Path, small_toml: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "set"
    argv = ["simulate", "rig", "--out", str(out), "--frames", "3", "--trajectory", str(rod_file)]
    argv += ["--config", str(small_toml), "--seed", "7", "--polarity", "dark", "--clamp", "--scratch"]
    assert main(argv) == 0
    frames = FrameSet(out)
    assert len(frames) == 3 and frames.image_size == (320, 200) and frames.fps == 119.0
    assert frames.exposure_us == 4000
    rig = frames.meta["rig"]
    assert rig["preset"] == "rig" and rig["polarity"] == "dark" and rig["seed"] == 7
    assert rig["rope_length_m"] == 0.411 and rig["render_diameter_m"] == 0.006 and "clamp_box_px" in rig
    # A loaded trajectory is named as the motion's source; no model configuration is claimed for it.
    assert rig["trajectory_source"] == str(rod_file) and rig["model"] is None
    assert rig["config"]["scene"]["render_diameter_m"] == 0.006 and rig["config"]["rope"]["fixed_end"] == "pinned"
    assert frames.meta["camera"]["distortion"] == [-0.1793, 0.3891, 0.0, 0.0, 0.0]
    assert frames.meta["plane"]["tvec_m"] == [0.0, -0.12, 1.5]
    truth = frames.truth()
    assert truth is not None and truth["begin_px"].shape[0] == 3
    images = [image for _, image in frames]
    # Dark rope on a bright background: the rope pixels are the darkest.
    tip = np.rint(truth["tip_begin_px"][0]).astype(int)
    middle = np.rint(truth["begin_px"][0][len(truth["s_m"]) // 2]).astype(int)
    assert images[0][middle[1], middle[0]] < 100 < np.median(images[0])
    assert 0 <= tip[0] < 320 and 0 <= tip[1] < 200
    assert "3 frames, 4000 us" in capsys.readouterr().err
    # Reproducible: the same command gives the same frames.
    assert main([*argv[:2], "--out", str(tmp_path / "again"), *argv[4:]]) == 0
    for (_, a), b in zip(FrameSet(tmp_path / "again"), images, strict=True):
        np.testing.assert_array_equal(a, b)


def test_several_exposures_give_one_set_each(tmp_path: Path, rod_file: Path, small_toml: Path) -> None:
    out = tmp_path / "sets"
    argv = ["simulate", "rig", "--out", str(out), "--frames", "2", "--trajectory", str(rod_file), "-q"]
    assert main([*argv, "--config", str(small_toml), "--exposure-ms", "1", "5", "--first-exposure-ms", "60"]) == 0
    assert FrameSet(out / "exposure_1ms").exposure_us == 1000
    assert FrameSet(out / "exposure_5ms").exposure_us == 5000
    one, five = (FrameSet(out / f"exposure_{ms}ms").truth() for ms in (1, 5))
    assert one is not None and five is not None
    np.testing.assert_array_equal(one["begin_px"], five["begin_px"])  # same motion, same start times
    assert np.all(five["subframes"] > one["subframes"])


def test_refuses_to_overwrite_and_explains_errors(
    tmp_path: Path, rod_file: Path, small_toml: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "set"
    base = ["simulate", "rig", "--out", str(out), "--trajectory", str(rod_file), "--config", str(small_toml), "-q"]
    assert main([*base, "--frames", "2"]) == 0
    before = (out / "frames" / "000000.png").read_bytes()
    assert main([*base, "--frames", "2", "--seed", "3"]) == 2
    assert "exists already" in capsys.readouterr().err
    assert (out / "frames" / "000000.png").read_bytes() == before
    assert main([*base, "--frames", "2", "--seed", "3", "--overwrite"]) == 0
    # The 0.1 s trajectory holds 12 frames at 119 FPS with 4 ms exposures, not 50.
    assert main([*base, "--frames", "50", "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert "holds 12 frames" in err and "fewer frames" in err
    bad = tmp_path / "bad.toml"
    bad.write_text("[scene]\npolarty = 'dark'\n")
    assert main([*base, "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "polarty" in err and str(bad) in err
    assert main([*base, "--exposure-ms", "9"]) == 2  # longer than the frame period at 119 FPS
    assert "exposure_ms" in capsys.readouterr().err
    assert main([*base, "--trajectory", str(tmp_path / "missing.npz")]) == 2
    assert "missing.npz" in capsys.readouterr().err


def test_wrong_rope_length_is_refused(tmp_path: Path, rod_factory: Callable[..., Trajectory],
                                      small_toml: Path, capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    path = tmp_path / "long.npz"
    rod_factory(1.0, 0.1).save(path)
    argv = ["simulate", "rig", "--out", str(tmp_path / "s"), "--trajectory", str(path), "--config", str(small_toml)]
    assert main(argv) == 2
    assert "rope.length_m" in capsys.readouterr().err


def test_interrupted_run_keeps_frames_and_their_truth(
    tmp_path: Path, tiny: Callable[..., SimConfig], rod_factory: Callable[..., Trajectory]
) -> None:
    def stop_after_two(done: int, total: int) -> None:
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_frameset(tiny(frames=5), rod_factory(0.411, 0.2), tmp_path / "set", 4.0, progress=stop_after_two)
    frames = FrameSet(tmp_path / "set")
    truth = frames.truth()
    assert len(frames) == 2 and truth is not None
    assert truth["begin_px"].shape[0] == 2 and truth["t_begin_ns"].tolist() == [r.t_ns for r in frames.records]


def test_help_lists_presets(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = capsys.readouterr().out
    for name in ("paper", "paper-soft", "rig", "rig-soft", "--exposure-ms", "--trajectory", "docs/frameset.md"):
        assert name in text


def test_model_config_file_gives_the_model_commands_motion(tmp_path: Path) -> None:
    """One TOML file drives `ropecam model simulate` and `ropecam simulate`: the same motion, bit for bit."""
    config = tmp_path / "rope.toml"
    config.write_text(
        "[rope]\nlength_m = 0.411\nei_nm2 = 1e-4\nfixed_end = 'clamped'\ndrag_coefficient = 1.122\n"
        "mass_damping_per_s = 0.5\n[solver]\nelements = 6\nduration_s = 0.05\nspectral_radius = 0.8\n"
    )
    model_npz = tmp_path / "model.npz"
    argv = ["model", "simulate", "--config", str(config), "--out", str(tmp_path / "tip.csv")]
    assert main([*argv, "--trajectory", str(model_npz), "--quiet"]) == 0
    out = tmp_path / "set"
    assert main(["simulate", "rig", "--out", str(out), "--frames", "2", "--config", str(config), "-q"]) == 0
    expected, got = Trajectory.load(model_npz), Trajectory.load(out / "trajectory.npz")
    np.testing.assert_array_equal(got.times_s, expected.times_s)
    np.testing.assert_array_equal(got.q, expected.q)
    model = FrameSet(out).meta["rig"]["model"]
    assert model["rope"]["fixed_end"] == "clamped" and model["solver"]["elements"] == 6
    assert model["solver"]["duration_s"] == 0.05


def test_frame_sets_record_the_version_the_cli_reports(
    tmp_path: Path,
    tiny: Callable[..., SimConfig],
    rod_factory: Callable[..., Trajectory],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    import ropecam.shared.cli

    monkeypatch.setattr(ropecam.shared.cli, "version", lambda name: "9.8.7-test")
    with pytest.raises(SystemExit):
        main(["--version"])
    assert "9.8.7-test" in capsys.readouterr().out
    write_frameset(tiny(frames=1), rod_factory(0.411, 0.2), tmp_path / "set", 4.0)
    assert FrameSet(tmp_path / "set").meta["rig"]["ropecam_version"] == "9.8.7-test"


@pytest.mark.parametrize("views", ["2", "-3"])
def test_bad_calibration_views_are_refused_before_any_work(
    tmp_path: Path, views: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import ropecam.host.sim.dynamics

    def no_solving(*args: object, **kwargs: object) -> None:
        raise AssertionError("the model was solved before the arguments were checked")

    monkeypatch.setattr(ropecam.host.sim.dynamics, "solve_trajectory", no_solving)
    out = tmp_path / "set"
    assert main(["simulate", "rig", "--out", str(out), "--frames", "1", f"--calibration-views={views}", "-q"]) == 2
    assert f"--calibration-views must be 0 (none) or >= 4, got {views}" in capsys.readouterr().err
    assert not out.exists()


def test_existing_calibration_set_is_refused_before_any_work(
    tmp_path: Path, rod_file: Path, small_toml: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "set"
    (out / "calibration").mkdir(parents=True)
    (out / "calibration" / "truth.json").write_text("{}")
    argv = ["simulate", "rig", "--out", str(out), "--frames", "1", "--trajectory", str(rod_file)]
    assert main([*argv, "--config", str(small_toml), "--calibration-views", "4", "-q"]) == 2
    assert "a calibration set exists already (use --overwrite to replace it)" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["calibration"]  # no frame set rendered


@pytest.mark.parametrize(
    ("option", "message"),
    [(["--gamma", "0.5"], "sensor.gamma must be in [1.0, 3.0], got 0.5"),
     (["--jpeg-quality", "101"], "sensor.jpeg_quality must be in [0, 100], got 101"),
     (["--sharpen", "-1"], "sensor.sharpen must be in [0.0, 3.0], got -1.0")],
)  # fmt: skip
def test_bad_realism_options_name_key_and_range_and_write_nothing(
    tmp_path: Path, rod_file: Path, small_toml: Path, option: list[str], message: str,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    out = tmp_path / "set"
    argv = ["simulate", "rig", "--out", str(out), "--trajectory", str(rod_file), "--config", str(small_toml), "-q"]
    assert main([*argv, *option]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_lab_preset_and_paper_exposures_end_to_end(
    tmp_path: Path, rod_factory: Callable[..., Trajectory], small_toml: Path, realdata_dir: Path
) -> None:
    rod = tmp_path / "rod.npz"
    rod_factory(0.411, 0.1).save(rod)
    out = tmp_path / "lab"
    argv = ["simulate", "lab-rolling", "--out", str(out), "--frames", "2", "--trajectory", str(rod), "-q"]
    assert main([*argv, "--config", str(small_toml), "--photo-dir", str(realdata_dir)]) == 0
    frames = FrameSet(out)
    rig = frames.meta["rig"]
    assert rig["preset"] == "lab-rolling" and rig["readout_ms"] == 7.0 and "rod_px" in rig
    assert rig["rope_photo"] == str(realdata_dir / "trackdlo_rope/rope.png")
    assert rig["config"]["sensor"]["gamma"] == 2.2
    truth = frames.truth()
    assert truth is not None and truth["row_offset_ns"].shape == (200,)
    long_rod = tmp_path / "long.npz"
    rod_factory(1.0, 0.1).save(long_rod)
    paper = tmp_path / "paper"
    argv = ["simulate", "lab-hard", "--out", str(paper), "--frames", "2", "--trajectory", str(long_rod), "-q"]
    assert main([*argv, "--paper-exposures", "--exposure-ms", "15", "--photo-dir", str(realdata_dir)]) == 0
    one = FrameSet(paper)  # the four exposures are the preset's; one is enough here
    assert one.image_size == (800, 512) and one.fps == 30.0 and one.exposure_us == 15000
    assert one.meta["rig"]["preset"] == "lab-hard+paper-exposures" and "distractor_px" in one.meta["rig"]
