"""The one path every received message takes, live (`ropecam monitor`) or replayed (`ropecam replay`).

`Session.handle(packet)`: statistics, the raw wire channel (always, every packet, including damaged ones, so replay
reproduces the stream exactly), then the full decode and the decoded channels (Foxglove scene, material points,
status, log). Under overload the caller may pass ``decode=False`` for FrameResults: the raw bytes are still recorded
and counted, only the decoded channels skip that frame (`Session.skipped_decodes`); ``ropecam replay --record``
rebuilds them later from the raw channel.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Final

import numpy as np

from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.host.monitor.stats import DeviceRow, StreamStats
from ropecam.host.receiver import Packet, summarize_frame
from ropecam.host.recording.convert import frame_point_cloud, frame_scene, log_message, raw_image, status_message
from ropecam.host.recording.writer import Recorder
from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.rawframe import FrameAssembler
from ropecam.shared.protocol.records import FrameResult, Log, RawFrameChunk, Status
from ropecam.shared.protocol.wire import Message, MessageType, decode_message

if TYPE_CHECKING:
    from ropecam.host.model_overlay import ModelOverlay

ModelSource = Callable[[FrameResult, int], "ModelOverlay | None"]
"""``(record, device_id) -> ModelOverlay | None``: the model aligned with that device's clock, if any."""

__all__ = ["LOG_TOPIC", "RAW_ENCODING", "RAW_TOPIC", "Session", "device_topic"]

RAW_TOPIC: Final = "/ropecam/wire"
"""Every received message, byte for byte (schemaless channel)."""
RAW_ENCODING: Final = "ropecam.wire.v1"
LOG_TOPIC: Final = "/log"
RECENT_LOGS: Final = 8


def device_topic(device_id: int, name: str) -> str:
    """Return the topic of one of a device's decoded channels, e.g. ``/device3/image/scene``."""
    return f"/device{device_id}/{name}"


