"""Receiver, statistics, decoded channels and their Foxglove schemas, in process over loop:// and UDP."""

from __future__ import annotations

import time
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from ropecam.host.monitor.cli import monitor_loop
from ropecam.host.receiver import Receiver, check_packet, summarize_frame
from ropecam.host.recording.schemas import json_schema
from ropecam.host.recording.writer import Recorder, RecordingConfig
from ropecam.host.session import RAW_TOPIC, Session
from ropecam.shared.protocol import FrameResult, decode_message, polyline_distances_px
from ropecam.shared.transport import open_transport
from ropecam.shared.transport.loop import LoopTransport


def test_check_packet_sorts_good_crc_damaged_and_garbage(sim_device) -> None:
    _, good = next(m for m in sim_device.messages(2) if m[1][3] == 1)
    assert check_packet(good, 5).ok
    damaged = bytearray(good)
    damaged[30] ^= 0x40
    bad = check_packet(bytes(damaged), 5)
    assert not bad.ok and bad.crc_error and bad.header is not None and "CRC" in bad.error
    garbage = check_packet(b"\x00" * 40, 5)
    assert garbage.header is None and "magic" in garbage.error


def test_frame_summary_matches_the_full_decode(sim_device) -> None:
    for _, data in sim_device.messages(5):
        packet = check_packet(data, 0)
        summary = summarize_frame(packet)
        record = decode_message(data).record
        if not isinstance(record, FrameResult):
            assert summary is None
            continue
        assert summary.frame_index == record.frame_index
        assert summary.exposure_start_t_ns == record.exposure_start_t_ns
        assert summary.exposure_end_t_ns == record.exposure_end_t_ns
        assert summary.pipeline_us == record.pipeline_us
        assert summary.order_confidence == pytest.approx(record.order_confidence, abs=1e-12)


def _stream(sim_device, count: int) -> list[bytes]:
    return [data for _, data in sim_device.messages(count, start_t_ns=time.time_ns())]


def test_loss_duplicates_reordering_and_bad_packets_are_counted_never_fatal(sim_device) -> None:
    messages = _stream(sim_device, 30)
    # drop two, duplicate one, swap two, insert garbage and a CRC-damaged copy
    sent = messages[:5] + messages[6:8] + [messages[9], messages[8]] + messages[10:12] + [messages[11]] + messages[13:]
    damaged = bytearray(messages[4])
    damaged[-1] ^= 0xFF
    sent = [*sent[:3], b"RC\tgarbage", bytes(damaged), *sent[3:]]
    device, host = LoopTransport.pair()
    session = Session()
    receiver = Receiver(host)
    for data in sent:
        assert device.send(data)
    while (packet := receiver.poll(0.0)) is not None:
        session.handle(packet)
    (row,) = session.snapshot(time.time_ns())
    assert row.device_id == 7
    assert abs(row.latency_ms) < 1000  # shown: the simulated device stamps with the host wall clock
    assert (row.lost, row.duplicates, row.reordered) == (2, 1, 1)
    assert row.crc_errors == 1
    assert session.stats.bad_packets == 1
    assert any(w.startswith("LOSS +2") for w in row.warnings)
    assert row.tip_px is not None and row.order_confidence == pytest.approx(0.9, abs=1e-4)
    assert 2400 <= row.pipeline_p50_us <= 3000


@pytest.mark.parametrize("url", ["loop://monitor-e2e", "udp"])
def test_recorded_file_holds_every_message_and_the_devices_shapes(
    sim_device,
    tmp_path: Path,
    url: str,
    udp_port: int,
    read_mcap,
    read_messages,
) -> None:
    messages = _stream(sim_device, 120)
    if url == "udp":
        host = open_transport(f"udp://127.0.0.1:{udp_port}?listen=1")
        device = open_transport(f"udp://127.0.0.1:{udp_port}")
    else:
        device, host = open_transport(url), open_transport(url)
    recorder = Recorder(RecordingConfig(tmp_path / "run.mcap"), {"rig": {"source": url}})
    session = Session(recorder)
    receiver = Receiver(host)
    for data in messages:
        assert device.send(data)
    monitor_loop(receiver, session, None, duration_s=0.5, decode_backlog=1000)
    session.close()
    host.close()
    device.close()

    records = read_mcap(tmp_path / "run.mcap")
    raw = [data for topic, _, _, data in records if topic == RAW_TOPIC]
    assert raw == messages
    frames = [decode_message(m).record for m in messages]
    frames = [r for r in frames if isinstance(r, FrameResult)]
    scenes = [d for t, s, _, d in read_messages(tmp_path / "run.mcap") if t == "/device7/image/scene"]
    assert len(scenes) == len(frames) == 120
    for scene, frame, original in zip(scenes, frames, sim_device.frames * 10, strict=True):
        lines = scene["entities"][0]["lines"]
        for line, decoded, device_points in zip(
            lines, (frame.begin_px, frame.end_px), (original.begin_px, original.end_px), strict=True
        ):
            points = np.array([[p["x"], p["y"]] for p in line["points"]])
            np.testing.assert_allclose(points, decoded, atol=2**-8)  # protobuf: 2^-7 px grid
            assert polyline_distances_px(device_points, points).max() <= 0.05 + 2**-7.5  # + half a grid step
    names = set()
    for _topic, schema_name, _, data in read_messages(tmp_path / "run.mcap"):
        if schema_name not in names and schema_name != "ropecam.WireMessage":
            jsonschema.validate(data, json_schema(schema_name))  # every message: tests/host/recording
        names.add(schema_name)
    assert names == {"foxglove.SceneUpdate", "foxglove.PointCloud", "foxglove.Log", "ropecam.Status",
                     "ropecam.WireMessage"}  # fmt: skip


