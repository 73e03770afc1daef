"""`ropecam replay --frames DIR`: raw frames measured by the device pipeline go through the live path and match
the offline `ropecam-device extract` of the same frames."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.cli import main as device_main
from ropecam.host.cli import main as host_main
from ropecam.host.recording.reader import iter_raw
from ropecam.shared.protocol import polyline_distances_px


def test_replay_frames_records_and_exports_the_pipeline_results(tmp_path: Path, rig_frames: Path) -> None:
    frames = rig_frames
    recording, exported = tmp_path / "rig.mcap", tmp_path / "rig.jsonl"
    assert (
        host_main(["replay", "--frames", str(frames), "--record", str(recording), "--export-jsonl", str(exported)]) == 0
    )
    assert device_main(["extract", str(frames), "--out", str(tmp_path / "offline.jsonl"), "--quiet"]) == 0
    live = [json.loads(line) for line in exported.read_text().splitlines()]
    offline = [json.loads(line) for line in (tmp_path / "offline.jsonl").read_text().splitlines()]
    assert [r["frame"] for r in live] == [r["frame"] for r in offline] == list(range(12))
    from ropecam.shared.protocol.jsonl import DEVICE_ONLY_FIELDS

    for got, want in zip(live, offline, strict=True):
        assert set(want) - set(got) == set(DEVICE_ONLY_FIELDS) and set(got) <= set(want)  # one format
        for key in ("frame", "t_ns", "t_end_ns", "status", "method", "order_confidence"):
            assert got[key] == want[key], key
        for key in ("tips", "material_points", "stretch", "fixed_end"):
            assert (got[key] is None) == (want[key] is None), key
            if isinstance(want[key], dict):
                assert set(got[key]) == set(want[key]), key
        if want["material_points"] is not None:
            assert got["material_points"]["s_m"] == want["material_points"]["s_m"]
        for key in ("begin", "end"):
            if want[key] is not None:
                assert polyline_distances_px(np.array(want[key]), np.array(got[key])).max() <= 0.05 + 2e-3
    assert len(list(iter_raw([recording]))) == 12  # the raw messages are in the recording for exact replay


def test_replay_needs_exactly_one_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert host_main(["replay"]) == 2
    assert "either a recording" in capsys.readouterr().err
