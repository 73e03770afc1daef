"""The one CLI policy of both programs (ropecam.shared.cli): outputs, --force, exit codes, -v, help, progress.

Every command that writes files refuses an existing output (exit 2, the file unchanged) and replaces it with
--force. The refusal happens before the command does any work, so each refusal case here is instant; the --force
cases run the cheap commands for real and, for the expensive ones (simulate, calibrate, compare, demo), show that
--force gets past the refusal to the command's own next check (their full runs with fresh outputs are tested in
their own test files).
"""

from __future__ import annotations

import argparse
import logging
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.cli import COMMAND_MODULES as DEVICE_MODULES
from ropecam.device.cli import main as device_main
from ropecam.host.cli import COMMAND_MODULES as HOST_MODULES
from ropecam.host.cli import main
from ropecam.shared.cli import EXIT_STATUS_HELP, build_parser

OLD = b"old contents\n"


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small complete recording of a simulated device (12 frames)."""
    from ropecam.host.receiver import check_packet
    from ropecam.host.recording.writer import Recorder, RecordingConfig
    from ropecam.host.session import Session
    from ropecam.host.sim.stream import SimulatedDevice

    path = tmp_path_factory.mktemp("recording") / "run.mcap"
    session = Session(Recorder(RecordingConfig(path)))
    for _, data in SimulatedDevice(7, frame_count=12, seed=3).messages(12, start_t_ns=time.time_ns()):
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    return path


@pytest.fixture(scope="module")
def frames(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A two-frame set of blank 64x48 images (the pipeline finds no rope: still one line per frame)."""
    from ropecam.device.capture.frameset import FrameSetWriter

    root = tmp_path_factory.mktemp("frames") / "set"
    with FrameSetWriter(root, (64, 48), 30.0) as writer:
        for k in range(2):
            writer.add(np.zeros((48, 64), np.uint8), k * 33_333_333, 4000)
    return root


def _existing(path: Path) -> Path:
    """Make `path` an existing output: a file with OLD in it, or a non-empty folder when it has no suffix."""
    if path.suffix:
        path.write_bytes(OLD)
        return path
    path.mkdir(exist_ok=True)
    (path / "keep.txt").write_bytes(OLD)
    return path / "keep.txt"


# command name -> (argv builder from (tmp_path, recording, frames), the output the argv names)
Case = Callable[[Path, Path, Path], tuple[list[str], Path]]
CASES: dict[str, Case] = {
    "calibrate intrinsics": lambda t, r, f: (
        [
            "calibrate",
            "intrinsics",
            str(t / "v.png"),
            "--board",
            "9x6",
            "--square-mm",
            "20",
            "--out",
            str(t / "c.yaml"),
        ],
        t / "c.yaml",
    ),
    "calibrate plane (its default report)": lambda t, r, f: (
        [
            "calibrate",
            "plane",
            str(t / "p.png"),
            "--camera",
            str(t / "c.yaml"),
            "--board",
            "9x6",
            "--square-mm",
            "20",
            "--out",
            str(t / "plane.yaml"),
        ],
        t / "plane.png",
    ),
    "compare": lambda t, r, f: (["compare", str(r), "--plane", str(t / "p.yaml"), "--out", str(t / "rep")], t / "rep"),
    "model simulate": lambda t, r, f: (["model", "simulate", "--out", str(t / "tip.csv")], t / "tip.csv"),
    "simulate": lambda t, r, f: (["simulate", "rig", "--out", str(t / "set")], t / "set"),
    "monitor --record": lambda t, r, f: (
        ["monitor", "--source", "udp://127.0.0.1:0", "--record", str(t / "live.mcap"), "--no-ui"],
        t / "live.mcap",
    ),
    "monitor --record (a later part)": lambda t, r, f: (
        ["monitor", "--source", "udp://127.0.0.1:0", "--record", str(t / "live.mcap"), "--no-ui"],
        t / "live_001.mcap",
    ),
    "recover": lambda t, r, f: (["recover", str(r), "--out", str(t / "fixed.mcap")], t / "fixed.mcap"),
    "replay --record": lambda t, r, f: (["replay", str(r), "--record", str(t / "re.mcap")], t / "re.mcap"),
    "replay --export-jsonl": lambda t, r, f: (["replay", str(r), "--export-jsonl", str(t / "r.jsonl")], t / "r.jsonl"),
    "replay --export-csv": lambda t, r, f: (
        ["replay", str(r), "--plane", str(t / "p.yaml"), "--export-csv", str(t / "r.csv")],
        t / "r.csv",
    ),
    "demo": lambda t, r, f: (["demo", "--out", str(t / "demo")], t / "demo"),
    "keygen": lambda t, r, f: (["keygen", str(t / "control.key")], t / "control.key"),
    "ropecam-device extract": lambda t, r, f: (["extract", str(f), "--out", str(t / "x.jsonl")], t / "x.jsonl"),
}


def _main(argv: list[str]) -> int:
    return device_main(argv) if argv[0] == "extract" else main(argv)