def test_latency_is_hidden_when_the_device_clock_is_not_the_host_clock(sim_device) -> None:
    session = Session()
    for data in [d for _, d in sim_device.messages(5, start_t_ns=123_000_000_000)]:  # a monotonic clock
        session.handle(check_packet(data, time.time_ns()))
    (row,) = session.snapshot(time.time_ns())
    assert np.isnan(row.latency_ms) and row.rate_hz > 0


def test_plane_channels_in_metres_when_calibrated(sim_device, tmp_path: Path, read_messages) -> None:
    from ropecam.host.sim.rig_polylines import RIG_CAMERA, RIG_PLANE

    recorder = Recorder(RecordingConfig(tmp_path / "cal.mcap"))
    session = Session(recorder, (RIG_CAMERA, RIG_PLANE))
    for data in _stream(sim_device, 3):
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    (row,) = session.snapshot(time.time_ns())
    # the rope is 0.411 m long and pinned at the plane origin
    assert row.tip_plane_m is not None and 0.3 < np.hypot(*row.tip_plane_m) < 0.42
    scenes = [d for t, _, _, d in read_messages(tmp_path / "cal.mcap") if t == "/device7/plane/scene"]
    assert len(scenes) == 3
    points = scenes[0]["entities"][0]["lines"][0]["points"]
    assert scenes[0]["entities"][0]["frame_id"] == "device7/plane"
    assert abs(points[0]["x"]) < 2e-3 and abs(points[0]["y"]) < 2e-3  # fixed end at the origin


def test_serial_source_over_a_pty_with_line_noise(sim_device) -> None:
    import os
    import pty
    import threading

    from ropecam.shared.protocol import frame

    master, slave = pty.openpty()
    name = os.ttyname(slave)
    host = open_transport(f"serial://{name}?baud=921600")
    os.close(slave)
    messages = _stream(sim_device, 25)
    stream = (
        b"".join(frame(m) for m in messages[:10])
        + b"\x13\x37 line noise \xff"
        + b"".join(frame(m) for m in messages[10:])
    )

    def write() -> None:
        view = memoryview(stream)
        while view:
            written = os.write(master, view[:512])
            view = view[written:]
            time.sleep(0.002)

    writer = threading.Thread(target=write)
    writer.start()
    session = Session()
    receiver = Receiver(host)
    monitor_loop(receiver, session, None, duration_s=1.5, decode_backlog=1000)
    writer.join()
    host.close()
    os.close(master)
    (row,) = session.snapshot(time.time_ns())
    assert (row.received, row.lost) == (len(messages), 0)
    assert row.tip_px is not None


def test_frames_the_device_dropped_raise_a_warning() -> None:
    from ropecam.shared.protocol import Status, encode_message

    session = Session()
    for sequence, dropped in enumerate((0, 0, 3)):
        status = Status(119.0, 100 * sequence, dropped, 0, 4000, 0.0, sequence * 10**9)
        data = encode_message(status, device_id=2, sequence=sequence, t_ns=time.time_ns())
        session.handle(check_packet(data, time.time_ns()))
        rows = session.snapshot(time.time_ns())
    assert rows[0].device_dropped == 3 and "DEVICE DROPPED +3 frames" in rows[0].warnings
    assert session.snapshot(time.time_ns())[0].warnings == ()  # reported once


