"""The daemon under faults, on a fake V4L2 camera: acks that tell what really happened, camera settings and counters
that survive a camera reopen, a link that fails and comes back, and a watchdog kept alive while retrying."""

from __future__ import annotations

import logging
import time

import pytest

from ropecam.device.capture.config import CaptureConfig
from ropecam.device.capture.fake import FakeCamera, fake_factory, uvc_like_camera
from ropecam.device.daemon.config import DaemonConfig, DeviceConfig, SenderConfig
from ropecam.device.daemon.runner import EXIT_CAMERA_LOST, Daemon
from ropecam.device.daemon.systemd import Notifier
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.shared.errors import TransportError
from ropecam.shared.protocol import (
    AckResult,
    Command,
    Control,
    ControlAck,
    FrameResult,
    Signer,
    Status,
    decode_message,
    encode_message,
)
from ropecam.shared.protocol.auth import AuthConfig
from ropecam.shared.transport import open_transport
from ropecam.shared.transport.loop import LoopTransport

from .conftest import running

KEY_HEX = "00112233445566778899aabbccddeeff"
SMALL_CAMERA = "v4l2:///dev/video0?width=64&height=32&fps=119&format=GREY"


def _camera() -> FakeCamera:
    camera = uvc_like_camera()
    camera.on_wait = lambda c: c.deliver(1)
    return camera


def _config(sink: str, **daemon: float) -> DeviceConfig:
    return DeviceConfig(
        capture=CaptureConfig(source=SMALL_CAMERA, read_timeout_s=0.05),
        pipeline=PipelineConfig(rope_length_m=0.411, material_points_m=(0.1,)),
        sender=SenderConfig(sink=sink, status_period_s=0.1),
        control=AuthConfig(key_hex=KEY_HEX),
        daemon=DaemonConfig(**{"retry_initial_s": 0.05, "retry_max_s": 0.1, **daemon}),
    )


def _collect(link, seconds: float) -> list:
    messages, until = [], time.monotonic() + seconds
    while time.monotonic() < until:
        data = link.receive(0.05)
        if data is not None:
            messages.append(decode_message(data))
    return messages


def _records(messages: list, kind: type) -> list:
    return [m.record for m in messages if isinstance(m.record, kind)]


def test_acks_tell_what_the_camera_did_and_settings_survive_a_reopen() -> None:
    camera = _camera()
    host = open_transport("loop://faults-ack")
    signer = Signer(bytes.fromhex(KEY_HEX))
    daemon = Daemon(_config("loop://faults-ack"), driver_factory=fake_factory(camera))

    def control(sequence: int, command: Command, *values: float) -> None:
        host.send(encode_message(Control(command, values), device_id=1, sequence=sequence, t_ns=0, signer=signer))

    with running(daemon) as run:
        before = _collect(host, 0.4)
        control(11, Command.SET_EXPOSURE, 2500)
        control(12, Command.SET_EXPOSURE, 50_000)  # longer than the frame period at 119 fps: the camera refuses
        control(13, Command.SET_GAIN, 40)  # camera units (the fake's gain control: 0..100)
        control(14, Command.SET_GAIN, 500)  # out of the camera's range
        control(15, Command.SET_GAIN, 2.5)  # not a camera gain value: refused at once
        applied = _collect(host, 0.6)
        assert camera.values["exposure_time_absolute"] == 25 and camera.values["gain"] == 40
        camera.vanish()
        lost = _collect(host, 0.3)
        camera.values.update(exposure_time_absolute=157, gain=0)  # a power-cycled camera is back at its defaults
        camera.reconnect()
        after = _collect(host, 0.6)
        assert run.thread.is_alive() and daemon.camera_reopened == 1
    acks = {a.acked_sequence: a for a in _records(applied, ControlAck)}
    assert {seq: a.result for seq, a in acks.items()} == {
        11: AckResult.APPLIED,
        12: AckResult.INVALID,
        13: AckResult.APPLIED,
        14: AckResult.INVALID,
        15: AckResult.INVALID,
    }
    assert "frame period" in acks[12].detail and "range" in acks[14].detail and "integer" in acks[15].detail
    # The control settings were put back on the reopened camera.
    assert camera.values["exposure_time_absolute"] == 25 and camera.values["gain"] == 40
    statuses = _records(before + applied + lost + after, Status)
    last = statuses[-1]
    assert last.exposure_us == 2500 and last.gain == 40.0  # gain in camera units (docs/daemon.md)
    counters = dict(last.counters)
    assert counters["control_applied"] == 2 and counters["control_failed"] == 3
    # Totals since the daemon started: they never go backwards when the camera is reopened.
    captured = [s.frames_captured for s in statuses]
    assert captured == sorted(captured) and captured[-1] > max(s.frames_captured for s in _records(lost, Status))
    assert _records(after, FrameResult)
    host.close()


