"""Recorder durability: SIGKILL + recover, disk full, unwritable paths, rolling; replay reproduces live results."""

from __future__ import annotations

import errno
import io
import os
import signal
import time
from pathlib import Path

import pytest

from ropecam.host.cli import main
from ropecam.host.receiver import check_packet
from ropecam.host.recording.reader import iter_raw, recording_parts
from ropecam.host.recording.recover import recover_mcap
from ropecam.host.recording.writer import Recorder, RecordingConfig, part_path
from ropecam.host.replay import replay
from ropecam.host.session import RAW_TOPIC, Session
from ropecam.shared.errors import ConfigError, DataError, UsageError
from ropecam.shared.transport import open_transport


def _messages(sim_device, count: int) -> list[bytes]:
    return [data for _, data in sim_device.messages(count, start_t_ns=time.time_ns())]


def test_sigkill_while_recording_then_recover_keeps_all_but_the_last_second(
    sim_device,
    tmp_path: Path,
    udp_port: int,
    monitor_process,
    send_paced,
    read_mcap,
) -> None:
    path = tmp_path / "killed.mcap"
    monitor = monitor_process(["--source", f"udp://127.0.0.1:{udp_port}?listen=1", "--record", str(path)])
    messages = _messages(sim_device, 300)
    with open_transport(f"udp://127.0.0.1:{udp_port}") as link:
        send_times = send_paced(link, messages, fps=119.0)
    killed_at = time.monotonic()
    os.kill(monitor.process.pid, signal.SIGKILL)
    monitor.finish()
    with pytest.raises(DataError, match="recover"):
        list(iter_raw([path]))  # the cut file has no summary: indexed reading fails with a hint
    fixed = tmp_path / "fixed.mcap"
    report = recover_mcap(path, fixed)
    assert not report.complete
    raw = [data for topic, _, _, data in read_mcap(fixed) if topic == RAW_TOPIC]
    assert raw == messages[: len(raw)]  # an exact, ordered prefix
    must_have = sum(1 for t in send_times if t < killed_at - 1.0)
    assert len(raw) >= must_have, f"recovered {len(raw)} messages, {must_have} were sent more than 1 s before the kill"
    assert any(topic == "/device7/image/scene" for topic, *_ in read_mcap(fixed))


@pytest.mark.parametrize("stop_signal", [signal.SIGTERM, signal.SIGINT])
def test_sigterm_and_ctrl_c_close_the_recording_properly(
    stop_signal: signal.Signals,
    sim_device,
    tmp_path: Path,
    udp_port: int,
    monitor_process,
    read_mcap,
) -> None:
    path = tmp_path / "term.mcap"
    monitor = monitor_process(["--source", f"udp://127.0.0.1:{udp_port}?listen=1", "--record", str(path)])
    messages = _messages(sim_device, 20)
    with open_transport(f"udp://127.0.0.1:{udp_port}") as link:
        for data in messages:
            link.send(data)
            time.sleep(0.002)
    time.sleep(0.3)
    monitor.process.send_signal(stop_signal)
    code, out, err = monitor.finish()
    assert code == 0, err
    assert "final: dev7" in out and "recorded" in out
    assert ("stopped by Ctrl-C" if stop_signal == signal.SIGINT else "stopped by SIGTERM") in err
    raw = [data for topic, _, _, data in read_mcap(path) if topic == RAW_TOPIC]  # complete file: indexed read works
    assert raw == messages


def test_ctrl_c_still_records_every_packet_already_received(tmp_path: Path, read_mcap) -> None:
    from ropecam.host.monitor.cli import StopSignals, monitor_loop
    from ropecam.host.receiver import Receiver
    from ropecam.shared.protocol.records import Log
    from ropecam.shared.protocol.wire import encode_message
    from ropecam.shared.transport.loop import LoopTransport

    device, host = LoopTransport.pair()
    messages = [encode_message(Log(level=20, text=f"m{i}"), device_id=1, sequence=i, t_ns=i) for i in range(500)]
    for data in messages:
        device.send(data)
    session = Session(Recorder(RecordingConfig(tmp_path / "int.mcap")))
    receiver = Receiver(host)
    checks = []
    before = signal.getsignal(signal.SIGINT)  # default_int_handler, or SIG_IGN under a background job
    with StopSignals() as stop:

        def should_stop() -> bool:
            checks.append(1)
            if len(checks) == 10:
                signal.raise_signal(signal.SIGINT)  # Ctrl-C with hundreds of packets still queued
            return stop.requested()

        monitor_loop(receiver, session, None, None, should_stop)
    session.close()
    assert stop.signal_name == "SIGINT" and len(checks) == 10
    assert signal.getsignal(signal.SIGINT) is before  # the previous handler is back
    raw = [data for topic, _, _, data in read_mcap(tmp_path / "int.mcap") if topic == RAW_TOPIC]
    assert raw == messages


