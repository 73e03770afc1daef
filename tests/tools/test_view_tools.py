"""tools/bench.py recording-size and tools/evaluate.py montage end to end (subprocesses, small inputs; their
refusals in this process)."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from subprocess import CompletedProcess

import cv2
import pytest

from ropecam.host.cli import main as ropecam

RunTool = Callable[..., CompletedProcess[str]]
"""The `run_tool` fixture (tests/tools/conftest.py)."""


def _record_stream(path: Path, frames: int) -> Path:
    """A simulated device's stream recorded as `ropecam monitor --record` does."""
    from ropecam.host.receiver import check_packet
    from ropecam.host.recording.writer import Recorder, RecordingConfig
    from ropecam.host.session import Session
    from ropecam.host.sim.stream import SimulatedDevice

    device = SimulatedDevice(3, fps=10.0, frame_count=frames, seed=2)
    session = Session(Recorder(RecordingConfig(path)), None)
    start_ns = 1_800_000_000_000_000_000
    for offset_s, data in device.messages(frames):
        session.handle(check_packet(data, start_ns + round(offset_s * 1e9)))
    session.close()
    return path


@pytest.mark.slow
def test_recording_size_compares_both_encodings_on_the_same_frames(run_tool: RunTool, tmp_path: Path) -> None:
    recording = _record_stream(tmp_path / "run.mcap", frames=12)
    done = run_tool("bench.py", "recording-size", str(recording), timeout_s=300)
    assert done.returncode == 0, done.stderr
    per_encoding = dict(re.findall(r"^(json|protobuf): (\d+) frames", done.stdout, flags=re.M))
    assert per_encoding == {"json": "12", "protobuf": "12"}, done.stdout
    ratio = float(re.search(r"protobuf / json per frame: file ([0-9.]+)", done.stdout).group(1))
    assert 0.0 < ratio <= 0.5, done.stdout


def test_recording_size_names_a_missing_recording(run_tool_here: RunTool, tmp_path: Path) -> None:
    done = run_tool_here("bench.py", "recording-size", str(tmp_path / "none.mcap"))
    assert done.returncode == 2 and "none.mcap: no such recording" in done.stderr, done.stderr


@pytest.mark.slow
def test_montage_puts_one_row_per_preset_with_whole_frame_and_crops(
    run_tool: RunTool, run_tool_here: RunTool, tmp_path: Path
) -> None:
    sets = tmp_path / "sets"
    assert ropecam(["simulate", "rig", "--out", str(sets / "rig"), "--frames", "3", "-q"]) == 0
    out = tmp_path / "montage.png"
    done = run_tool("evaluate.py", "montage", str(sets), "--presets", "rig", "rig", "--frame", "2", "--out", str(out))
    assert done.returncode == 0, done.stderr
    image = cv2.imread(str(out), cv2.IMREAD_GRAYSCALE)
    # Two rows of 128 px with a 4 px gap; each row: the whole frame at 128 px high and three 128 px crops.
    assert image.shape[0] == 2 * 128 + 4
    assert image.shape[1] > 3 * 128 + 128
    done = run_tool_here("evaluate.py", "montage", str(sets), "--presets", "lab", "--out", str(tmp_path / "x.png"))
    assert done.returncode == 2 and "no frame set" in done.stderr, done.stderr