def test_self_check_failures_the_device_counted_raise_a_warning() -> None:
    from ropecam.shared.protocol import Status, encode_message

    session = Session()
    for sequence, count in enumerate((0, 2, 2, 5)):
        counters = (("frames_ok", 10 * sequence), ("check_length", count), ("check_no_blur", min(count, 1)))
        status = Status(119.0, 100 * sequence, 0, 0, 4000, 0.0, sequence * 10**9, counters=counters)
        session.handle(check_packet(encode_message(status, device_id=2, sequence=sequence, t_ns=time.time_ns()),
                                    time.time_ns()))  # fmt: skip
        warnings = session.snapshot(time.time_ns())[0].warnings
        if sequence == 1:
            assert warnings == ("CHECK length +2", "CHECK no_blur +1")
        elif sequence == 2:
            assert warnings == ()  # reported once
    assert warnings == ("CHECK length +3",)


def test_raw_frames_become_foxglove_raw_images(tmp_path: Path, read_messages) -> None:
    import base64

    from ropecam.shared.protocol import encode_message, split_frame

    image = (np.arange(40 * 30) % 251).astype(np.uint8).reshape(30, 40)
    recorder = Recorder(RecordingConfig(tmp_path / "raw.mcap"))
    session = Session(recorder)
    for sequence, chunk in enumerate(split_frame(9, image, chunk_bytes=500)):
        data = encode_message(chunk, device_id=4, sequence=sequence, t_ns=time.time_ns())
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    assert session.raw_frames == 1
    raw = read_messages(tmp_path / "raw.mcap")
    ((schema_name, message),) = [(s, d) for t, s, _, d in raw if t == "/device4/image/raw"]
    jsonschema.validate(message, json_schema(schema_name))
    assert (message["width"], message["height"], message["encoding"]) == (40, 30, "mono8")
    assert base64.b64decode(message["data"]) == image.tobytes()


def test_control_acks_count_in_the_device_sequence_and_are_not_lost() -> None:
    from ropecam.device.senders.stream import ResultSender
    from ropecam.host.monitor.stats import StreamStats
    from ropecam.shared.protocol import AckResult, Command, ControlAck, Log

    device, host = LoopTransport.pair()
    sender = ResultSender(device, 1)
    sender.submit(Log(level=20, text="a"))
    sender.submit(ControlAck(5, Command.START, AckResult.APPLIED, "ok"))
    sender.submit(Log(level=20, text="b"))
    sender.close()
    stats = StreamStats()
    while (data := host.receive(0.1)) is not None:
        assert stats.observe(check_packet(data, time.time_ns()))
    (row,) = stats.snapshot(time.time_ns())
    assert (row.received, row.lost) == (3, 0)
    assert not any(w.startswith("LOSS") for w in row.warnings)


def test_a_pixel_off_the_plane_is_counted_bad_and_never_stops_the_session(tmp_path: Path, read_mcap) -> None:
    from ropecam.host.calibration.geometry import CameraModel, PlanePose
    from ropecam.shared.protocol.wire import encode_message

    camera = CameraModel(np.array([[1000.0, 0, 512], [0, 1000.0, 272], [0, 0, 1]]), np.zeros(5), (1024, 544))
    plane = PlanePose.from_rvec([0.6, 0, 0], [0, 0, 1.0])  # tilted 34 degrees: rows far below the image miss it
    good = np.array([[500.0, 100.0], [500.0, 300.0]])
    bad = np.array([[500.0, 100.0], [500.0, 3000.0]])  # valid on the wire, its ray meets the plane behind the camera
    shapes = [good, bad, good]
    recorder = Recorder(RecordingConfig(tmp_path / "bad.mcap"))
    model_calls = []
    session = Session(recorder, (camera, plane), model=lambda record, device: model_calls.append(record) or None)
    for index, shape in enumerate(shapes):
        tip = tuple(shape[-1])
        record = FrameResult(index, index * 10_000_000, index * 10_000_000 + 4_000_000, begin_px=shape, end_px=shape,
                             begin_tip_px=tip, end_tip_px=tip)  # fmt: skip
        data = encode_message(record, device_id=1, sequence=index, t_ns=time.time_ns())
        session.handle(check_packet(data, time.time_ns()))
    session.close()
    (row,) = session.snapshot(time.time_ns())
    assert row.decode_errors == 1 and row.received == 3
    assert [r.frame_index for r in model_calls] == [0, 2]
    topics = [t for t, _, _, _ in read_mcap(tmp_path / "bad.mcap")]
    assert topics.count("/device1/image/scene") == 3 and topics.count("/device1/plane/scene") == 2
    assert topics.count(RAW_TOPIC) == 3