class FailingFile(io.FileIO):
    """A real file that fails with ENOSPC once `limit` bytes have been written (a disk filling up)."""

    def __init__(self, path: Path, limit: int) -> None:
        super().__init__(path, "w")
        self.limit = limit
        self.written = 0

    def write(self, data) -> int:
        if self.written + len(data) > self.limit:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.written += len(data)
        return super().write(data)


def test_disk_full_stops_recording_with_a_clear_error_and_keeps_what_was_flushed(
    sim_device,
    tmp_path: Path,
    read_mcap,
) -> None:
    path = tmp_path / "full.mcap"
    recorder = Recorder(
        RecordingConfig(path, flush_s=0.01), opener=lambda p, overwrite: io.BufferedWriter(FailingFile(p, 60_000))
    )
    session = Session(recorder)
    messages = _messages(sim_device, 150)
    flushed_when_failed = None
    for data in messages:
        session.handle(check_packet(data, time.time_ns()))
        time.sleep(0.002)
        session.tick()
        if recorder.error and flushed_when_failed is None:
            flushed_when_failed = recorder.flushed_messages
    assert recorder.error is not None and "No space left on device" in recorder.error
    assert "ropecam recover" in recorder.error and str(path) in recorder.error
    assert recorder.unrecorded > 0 and not recorder.active
    (row,) = session.snapshot(time.time_ns())
    assert row.received == len(messages)  # monitoring went on
    session.close()  # no exception after the failure
    report = recover_mcap(path, tmp_path / "fixed.mcap")
    assert report.messages == flushed_when_failed > 0


def test_unwritable_paths(sim_device, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot create recording file"):
        Recorder(RecordingConfig(tmp_path / "missing-dir" / "x.mcap"))
    (tmp_path / "exists.mcap").write_bytes(b"precious")
    with pytest.raises(ConfigError, match="exists"):
        Recorder(RecordingConfig(tmp_path / "exists.mcap"))
    assert (tmp_path / "exists.mcap").read_bytes() == b"precious"
    with pytest.raises(ConfigError, match="No space left"):  # a disk already full at the start
        Recorder(RecordingConfig(tmp_path / "full.mcap"), opener=lambda p, o: io.BufferedWriter(FailingFile(p, 10)))
    assert not (tmp_path / "full.mcap").exists()

    def opener(path: Path, overwrite: bool):
        if path != tmp_path / "roll.mcap":
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return open(path, "xb")

    # the path becomes unwritable when the recording rolls to its second file
    recorder = Recorder(RecordingConfig(tmp_path / "roll.mcap", roll_bytes=20_000), opener=opener)
    session = Session(recorder)
    for data in _messages(sim_device, 60):
        session.handle(check_packet(data, time.time_ns()))
        recorder._last_flush = 0.0  # flush on every tick
        session.tick()
    assert recorder.error is not None and "Permission denied" in recorder.error
    assert "roll_001.mcap" in recorder.error
    assert session.snapshot(time.time_ns())[0].received == 60 + 1  # monitoring went on (60 frames and a Log)
    assert len(list(iter_raw([tmp_path / "roll.mcap"]))) > 0  # the first part was closed properly


@pytest.mark.parametrize("roll", [{"roll_bytes": 3_000}, {"roll_s": 0.01}])
def test_rolled_recording_replays_across_parts(sim_device, tmp_path: Path, roll: dict) -> None:
    path = tmp_path / "part.mcap"
    recorder = Recorder(RecordingConfig(path, **roll))
    session = Session(recorder)
    messages = _messages(sim_device, 50)
    for data in messages:
        session.handle(check_packet(data, time.time_ns()), decode=False)
        recorder._last_flush = 0.0
        time.sleep(0.001)
        session.tick()
    for _ in range(3):  # idle time: no empty parts
        time.sleep(0.02)
        recorder._last_flush = 0.0
        session.tick()
    session.close()
    parts = recording_parts(path)
    assert all(list(iter_raw([part])) for part in parts)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*(p.name for p in parts), "part.layout.json"])
    assert len(parts) >= 3 and parts[1] == part_path(path, 1)
    assert [data for data, _ in iter_raw(parts)] == messages