@pytest.mark.parametrize("name", list(CASES))
def test_an_existing_output_is_refused_with_exit_2_and_left_alone(
    name: str, tmp_path: Path, recording: Path, frames: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv, output = CASES[name](tmp_path, recording, frames)
    marker = _existing(output)
    assert _main(argv) == 2
    err = capsys.readouterr().err
    assert f"{output}:" in err and "pass --force" in err, err
    assert marker.read_bytes() == OLD


def test_force_replaces_a_key(tmp_path: Path) -> None:
    key = tmp_path / "control.key"
    _existing(key)
    assert main(["keygen", str(key), "--force"]) == 0
    assert key.read_bytes() != OLD and len(key.read_text().strip()) == 64


def test_force_replaces_a_model_run(tmp_path: Path) -> None:
    tip = _existing(tmp_path / "tip.csv")
    argv = ["model", "simulate", "--length-m", "0.3", "--elements", "2", "--duration-s", "0.01", "--quiet"]
    assert main([*argv, "--out", str(tip), "--force"]) == 0
    assert tip.read_text().startswith("t,x,y")


def test_force_replaces_recover_replay_and_extract_outputs(tmp_path: Path, recording: Path, frames: Path) -> None:
    fixed, jsonl, extracted = (_existing(tmp_path / name) for name in ("fixed.mcap", "r.jsonl", "x.jsonl"))
    assert main(["recover", str(recording), "--out", str(fixed), "--force"]) == 0
    assert fixed.read_bytes()[:8] == b"\x89MCAP0\r\n"
    assert main(["replay", str(recording), "--export-jsonl", str(jsonl), "--force"]) == 0
    assert len(jsonl.read_text().splitlines()) == 12
    assert device_main(["extract", str(frames), "--out", str(extracted), "--force", "--quiet"]) == 0
    assert len(extracted.read_text().splitlines()) == 2


def test_force_replaces_a_monitor_recording_and_its_later_parts(tmp_path: Path) -> None:
    live, later = _existing(tmp_path / "live.mcap"), _existing(tmp_path / "live_001.mcap")
    argv = ["monitor", "--source", "udp://127.0.0.1:0", "--record", str(live), "--no-ui", "--duration-s", "0.2"]
    assert main([*argv, "--force"]) == 0
    assert live.read_bytes()[:8] == b"\x89MCAP0\r\n" and not later.exists()


@pytest.mark.parametrize(
    ("argv", "next_check"),
    [
        ("simulate rig --calibration-views 2", "--calibration-views must be"),
        ("calibrate intrinsics {t}/missing.png --board 9x6 --square-mm 20", "missing.png"),
        ("compare {t}/m.jsonl --plane {t}/missing.yaml", "missing.yaml"),
        ("demo --calibration-views 2", "--calibration-views must be"),
    ],
)
def test_force_gets_an_expensive_command_past_the_refusal(
    argv: str, next_check: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    _existing(out)
    assert main([*argv.format(t=tmp_path).split(), "--out", str(out), "--force"]) != 0
    err = capsys.readouterr().err
    assert next_check in err and "pass --force" not in err, err


def test_exit_codes_usage_configuration_and_runtime(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as usage:
        main(["compare", "--no-such-option"])
    assert usage.value.code == 2
    bad = tmp_path / "rope.toml"
    bad.write_text("[rope]\nlength_m = -1\n")
    assert main(["model", "simulate", "--config", str(bad), "--out", str(tmp_path / "t.csv")]) == 2  # config
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    code = main(["replay", str(junk)])
    err = capsys.readouterr().err
    assert code == 1 and "ropecam: error:" in err and str(junk) in err, err  # runtime: bad data


def test_recover_of_an_empty_file_exits_1_and_writes_nothing(tmp_path: Path, capsys) -> None:
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    assert main(["recover", str(empty), "--out", str(tmp_path / "fixed.mcap")]) == 1
    assert str(empty) in capsys.readouterr().err
    assert not (tmp_path / "fixed.mcap").exists()


def _parsers(parser: argparse.ArgumentParser, prefix: str = "") -> dict[str, argparse.ArgumentParser]:
    found = {}
    for action in parser._actions:  # argparse keeps sub-parsers only here
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found[f"{prefix}{name}"] = sub
                found.update(_parsers(sub, f"{prefix}{name} "))
    return found


@pytest.mark.parametrize(("prog", "modules"), [("ropecam", HOST_MODULES), ("ropecam-device", DEVICE_MODULES)])
def test_every_help_lists_the_exit_codes_and_accepts_v_after_the_command(prog: str, modules: tuple[str, ...]) -> None:
    parser = build_parser(prog, "", modules)
    commands = _parsers(parser)
    assert len(commands) >= 3
    flat = " ".join(EXIT_STATUS_HELP.split())
    for name, sub in commands.items():
        assert flat in " ".join(sub.format_help().split()), name
    if prog == "ropecam":
        assert parser.parse_args(["keygen", "k", "-v"]).verbose == 1
        assert parser.parse_args(["-v", "keygen", "k"]).verbose == 1
        assert parser.parse_args(["-v", "keygen", "k", "-vv"]).verbose == 2
        assert parser.parse_args(["keygen", "k"]).verbose == 0


def test_library_info_logs_are_quiet_unless_verbose(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DASK_DISTRIBUTED__LOGGING__DISTRIBUTED", "info")
    key = tmp_path / "k"
    assert main(["keygen", str(key)]) == 0
    assert logging.getLogger("distributed").getEffectiveLevel() == logging.WARNING
    import os

    assert os.environ["DASK_DISTRIBUTED__LOGGING__DISTRIBUTED"] == "warning"  # worker processes inherit it
    assert main(["keygen", str(key), "--force", "-v"]) == 0
    assert logging.getLogger("distributed").getEffectiveLevel() == logging.INFO


def test_progress_off_a_terminal_is_periodic_lines(capsys: pytest.CaptureFixture[str]) -> None:
    from ropecam.host.progress import fit_progress, progress_bar

    report = fit_progress()
    for runs in range(1, 50):
        report(runs, 1e-3)
    with progress_bar("replay", 100, "messages") as progress:
        for done in range(0, 101, 10):
            progress(done)
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.splitlines()
    assert lines[0] == "  model runs 1: RMS 1.000 mm" and len(lines) <= 4  # not one line per call
    assert lines[-1] == "replay: 100/100 messages"