class Unpluggable(LoopTransport):
    """A loop transport whose port can be pulled: then sends and receives fail but it is never closed."""

    unplugged = False

    def send(self, message: bytes) -> bool:
        if self.unplugged:
            raise TransportError("write failed: [Errno 5] Input/output error")
        return super().send(message)

    def receive(self, timeout_s: float | None = 0.0) -> bytes | None:
        if self.unplugged:
            time.sleep(min(timeout_s or 0.0, 0.05))
            raise TransportError("read failed: port lost?")
        return super().receive(timeout_s)


def test_a_failing_link_is_reopened_and_numbering_continues(caplog: pytest.LogCaptureFixture) -> None:
    camera = _camera()
    links: list[tuple[Unpluggable, LoopTransport]] = []
    refusals = [2]  # the port is not back at once: the first two reopen attempts fail

    def factory(url: str) -> Unpluggable:
        if links and refusals[0] > 0:
            refusals[0] -= 1
            raise TransportError(f"{url}: cannot open serial port: No such file or directory")
        device_end, host_end = LoopTransport.pair(4096, url)
        link = Unpluggable(url, device_end._inbox, device_end._outbox)
        links.append((link, host_end))
        return link

    daemon = Daemon(_config("loop://unused"), driver_factory=fake_factory(camera), transport_factory=factory)
    caplog.set_level(logging.WARNING)
    with running(daemon) as run:
        while not links and run.thread.is_alive():
            time.sleep(0.01)
        first = _collect(links[0][1], 0.4)
        links[0][0].unplugged = True
        deadline = time.monotonic() + 10
        while len(links) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert len(links) == 2, "the daemon never reopened the link"
        second = _collect(links[1][1], 0.5)
        assert run.thread.is_alive()
    assert daemon.link_reopened == 1
    first_sequences = [m.header.sequence for m in first]
    second_sequences = [m.header.sequence for m in second]
    assert _records(second, FrameResult) and _records(second, Status)
    assert second_sequences == sorted(second_sequences) and second_sequences[0] > first_sequences[-1]
    counters = dict(_records(second, Status)[-1].counters)
    assert counters["link_reopened"] == 1
    assert counters["link_errors"] >= 3  # the broken link's errors stay in the totals after the reopen
    # One error line per broken link, not one every half second.
    assert sum("control receive failed" in r.getMessage() for r in caplog.records) <= 1


class PingLog(Notifier):
    """Records the time of every notification instead of sending it."""

    def __init__(self, watchdog_usec: int) -> None:
        super().__init__(None, watchdog_usec)
        self.times: list[tuple[float, str]] = []

        self.daemon: Daemon | None = None
        self.measured_at_ready: int | None = None

    def notify(self, text: str) -> None:
        self.times.append((time.monotonic(), text.split("\n")[0]))
        if text.startswith("READY=1") and self.daemon is not None:
            self.measured_at_ready = self.daemon.frames_measured

    def pings_after(self, t: float) -> int:
        return sum(when >= t and text == "WATCHDOG=1" for when, text in self.times)


def test_watchdog_is_pinged_while_the_camera_is_retried() -> None:
    camera = _camera()
    notifier = PingLog(watchdog_usec=100_000)  # a ping is due every 0.05 s
    host = open_transport("loop://faults-wd")
    config = _config("loop://faults-wd", retry_initial_s=0.3, retry_max_s=0.3, camera_give_up_s=1.0)
    daemon = Daemon(config, notifier=notifier, driver_factory=fake_factory(camera))
    notifier.daemon = daemon
    with running(daemon) as run:
        _collect(host, 0.3)
        # READY once the first frame went through the pipeline (its kernels are loaded: the watchdog may start).
        assert notifier.measured_at_ready is not None and notifier.measured_at_ready >= 1
        lost_at = time.monotonic()
        camera.vanish()
        assert run.wait(10) == EXIT_CAMERA_LOST
    # About 20 pings are due in the second of retries (0.3 s waits); none were sent before the fix.
    assert notifier.pings_after(lost_at) >= 8
    host.close()


def test_watchdog_is_pinged_while_the_link_is_retried() -> None:
    notifier = PingLog(watchdog_usec=100_000)
    links: list[Unpluggable] = []

    def factory(url: str) -> Unpluggable:
        if links:  # once pulled, the port does not come back during this test
            raise TransportError(f"{url}: cannot open serial port: No such file or directory")
        device_end, _ = LoopTransport.pair(4096, url)
        links.append(Unpluggable(url, device_end._inbox, device_end._outbox))
        return links[0]

    config = _config("loop://unused", retry_initial_s=0.3, retry_max_s=0.3)
    daemon = Daemon(config, notifier=notifier, driver_factory=fake_factory(_camera()), transport_factory=factory)
    with running(daemon):
        deadline = time.monotonic() + 10
        while not any(text.startswith("READY") for _, text in notifier.times) and time.monotonic() < deadline:
            time.sleep(0.01)
        pulled_at = time.monotonic()
        links[0].unplugged = True
        time.sleep(1.0)
    assert notifier.pings_after(pulled_at) >= 8