def _record(path: Path, tag: bytes, count: int, roll_s: float, overwrite: bool = False) -> list[Path]:
    from ropecam.host.recording.wire import LEGACY_ENCODING as RAW_ENCODING

    recorder = Recorder(RecordingConfig(path, roll_s=roll_s, overwrite=overwrite))
    for i in range(count):
        recorder.write(RAW_TOPIC, tag + bytes([i]), time.time_ns(), None, RAW_ENCODING)
        recorder._part_started = 0.0 if roll_s else recorder._part_started  # roll at every tick
        recorder.tick()
    recorder.close()
    return recorder.parts


def test_parts_of_an_earlier_recording_are_refused_or_deleted_never_mixed_in(tmp_path: Path) -> None:
    from ropecam.host.recording.writer import read_part_id

    path = tmp_path / "run.mcap"
    old = _record(path, b"OLD", 4, roll_s=1.0)
    assert len(old) == 4 and [read_part_id(p)[1] for p in old] == [0, 1, 2, 3]
    assert len({read_part_id(p)[0] for p in old}) == 1  # one id for all parts
    path.unlink()
    with pytest.raises(ConfigError, match=r"run_001\.mcap \(and 2 more\) exists.*--force"):
        Recorder(RecordingConfig(path, roll_s=1.0))  # a leftover part would stop the recording at its first roll
    assert not path.exists()
    new = _record(path, b"NEW", 2, roll_s=0.0, overwrite=True)
    assert sorted(tmp_path.iterdir()) == new == [path]  # the old parts were deleted
    assert {data[:3] for data, _ in iter_raw(recording_parts(path))} == {b"NEW"}


def test_replay_refuses_a_part_of_another_recording(tmp_path: Path) -> None:
    first = _record(tmp_path / "a.mcap", b"AAA", 2, roll_s=1.0)
    other = _record(tmp_path / "b.mcap", b"BBB", 2, roll_s=1.0)
    other[1].replace(first[1])  # b_001.mcap copied over a_001.mcap by hand
    with pytest.raises(DataError, match=r"a_001\.mcap does not belong to the recording .*a\.mcap.*part 1"):
        recording_parts(first[0])


def test_replay_reproduces_the_live_decoded_results_exactly(
    sim_device,
    tmp_path: Path,
    udp_port: int,
    monitor_process,
    send_paced,
    read_mcap,
) -> None:
    live = tmp_path / "live.mcap"
    monitor = monitor_process(
        [
            "--source",
            f"udp://127.0.0.1:{udp_port}?listen=1",
            "--record",
            str(live),
            "--duration-s",
            "4",
            "--decode",
            "all",
        ]
    )
    messages = _messages(sim_device, 130)
    damaged = bytearray(messages[50])
    damaged[25] ^= 1
    messages.insert(51, bytes(damaged))
    with open_transport(f"udp://127.0.0.1:{udp_port}") as link:
        send_paced(link, messages, fps=119.0)
    code, out, err = monitor.finish()
    assert code == 0, err
    lines = [line for line in out.splitlines() if line.startswith("t=")]
    assert len(lines) >= 3  # one line per second
    replayed = tmp_path / "replayed.mcap"
    assert main(["replay", str(live), "--record", str(replayed)]) == 0
    live_records = [r for r in read_mcap(live)]
    replay_records = read_mcap(replayed)
    assert len([r for r in live_records if r[0] == "/device7/image/scene"]) == 130  # nothing skipped live
    assert sorted(live_records) == sorted(replay_records)

    # the statistics too: a second replay in process against the live statistics from the monitor's output
    session = Session()
    assert replay([live], session) == len(messages)
    (row,) = session.snapshot(session.stats.last_receive_t_ns)
    assert (row.received, row.crc_errors, row.lost) == (130 + 1 + 1, 1, 0)
    final = next(line for line in out.splitlines() if line.startswith("final: "))
    assert f"rx {row.received} lost 0" in final and "bad 1" in final


