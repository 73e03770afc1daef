"""The live path end to end, as on the rig: `ropecam-device run` replays recorded frames paced at 30 FPS and streams
over UDP on 127.0.0.1 into `ropecam monitor --record`; the recording, replayed and exported, holds the result of
every frame the daemon measured, equal to the offline `ropecam-device extract` of the same frames (issue 6
acceptance 1 at a paced 30 FPS, issue 7 acceptance 1), and the daemon accounts for the frames it skipped."""

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
    summary = tmp_path / "device-summary.json"
    try:
        daemon = subprocess.run(
            [sys.executable, "-m", "ropecam.device.cli", "run", "--source", f"frames:{frames}?fps=30",
             "--sink", f"udp://127.0.0.1:{port}", "--device-id", "7", "--summary-json", str(summary)],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert daemon.returncode == 0, daemon.stdout + daemon.stderr
        time.sleep(1.5)  # the last datagrams reach the monitor
    except BaseException:
        monitor.kill()
        raise
    code, out, err = monitor.stop(timeout_s=30)
    assert code == 0, err + out
    # Paced as a camera, the daemon skips the frames it is late for (the first frames build tables: how many
    # depends on the machine's speed); it accounts for every frame, and always gets the last one (the newest).
    counts = json.loads(summary.read_text())
    assert counts["frames"] == 12 and counts["dropped"] == 0
    assert counts["measured"] + counts["skipped"] == 12 and counts["measured"] >= 1
    assert f"measured {counts['measured']} of 12 frames" in daemon.stdout

    exported = tmp_path / "live.jsonl"
    assert host_main(["replay", str(recording), "--export-jsonl", str(exported), "--device", "7"]) == 0
    live = _read_jsonl(exported)
    numbers = [r["frame"] for r in live]
    assert len(numbers) == counts["measured"] and numbers == sorted(set(numbers)) and numbers[-1] == 11
    # The offline reference sees the same frames as the daemon did (a frame set of those frames only, with their
    # recorded times): the pipeline's state after a skipped frame is then the same.
    measured = tmp_path / "measured"
    measured.mkdir()
    (measured / "frameset.json").write_text((frames / "frameset.json").read_text())
    header, *rows = (frames / "index.csv").read_text().splitlines()
    kept = [row for row in rows if int(row.split(",")[0]) in numbers]
    (measured / "index.csv").write_text("\n".join([header, *kept]) + "\n")
    (measured / "frames").symlink_to(frames / "frames")
    assert device_main(["extract", str(measured), "--out", str(tmp_path / "offline.jsonl")]) == 0
    offline = _read_jsonl(tmp_path / "offline.jsonl")
    assert [r["frame"] for r in offline] == numbers
    for got, want in zip(live, offline, strict=True):
        assert got["status"] == want["status"]
        for key in ("begin", "end"):
            assert (got[key] is None) == (want[key] is None)
            if got[key] is not None:
                # Within the sender's shape tolerance (the wire codec) and the JSON's 1/1000 px rounding.
                tolerance = SenderConfig().shape_tolerance_px + 2e-3
                assert polyline_distances_px(np.array(want[key]), np.array(got[key])).max() <= tolerance
