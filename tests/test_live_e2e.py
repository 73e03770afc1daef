"""The live path end to end, as on the rig: `ropecam-device run` replays recorded frames and streams over UDP on
127.0.0.1 into `ropecam monitor --record`; the recording, replayed and exported, holds every frame's result, equal
to the offline `ropecam-device extract` of the same frames (issue 6 acceptance 1 at a paced 30 FPS, issue 7
acceptance 1)."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.cli import main as device_main
from ropecam.device.daemon.config import SenderConfig
from ropecam.host.cli import main as host_main
from ropecam.host.monitor.process import MonitorProcess
from ropecam.shared.protocol import polyline_distances_px


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _read_jsonl(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


@pytest.mark.slow
def test_daemon_streams_into_the_monitor_recording(tmp_path: Path, rig_frames: Path) -> None:
    frames = rig_frames
    port = _free_udp_port()
    recording = tmp_path / "run.mcap"
    monitor = MonitorProcess(
        ["--source", f"udp://127.0.0.1:{port}", "--record", str(recording), "--no-ui", "--duration-s", "120"]
    )
    try:
        daemon = subprocess.run(
            # Paced at 10 FPS: the paced replay hands the daemon the newest frame, as a camera does, so a frame that
            # takes longer than the period skips the next. Frame 0 costs ~40 ms of CPU (whole-frame search, the
            # thresholds, the edge model's tables of the measured width), the others 5-13 ms; at 30 FPS this was
            # measured to skip frames on a loaded machine (2 of 12 measured at load 9 on 2 cores).
            [sys.executable, "-m", "ropecam.device.cli", "run", "--source", f"frames:{frames}?fps=10",
             "--sink", f"udp://127.0.0.1:{port}", "--device-id", "7"],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert daemon.returncode == 0, daemon.stdout + daemon.stderr
        assert "measured 12 frames" in daemon.stdout
        time.sleep(1.5)  # the last datagrams reach the monitor
    except BaseException:
        monitor.kill()
        raise
    code, out, err = monitor.stop(timeout_s=30)
    assert code == 0, err + out

    exported = tmp_path / "live.jsonl"
    assert host_main(["replay", str(recording), "--export-jsonl", str(exported), "--device", "7"]) == 0
    assert device_main(["extract", str(frames), "--out", str(tmp_path / "offline.jsonl")]) == 0
    live, offline = _read_jsonl(exported), _read_jsonl(tmp_path / "offline.jsonl")
    assert [r["frame"] for r in live] == [r["frame"] for r in offline] == list(range(12))
    for got, want in zip(live, offline, strict=True):
        assert got["status"] == want["status"]
        for key in ("begin", "end"):
            assert (got[key] is None) == (want[key] is None)
            if got[key] is not None:
                # Within the sender's shape tolerance (the wire codec) and the JSON's 1/1000 px rounding.
                tolerance = SenderConfig().shape_tolerance_px + 2e-3
                assert polyline_distances_px(np.array(want[key]), np.array(got[key])).max() <= tolerance