def test_recover_refuses_non_mcap_and_reports_complete_files(tmp_path: Path, sim_device, capsys) -> None:
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file at all")
    with pytest.raises(DataError, match="not an MCAP file"):
        recover_mcap(tmp_path / "junk.mcap", tmp_path / "out.mcap")
    recorder = Recorder(RecordingConfig(tmp_path / "ok.mcap"))
    session = Session(recorder)
    for data in _messages(sim_device, 5):
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    report = recover_mcap(tmp_path / "ok.mcap", tmp_path / "copy.mcap")
    assert report.complete and report.messages == recorder.messages
    assert main(["recover", str(tmp_path / "ok.mcap"), "--out", str(tmp_path / "cli.mcap")]) == 0
    assert f"wrote {recorder.messages} messages" in capsys.readouterr().out
    with pytest.raises(UsageError, match="exists"):
        recover_mcap(tmp_path / "ok.mcap", tmp_path / "copy.mcap")


def test_recover_onto_a_full_disk_is_a_data_error_and_leaves_no_file(
    tmp_path: Path, sim_device, monkeypatch: pytest.MonkeyPatch
) -> None:
    import builtins

    from ropecam.host.recording import recover

    recorder = Recorder(RecordingConfig(tmp_path / "ok.mcap"))
    session = Session(recorder)
    for data in _messages(sim_device, 5):
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    full = tmp_path / "full.mcap"

    def open_on_a_full_disk(path, mode="r", *args, **kwargs):
        return FailingFile(Path(path), limit=200) if Path(path) == full else builtins.open(path, mode, *args, **kwargs)

    monkeypatch.setattr(recover, "open", open_on_a_full_disk, raising=False)
    with pytest.raises(DataError, match=r"recovering .*ok\.mcap into .*full\.mcap failed: No space left.*unchanged"):
        recover_mcap(tmp_path / "ok.mcap", full)
    assert not full.exists() and (tmp_path / "ok.mcap").stat().st_size > 0


def test_replay_reprocess_with_a_calibration_adds_the_plane_channels(sim_device, tmp_path: Path, read_mcap) -> None:
    from ropecam.host.calibration.files import write_plane
    from ropecam.host.sim.rig_polylines import RIG_CAMERA, RIG_PLANE

    recorder = Recorder(RecordingConfig(tmp_path / "raw.mcap"))
    session = Session(recorder)
    for data in _messages(sim_device, 4):
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    plane = write_plane(tmp_path / "plane.yaml", RIG_CAMERA, RIG_PLANE)
    out = tmp_path / "metres.mcap"
    assert main(["replay", str(tmp_path / "raw.mcap"), "--reprocess", "--plane", str(plane), "--record", str(out)]) == 0
    topics = [topic for topic, *_ in read_mcap(out)]
    assert topics.count("/device7/plane/scene") == 4
    assert main(["replay", str(tmp_path / "raw.mcap"), "--reprocess"]) == 2  # names what is missing


def test_replay_exports_extract_json_lines_for_ropecam_compare(sim_device, tmp_path: Path, capsys) -> None:
    from ropecam.host.compare.measurement import read_extract_jsonl
    from ropecam.shared.protocol import FrameResult, decode_message

    recorder = Recorder(RecordingConfig(tmp_path / "run.mcap"))
    session = Session(recorder)
    messages = _messages(sim_device, 6)
    for data in messages:
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    out = tmp_path / "run.jsonl"
    assert main(["replay", str(tmp_path / "run.mcap"), "--export-jsonl", str(out)]) == 0
    assert "exported 6 frames of device 7" in capsys.readouterr().out
    frames = read_extract_jsonl(out)
    records = [r for r in (decode_message(m).record for m in messages) if isinstance(r, FrameResult)]
    assert [f.t_begin_ns for f in frames] == [r.exposure_start_t_ns for r in records]
    for frame, record in zip(frames, records, strict=True):
        assert frame.t_end_ns == record.exposure_end_t_ns
        assert frame.begin_px.tolist() == record.begin_px.tolist() and frame.end_px.tolist() == record.end_px.tolist()
    assert main(["replay", str(tmp_path / "run.mcap"), "--export-jsonl", str(out)]) == 2  # never overwrites silently


