"""The live model: rest, release detection, model channels and the model error column."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import pytest

from ropecam.host.cli import main
from ropecam.host.monitor.live_model import LiveModel
from ropecam.host.receiver import check_packet
from ropecam.host.recording.writer import Recorder, RecordingConfig
from ropecam.host.session import Session


@pytest.fixture(scope="module")
def rig_model() -> tuple:
    from ropecam.host.model.config import RopeConfig, SolverConfig
    from ropecam.host.model.solver import CableModel
    from ropecam.host.sim.rig_polylines import RIG_CAMERA, RIG_PLANE

    rope = RopeConfig(length_m=0.411)
    trajectory, _ = CableModel(rope, SolverConfig(elements=4, step_s=0.002, duration_s=0.6)).run()
    return trajectory, rope.length_m, (RIG_CAMERA, RIG_PLANE)


def test_release_is_detected_after_rest_and_the_model_follows(
    sim_device, rig_model, tmp_path: Path, read_messages
) -> None:
    trajectory, length_m, calibration = rig_model
    model = LiveModel(trajectory, length_m, calibration)
    recorder = Recorder(RecordingConfig(tmp_path / "live.mcap"))
    session = Session(recorder, calibration, model)
    start_ns, rest = time.time_ns(), 15
    for _, data in sim_device.messages(40, start_t_ns=start_ns, rest_frames=rest):
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    assert "dev7 released at" in model.describe()
    release_s = model._devices[7].overlay.release_time_s
    true_release_s = (start_ns + rest * round(1e9 / 119)) * 1e-9
    assert abs(release_s - true_release_s) < 0.02  # within about two frame periods
    errors = [d for t, _, _, d in read_messages(tmp_path / "live.mcap") if t == "/device7/model_error"]
    assert 20 <= len(errors) <= 40 - rest  # only frames after the release (a few used to detect it)
    first_swing = errors[: len(sim_device.frames) - 5]  # the fixture cycles through 12 frames of the swing
    assert [e["frame_index"] for e in first_swing] == sorted(e["frame_index"] for e in first_swing)
    distances = [p[k] for e in first_swing for p in e["points"] for k in ("error_begin_mm", "error_end_mm") if k in p]
    assert (
        distances and max(distances) < 50
    )  # 46 mm  # the simulator's swing is not the ANCF rope's, but close early on
    (row,) = session.snapshot(time.time_ns())
    assert math.isfinite(row.model_error_mm)


def test_a_rope_never_at_rest_never_arms(sim_device, rig_model) -> None:
    trajectory, length_m, calibration = rig_model
    model = LiveModel(trajectory, length_m, calibration)
    session = Session(None, calibration, model)
    for _, data in sim_device.messages(30, start_t_ns=time.time_ns()):  # swinging from the first frame
        session.handle(check_packet(data, time.time_ns()))
    assert "dev7 waiting for the rope at rest" in model.describe()
    assert math.isnan(session.snapshot(time.time_ns())[0].model_error_mm)


def test_model_option_needs_the_plane(tmp_path: Path, capsys) -> None:
    (tmp_path / "rope.toml").write_text("[rope]\nlength_m = 0.411\n")
    assert main(["monitor", "--source", "loop://", "--model", str(tmp_path / "rope.toml"), "--duration-s", "0.1"]) == 2
    assert "--model needs --plane" in capsys.readouterr().err


def test_no_model_error_for_frames_not_ok_or_past_the_end_of_the_model(sim_device, rig_model) -> None:
    import dataclasses

    from ropecam.host.model_overlay import ModelOverlay
    from ropecam.shared.protocol.records import FrameStatus

    trajectory, length_m, calibration = rig_model  # 0.6 s of model
    overlay = ModelOverlay(trajectory, 10.0, length_m, (0.2, length_m), calibration)  # released at 10 s

    def frame(start_s: float, status: FrameStatus = FrameStatus.OK):
        start_ns = round(start_s * 1e9)
        return dataclasses.replace(sim_device.frames[0], exposure_start_t_ns=start_ns,
                                   exposure_end_t_ns=start_ns + 4_000_000, status=status)  # fmt: skip

    begin, end = overlay.frame_errors_mm(frame(10.1))
    assert all(e is not None for e in begin + end)
    assert overlay.frame_errors_mm(frame(10.1, FrameStatus.LOST_TRACK)) == ([None, None], [None, None])
    begin, end = overlay.frame_errors_mm(frame(10.598))  # the exposure ends after the model's last sample
    assert all(e is not None for e in begin) and end == [None, None]
    assert overlay.frame_errors_mm(frame(11.0)) == ([None, None], [None, None])
    topics = {topic: json.loads(data) for topic, data, _, _ in overlay.messages(frame(11.0), 7, 0)}
    error = topics["/device7/model_error"]
    assert "model_time_begin_s" not in error and "model_time_end_s" not in error
    assert all(set(point) == {"s_m"} for point in error["points"])
    assert topics["/device7/plane/model"]["entities"][0]["lines"] == []  # no model rope drawn past its end