class Session:
    """Statistics, recording and decoding of one stream of packets (any number of devices).

    Parameters
    ----------
    recorder
        Where to record (None: monitor only).
    calibration
        (camera, plane pose): adds the plane channels in metres and the tip position in millimetres.
    model
        ``(record, device_id) -> ModelOverlay | None``: the model aligned with that device's clock, if any (replay:
        fitted to the whole run; live: `ropecam.host.monitor.live_model.LiveModel` after the release). Adds the model
        rope and its error channels and the model error column.
    """

    def __init__(
        self,
        recorder: Recorder | None = None,
        calibration: tuple[CameraModel, PlanePose] | None = None,
        model: ModelSource | None = None,
    ) -> None:
        self.recorder = recorder
        self.calibration = calibration
        self.model = model
        self.stats = StreamStats()
        self.skipped_decodes = 0
        self._undecoded_run: dict[int, int] = {}  # FrameResults skipped in a row, per device
        self._assemblers: dict[int, FrameAssembler] = {}
        self.raw_frames = 0
        """Whole raw frames received (requested with REQUEST_RAW_FRAME), recorded as ``foxglove.RawImage``."""
        self.recent_logs: deque[tuple[int, int, str]] = deque(maxlen=RECENT_LOGS)  # (device id, level, text)

    def fair_decode(self, packet: Packet) -> bool:
        """Say whether to decode `packet` when only some frames can be: the device skipped longest goes first.

        Under sustained overload this spreads the decoded frames evenly over the devices (round robin) instead of
        favouring whichever device happens to send when the backlog dips.
        """
        header = packet.header
        if header is None or header.type != MessageType.FRAME_RESULT:
            return True
        runs = self._undecoded_run
        return runs.get(header.device_id, 0) >= max(runs.values(), default=0)

    def handle(self, packet: Packet, decode: bool = True) -> Message | None:
        """Account for, record and (unless skipped) decode one packet; return the decoded message if any.

        Never raises on bad packets: they are counted (per device when the header is readable) and recorded raw. A
        FrameResult with a pixel that does not map onto the plane is counted as bad too, recorded raw and in
        pixels, and left out of the plane and model channels.
        """
        summary = summarize_frame(packet)
        usable = self.stats.observe(packet, summary)
        header = packet.header
        recorder = self.recorder
        if recorder is not None:
            sequence = header.sequence if header is not None else 0
            recorder.write(RAW_TOPIC, packet.data, packet.receive_t_ns, None, RAW_ENCODING, sequence)
        if not usable or header is None:
            return None
        if header.type == MessageType.FRAME_RESULT:
            if not decode:
                self.skipped_decodes += 1
                self._undecoded_run[header.device_id] = self._undecoded_run.get(header.device_id, 0) + 1
                return None
            self._undecoded_run[header.device_id] = 0
        try:
            message = decode_message(packet.data)
        except ProtocolError:
            self.stats.decode_failed(header.device_id)
            return None
        record = message.record
        device_id, t_ns = header.device_id, packet.receive_t_ns
        if isinstance(record, FrameResult):
            self._frame(record, device_id, t_ns)
        elif isinstance(record, Status):
            self.stats.status_received(device_id, record.frames_dropped)
            if recorder is not None:
                recorder.write(device_topic(device_id, "status"), status_message(record, device_id, t_ns), t_ns,
                               "ropecam.Status", sequence=header.sequence)  # fmt: skip
        elif isinstance(record, RawFrameChunk):
            self._raw_chunk(record, device_id, t_ns)
        elif isinstance(record, Log):
            self.recent_logs.append((device_id, record.level, record.text))
            if recorder is not None:
                data = log_message(record, f"device{device_id}", t_ns)
                recorder.write(LOG_TOPIC, data, t_ns, "foxglove.Log", sequence=header.sequence)
        return message

    def _frame(self, record: FrameResult, device_id: int, t_ns: int) -> None:
        tip = record.end_tip_px if record.end_tip_px is not None else record.begin_tip_px
        recorder = self.recorder
        if recorder is not None:
            scene, points = "foxglove.SceneUpdate", "foxglove.PointCloud"
            recorder.write(device_topic(device_id, "image/scene"), frame_scene(record, device_id, t_ns), t_ns, scene)
            if record.material_s_m:
                data = frame_point_cloud(record, device_id, t_ns)
                recorder.write(device_topic(device_id, "image/material_points"), data, t_ns, points)
        if self.calibration is None:
            self.stats.frame_decoded(device_id, tip, None)
            return
        try:
            tip_plane, model_rms_mm, messages = self._plane_results(record, device_id, t_ns, tip)
        except ValueError:
            # A pixel whose viewing ray misses the plane (behind the camera, parallel): the frame is counted as bad
            # and stays recorded raw and in pixels; none of its plane or model channels is written.
            self.stats.decode_failed(device_id)
            self.stats.frame_decoded(device_id, tip, None)
            return
        self.stats.frame_decoded(device_id, tip, tip_plane)
        if model_rms_mm is not None:
            self.stats.model_compared(device_id, model_rms_mm)
        if recorder is not None:
            for topic, data, schema in messages:
                recorder.write(topic, data, t_ns, schema)

    def _plane_results(
        self, record: FrameResult, device_id: int, t_ns: int, tip: tuple[float, float] | None
    ) -> tuple[tuple[float, float] | None, float | None, list[tuple[str, bytes, str]]]:
        """Everything of a frame in metres: (tip on the plane, model RMS error mm, channel messages); nothing is
        written here, so a `ValueError` (pixel off the plane) leaves no partial output."""
        calibration = self.calibration
        assert calibration is not None
        tip_plane = None
        if tip is not None:
            x, y = pixels_to_plane([tip], *calibration)[0]
            tip_plane = (float(x), float(y))
        messages: list[tuple[str, bytes, str]] = []
        if self.recorder is not None:
            data = frame_scene(record, device_id, t_ns, calibration)
            messages.append((device_topic(device_id, "plane/scene"), data, "foxglove.SceneUpdate"))
            if record.material_s_m:
                data = frame_point_cloud(record, device_id, t_ns, calibration)
                messages.append((device_topic(device_id, "plane/material_points"), data, "foxglove.PointCloud"))
        overlay = self.model(record, device_id) if self.model is not None else None
        if overlay is None:
            return tip_plane, None, messages
        errors = overlay.frame_errors_mm(record)
        finite = [e for e in errors[0] + errors[1] if e is not None]
        rms_mm = float(np.sqrt(np.mean(np.square(finite)))) if finite else math.nan
        if self.recorder is not None:
            messages += overlay.messages(record, device_id, t_ns, errors)
        return tip_plane, rms_mm, messages

    def _raw_chunk(self, chunk: RawFrameChunk, device_id: int, t_ns: int) -> None:
        assembler = self._assemblers.setdefault(device_id, FrameAssembler())
        try:
            image = assembler.add(chunk)
        except ProtocolError:
            self.stats.decode_failed(device_id)
            return
        if image is None:
            return
        self.raw_frames += 1
        if self.recorder is not None:
            data = raw_image(image, device_id, t_ns)
            self.recorder.write(device_topic(device_id, "image/raw"), data, t_ns, "foxglove.RawImage")

    def tick(self) -> None:
        """Let the recorder flush and roll on time; call it at least 10 times a second."""
        if self.recorder is not None:
            self.recorder.tick()

    def snapshot(self, now_ns: int) -> list[DeviceRow]:
        """Per-device rows for the display (see `StreamStats.snapshot`)."""
        return self.stats.snapshot(now_ns)

    def close(self) -> None:
        """Finish the recording (summary, index) if there is one."""
        if self.recorder is not None:
            self.recorder.close()