def test_replay_with_a_model_records_the_model_rope_and_its_error(
    sim_device, tmp_path: Path, read_messages, capsys
) -> None:
    import jsonschema
    import numpy as np

    from ropecam.host.calibration.files import write_plane
    from ropecam.host.recording.schemas import json_schema
    from ropecam.host.sim.rig_polylines import RIG_CAMERA, RIG_PLANE

    recorder = Recorder(RecordingConfig(tmp_path / "run.mcap"))
    session = Session(recorder)
    for data in _messages(sim_device, 12):
        session.handle(check_packet(data, time.time_ns()), decode=False)
    session.close()
    plane = write_plane(tmp_path / "plane.yaml", RIG_CAMERA, RIG_PLANE)
    rope = tmp_path / "rope.toml"
    rope.write_text("[rope]\nlength_m = 0.411\n[solver]\nelements = 4\nstep_s = 0.002\n")
    out = tmp_path / "model.mcap"
    args = ["replay", str(tmp_path / "run.mcap"), "--plane", str(plane), "--model", str(rope), "--record", str(out)]
    assert main(args) == 0
    assert "release at" in capsys.readouterr().err
    records = read_messages(out)
    errors = [d for t, _, _, d in records if t == "/device7/model_error"]
    scenes = [d for t, _, _, d in records if t == "/device7/plane/model"]
    assert len(errors) == len(scenes) == 12
    for error in errors:
        jsonschema.validate(error, json_schema("ropecam.ModelError"))
        assert [p["s_m"] for p in error["points"]] == pytest.approx([0.411 * f for f in (0.25, 0.5, 0.75, 1.0)])
    model_rope = scenes[0]["entities"][0]["lines"][0]["points"]
    xy = np.array([[p["x"], p["y"]] for p in model_rope])
    assert np.hypot(*xy[0]) < 1e-6  # pinned at the plane origin, like the measured rope
    assert np.sum(np.hypot(*np.diff(xy, axis=0).T)) == pytest.approx(0.411, rel=0.01)
    # the model's swing is not the simulator's curve, but it follows it: errors of centimetres, not metres
    finite = [p[k] for e in errors for p in e["points"] for k in ("error_begin_mm", "error_end_mm") if k in p]
    assert finite and max(finite) < 100  # 79 mm at the tip late in the swing
    assert main(["replay", str(tmp_path / "run.mcap"), "--model", str(rope)]) == 2  # needs --plane and --record

    # `ropecam compare` on the exported frames fits the same release time and gets the same errors
    from ropecam.host.compare.run import compare_recording

    assert main(["replay", str(tmp_path / "run.mcap"), "--export-jsonl", str(tmp_path / "run.jsonl")]) == 0
    numbers = compare_recording(tmp_path / "run.jsonl", plane, tmp_path / "report", model_path=rope, verbose=False)
    assert errors[0]["release_time_s"] == pytest.approx(numbers["release_time_s"], abs=1e-9)
    assert np.sqrt(np.mean(np.square(finite))) == pytest.approx(numbers["overall_rms_error_mm"], abs=1e-3)


def test_replay_that_fails_leaves_no_output_file(tmp_path: Path, capsys) -> None:
    from ropecam.host.calibration.files import write_plane
    from ropecam.host.recording.wire import LEGACY_ENCODING as RAW_ENCODING
    from ropecam.host.sim.rig_polylines import RIG_CAMERA, RIG_PLANE
    from ropecam.shared.protocol.records import Log
    from ropecam.shared.protocol.wire import encode_message

    with Recorder(RecordingConfig(tmp_path / "logs.mcap")) as recorder:  # no FrameResult: nothing to fit
        recorder.write(
            RAW_TOPIC, encode_message(Log(level=20, text="hi"), device_id=1, sequence=0, t_ns=0), 0, None, RAW_ENCODING
        )
    plane = write_plane(tmp_path / "plane.yaml", RIG_CAMERA, RIG_PLANE)
    rope = tmp_path / "rope.toml"
    rope.write_text("[rope]\nlength_m = 0.411\n[solver]\nelements = 4\nstep_s = 0.002\n")
    out, jsonl = tmp_path / "out.mcap", tmp_path / "out.jsonl"
    model = ["--plane", str(plane), "--model", str(rope)]
    assert (
        main(["replay", str(tmp_path / "logs.mcap"), *model, "--record", str(out), "--export-jsonl", str(jsonl)]) == 1
    )  # a runtime error: the data holds nothing to fit
    assert "holds no FrameResult" in capsys.readouterr().err
    assert not out.exists() and not jsonl.exists()
    unwritable = str(tmp_path / "missing" / "out.mcap")
    assert main(["replay", str(tmp_path / "logs.mcap"), "--record", unwritable, "--export-jsonl", str(jsonl)]) == 2
    assert "cannot create recording file" in capsys.readouterr().err
    assert not jsonl.exists()


