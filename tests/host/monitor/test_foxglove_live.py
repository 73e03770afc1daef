"""`ropecam monitor --foxglove`: a Foxglove WebSocket client sees the live channels of a simulated device."""

from __future__ import annotations

import base64
import json
import re
import struct
import threading
import time
from pathlib import Path

import pytest

from ropecam.host.monitor.foxglove_live import parse_address
from ropecam.shared.errors import ConfigError
from ropecam.shared.transport import open_transport

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def test_address_parsing() -> None:
    assert parse_address("127.0.0.1:0") == ("127.0.0.1", 0)
    assert parse_address(":9000") == ("127.0.0.1", 9000)
    assert parse_address("localhost") == ("localhost", 8765)
    assert parse_address("[::1]:8765") == ("::1", 8765)
    with pytest.raises(ConfigError, match="HOST:PORT"):
        parse_address("127.0.0.1:x")
    with pytest.raises(ConfigError, match="65535"):
        parse_address("127.0.0.1:70000")


def test_a_busy_port_is_a_configuration_error() -> None:
    from ropecam.host.monitor.foxglove_live import FoxgloveLive

    first = FoxgloveLive("127.0.0.1", 0)
    try:
        with pytest.raises(ConfigError, match=f"--foxglove 127.0.0.1:{first.port}: cannot serve there"):
            FoxgloveLive("127.0.0.1", first.port)
    finally:
        first.close()


def test_a_foxglove_client_receives_the_live_scenes(
    monitor_process, sim_device, send_paced, udp_port: int, tmp_path: Path
) -> None:
    from google.protobuf import descriptor_pool, message_factory
    from google.protobuf.descriptor_pb2 import FileDescriptorSet
    from websockets.sync.client import connect

    from ropecam.host.calibration.files import write_plane
    from ropecam.host.sim.rig_polylines import RIG_CAMERA, RIG_PLANE

    plane = write_plane(tmp_path / "plane.yaml", RIG_CAMERA, RIG_PLANE)
    monitor = monitor_process(["--source", f"udp://127.0.0.1:{udp_port}", "--foxglove", "127.0.0.1:0",
                               "--plane", str(plane), "--no-ui", "--duration-s", "120"])  # fmt: skip
    url = re.search(r"Foxglove live view at (ws://127\.0\.0\.1:\d+)", monitor.stderr_path.read_text()).group(1)
    channels: dict[int, dict] = {}
    received: dict[str, list[bytes]] = {}
    with connect(url, subprotocols=SUBPROTOCOLS, max_size=None) as client:
        assert json.loads(client.recv(timeout=30))["op"] == "serverInfo"
        # the simulated device (as `ropecam sim-device`): 1 s of its stream at 119 FPS over UDP, from a thread
        link = open_transport(f"udp://127.0.0.1:{udp_port}")
        messages = [data for _, data in sim_device.messages(119, start_t_ns=time.time_ns())]
        device = threading.Thread(target=send_paced, args=(link, messages))
        device.start()
        try:
            quiet_since = None
            while True:
                try:
                    frame = client.recv(timeout=0.5)
                except TimeoutError:
                    if device.is_alive():
                        continue
                    quiet_since = quiet_since or time.monotonic()
                    if time.monotonic() - quiet_since > 1.5:  # the device is done and nothing more arrives
                        break
                    continue
                quiet_since = None
                if isinstance(frame, str):
                    message = json.loads(frame)
                    if message["op"] == "advertise":
                        for channel in message["channels"]:
                            channels[channel["id"]] = channel
                        subscriptions = [{"id": c["id"], "channelId": c["id"]} for c in message["channels"]]
                        client.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
                    elif message["op"] == "status" and "Unknown channel ID" in message["message"]:
                        # foxglove-sdk 0.30 may refuse a subscription that follows its advertisement within
                        # microseconds (the channel is not registered yet); a client asks again, as the app would
                        channel_id = int(message["message"].rsplit(":", 1)[1])
                        time.sleep(0.05)
                        subscriptions = [{"id": channel_id, "channelId": channel_id}]
                        client.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
                    continue
                opcode, subscription, _log_time_ns = struct.unpack_from("<BIQ", frame)
                assert opcode == 1
                received.setdefault(channels[subscription]["topic"], []).append(frame[13:])
        finally:
            device.join()
            link.close()
    code, out, err = monitor.stop()
    assert code == 0, err + out

    topics = {c["topic"]: c for c in channels.values()}
    expected = {"/device7/image/scene", "/device7/plane/scene", "/device7/image/material_points",
                "/device7/plane/material_points", "/tf", "/log", "/device7/status"}  # fmt: skip
    assert expected <= set(topics)
    assert "/ropecam/wire" not in topics
    scenes = received.get("/device7/image/scene", []) + received.get("/device7/plane/scene", [])
    counts = {topic: len(messages) for topic, messages in received.items()}
    assert len(scenes) >= 60, counts
    # the advertised schema decodes the messages: official protobuf SceneUpdate in the plane frame
    channel = topics["/device7/plane/scene"]
    assert (channel["encoding"], channel["schemaName"], channel["schemaEncoding"]) == (
        "protobuf", "foxglove.SceneUpdate", "protobuf"
    )  # fmt: skip
    pool = descriptor_pool.DescriptorPool()
    for file in FileDescriptorSet.FromString(base64.b64decode(channel["schema"])).file:
        pool.Add(file)
    scene_class = message_factory.GetMessageClass(pool.FindMessageTypeByName("foxglove.SceneUpdate"))
    scene = scene_class.FromString(received["/device7/plane/scene"][-1])
    assert scene.entities[0].frame_id == "device7/plane" and len(scene.entities[0].lines[0].points) > 100