def test_replay_speed_paces_by_the_recorded_receive_times(sim_device, tmp_path: Path) -> None:
    recorder = Recorder(RecordingConfig(tmp_path / "paced.mcap"))
    session = Session(recorder)
    t0 = time.time_ns()
    for k, data in enumerate(_messages(sim_device, 5)):
        session.handle(check_packet(data, t0 + k * 100_000_000), decode=False)  # received 0.1 s apart
    session.close()
    parts = [tmp_path / "paced.mcap"]
    start = time.monotonic()
    assert replay(parts, Session(), speed=2.0) == 6
    assert time.monotonic() - start >= 0.5 / 2.0 - 0.01  # 0.5 s of recording at twice the speed (a lower bound)


def test_model_frames_of_a_device_that_restarted_are_all_kept_duplicates_once() -> None:
    import numpy as np

    from ropecam.host.recording.reader import device_frames
    from ropecam.shared.protocol.records import FrameResult
    from ropecam.shared.protocol.wire import encode_message

    shape = np.array([[10.0, 10.0], [10.0, 50.0]])
    messages = []
    for run_start_ns in (1_000_000_000, 5_000_000_000):  # the device restarts: sequence and frame index from 0
        for k in range(4):
            t_ns = run_start_ns + k * 10_000_000
            record = FrameResult(k, t_ns, t_ns + 4_000_000, begin_px=shape, end_px=shape)
            messages.append((encode_message(record, device_id=3, sequence=k, t_ns=t_ns), t_ns))
    messages.append(messages[2])  # received twice
    frames, device_id = device_frames(messages)
    assert device_id == 3
    assert [f.exposure_start_t_ns for f in frames] == sorted({t for _, t in messages})
    assert len(frames) == 8
    assert device_frames(messages, device_id=4) == ([], 4)


def test_monitor_process_reports_a_monitor_that_cannot_start(udp_port: int) -> None:
    from ropecam.host.monitor.process import MonitorProcess
    from ropecam.shared.errors import RopecamError

    with pytest.raises(RopecamError, match=r"stopped at once \(2\)[\s\S]*--duration-s must be > 0"):
        MonitorProcess(["--source", f"udp://127.0.0.1:{udp_port}?listen=1", "--duration-s", "-1"])
    monitor = MonitorProcess(["--source", f"udp://127.0.0.1:{udp_port}?listen=1", "--no-ui"], start_timeout_s=60)
    code, _, err = monitor.stop()
    assert code == 0 and "receiving on" in err and "stopped by SIGTERM" in err


def test_the_stop_handlers_are_in_place_when_the_ready_line_appears(
    udp_port: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A SIGTERM sent as soon as "receiving on" appears (MonitorProcess.stop, a service manager) must stop the monitor
    # cleanly: the handler that turns it into a stop request is installed before that line is written (CI at load 16
    # killed a monitor whose handler came after it: exit -15).
    from ropecam.host.monitor.cli import StopSignals

    seen: list[object] = []

    class Stderr(io.StringIO):
        def write(self, text: str) -> int:
            if "receiving on" in text:
                seen.append(signal.getsignal(signal.SIGTERM))
            return super().write(text)

    monkeypatch.setattr("sys.stderr", Stderr())
    before = signal.getsignal(signal.SIGTERM)
    assert main(["monitor", "--source", f"udp://127.0.0.1:{udp_port}?listen=1", "--no-ui", "--duration-s", "0.1"]) == 0
    assert len(seen) == 1 and isinstance(getattr(seen[0], "__self__", None), StopSignals), seen
    assert signal.getsignal(signal.SIGTERM) is before  # restored
