"""The one path every received message takes, live (`ropecam monitor`) or replayed (`ropecam replay`).

`Session.handle(packet)`: statistics, the raw wire channel (always, every packet, including damaged ones, so replay
reproduces the stream exactly), then the full decode and the decoded channels (Foxglove scene, material points,
transforms, status, log), to the recording and to a live sink (`ropecam monitor --foxglove`) alike.

Times: a decoded message's log time is when it happened on the host clock: a frame's exposure midpoint (device
clock) mapped through the device's clock offset (`ClockMap`), a status or log line its device send time mapped
the same way; its publish time is the host receive time. The raw wire channel is stamped with the receive time
(replay feeds it back as such).

Under overload the caller may pass ``decode=False`` for FrameResults: the raw bytes are still recorded and counted,
only the decoded channels skip that frame (`Session.skipped_decodes`); ``ropecam replay --record`` rebuilds them
later from the raw channel.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Final, Protocol

import numpy as np

from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane
from ropecam.host.monitor.clock import ClockMap
from ropecam.host.monitor.stats import DeviceRow, StreamStats
from ropecam.host.receiver import Packet, summarize_frame
from ropecam.host.recording.convert import Encoder, frame_content, point_cloud_content, status_message
from ropecam.host.recording.frames import device_transforms
from ropecam.host.recording.wire import RAW_TOPIC, WIRE_ENCODING, WIRE_SCHEMA, wrap
from ropecam.host.recording.writer import Recorder
from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.rawframe import FrameAssembler
from ropecam.shared.protocol.records import FrameResult, Log, RawFrameChunk, Status
from ropecam.shared.protocol.wire import Message, MessageType, decode_message

if TYPE_CHECKING:
    from ropecam.host.model_overlay import ModelOverlay

ModelSource = Callable[[FrameResult, int], "ModelOverlay | None"]
"""``(record, device_id) -> ModelOverlay | None``: the model aligned with that device's clock, if any."""

__all__ = ["LOG_TOPIC", "RAW_TOPIC", "TF_TOPIC", "Session", "Sink", "device_topic"]

LOG_TOPIC: Final = "/log"
TF_TOPIC: Final = "/tf"
"""``foxglove.FrameTransforms`` of every calibrated device (`ropecam.host.recording.frames`), once a second."""
TF_PERIOD_NS: Final = 1_000_000_000
RECENT_LOGS: Final = 8


class Sink(Protocol):
    """Where decoded messages go besides the recording (e.g. the live Foxglove server)."""

    def write(
        self, topic: str, data: bytes, log_time_ns: int, schema_name: str | None = None,
        message_encoding: str = "json", sequence: int = 0, publish_time_ns: int | None = None,
    ) -> bool: ...  # fmt: skip


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
    encoder
        Message encoding of the Foxglove channels (default: protobuf when the official package is installed).
    live
        A second destination of the decoded channels (not of the raw wire channel).
    """

    def __init__(
        self,
        recorder: Recorder | None = None,
        calibration: tuple[CameraModel, PlanePose] | None = None,
        model: ModelSource | None = None,
        encoder: Encoder | None = None,
        live: Sink | None = None,
    ) -> None:
        from ropecam.host.recording.proto import make_encoder

        self.recorder = recorder
        self.calibration = calibration
        self.model = model
        self.encoder = encoder if encoder is not None else make_encoder()
        self.live = live
        self._sinks: list[Sink] = [sink for sink in (recorder, live) if sink is not None]
        self.clock = ClockMap()
        self._tf_due: dict[int, int] = {}  # device -> log time of its next transforms
        self.layout: Path | None = None
        """The Foxglove layout written beside the recording by `close`."""
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
        if self.recorder is not None:
            sequence = header.sequence if header is not None else 0
            self.recorder.write(RAW_TOPIC, wrap(packet.data), packet.receive_t_ns, WIRE_SCHEMA, WIRE_ENCODING, sequence)
        if not usable or header is None:
            return None
        self.clock.observe(header.device_id, header.t_ns, packet.receive_t_ns)
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
        device_id, receive_t_ns = header.device_id, packet.receive_t_ns
        sent_t_ns = self.clock.to_host(device_id, header.t_ns, receive_t_ns)
        if isinstance(record, FrameResult):
            mid_t_ns = (record.exposure_start_t_ns + record.exposure_end_t_ns) // 2
            self._frame(record, device_id, self.clock.to_host(device_id, mid_t_ns, receive_t_ns), receive_t_ns)
        elif isinstance(record, Status):
            self.stats.status_received(device_id, record.frames_dropped, record.counters)
            data = status_message(record, device_id, sent_t_ns)
            self._emit(device_topic(device_id, "status"), data, "ropecam.Status", sent_t_ns, receive_t_ns, "json",
                       header.sequence)  # fmt: skip
        elif isinstance(record, RawFrameChunk):
            self._raw_chunk(record, device_id, sent_t_ns, receive_t_ns)
        elif isinstance(record, Log):
            self.recent_logs.append((device_id, record.level, record.text))
            data = self.encoder.log(record, f"device{device_id}", sent_t_ns)
            self._emit(LOG_TOPIC, data, "foxglove.Log", sent_t_ns, receive_t_ns, sequence=header.sequence)
        return message

    def _emit(
        self, topic: str, data: bytes, schema: str, t_ns: int, receive_t_ns: int, encoding: str | None = None,
        sequence: int = 0,
    ) -> None:  # fmt: skip
        encoding = self.encoder.encoding if encoding is None else encoding
        for sink in self._sinks:
            sink.write(topic, data, t_ns, schema, encoding, sequence, receive_t_ns)

    def _transforms(self, device_id: int, t_ns: int, receive_t_ns: int) -> None:
        """Send the device's transform tree at its first frame and then once a second (each part gets one)."""
        if self.calibration is None or t_ns < self._tf_due.get(device_id, -1):
            return
        self._tf_due[device_id] = t_ns + TF_PERIOD_NS
        data = self.encoder.transforms(device_transforms(device_id, *self.calibration), t_ns)
        self._emit(TF_TOPIC, data, "foxglove.FrameTransforms", t_ns, receive_t_ns)

    def _frame(self, record: FrameResult, device_id: int, t_ns: int, receive_t_ns: int) -> None:
        tip = record.end_tip_px if record.end_tip_px is not None else record.begin_tip_px
        if self._sinks:
            encoder = self.encoder
            data = encoder.scene(frame_content(record, device_id), t_ns)
            self._emit(device_topic(device_id, "image/scene"), data, "foxglove.SceneUpdate", t_ns, receive_t_ns)
            if record.material_s_m:
                data = encoder.point_cloud(*point_cloud_content(record, device_id), t_ns)
                self._emit(device_topic(device_id, "image/material_points"), data, "foxglove.PointCloud", t_ns,
                           receive_t_ns)  # fmt: skip
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
        if self._sinks:
            self._transforms(device_id, t_ns, receive_t_ns)
            for topic, data, schema, encoding in messages:
                self._emit(topic, data, schema, t_ns, receive_t_ns, encoding)

    def _plane_results(
        self, record: FrameResult, device_id: int, t_ns: int, tip: tuple[float, float] | None
    ) -> tuple[tuple[float, float] | None, float | None, list[tuple[str, bytes, str, str]]]:
        """Everything of a frame in metres: (tip on the plane, model RMS error mm, channel messages); nothing is
        written here, so a `ValueError` (pixel off the plane) leaves no partial output."""
        calibration = self.calibration
        assert calibration is not None
        tip_plane = None
        if tip is not None:
            x, y = pixels_to_plane([tip], *calibration)[0]
            tip_plane = (float(x), float(y))
        messages: list[tuple[str, bytes, str, str]] = []
        encoder = self.encoder
        if self._sinks:
            data = encoder.scene(frame_content(record, device_id, calibration), t_ns)
            messages.append((device_topic(device_id, "plane/scene"), data, "foxglove.SceneUpdate", encoder.encoding))
            if record.material_s_m:
                data = encoder.point_cloud(*point_cloud_content(record, device_id, calibration), t_ns)
                topic = device_topic(device_id, "plane/material_points")
                messages.append((topic, data, "foxglove.PointCloud", encoder.encoding))
        overlay = self.model(record, device_id) if self.model is not None else None
        if overlay is None:
            return tip_plane, None, messages
        errors = overlay.frame_errors_mm(record)
        finite = [e for e in errors[0] + errors[1] if e is not None]
        rms_mm = float(np.sqrt(np.mean(np.square(finite)))) if finite else math.nan
        if self._sinks:
            messages += overlay.messages(record, device_id, t_ns, errors, encoder)
        return tip_plane, rms_mm, messages

    def _raw_chunk(self, chunk: RawFrameChunk, device_id: int, t_ns: int, receive_t_ns: int) -> None:
        assembler = self._assemblers.setdefault(device_id, FrameAssembler())
        try:
            image = assembler.add(chunk)
        except ProtocolError:
            self.stats.decode_failed(device_id)
            return
        if image is None:
            return
        self.raw_frames += 1
        if self._sinks:
            data = self.encoder.raw_image(image, device_id, t_ns)
            self._emit(device_topic(device_id, "image/raw"), data, "foxglove.RawImage", t_ns, receive_t_ns)

    def tick(self) -> None:
        """Let the recorder flush and roll on time; call it at least 10 times a second."""
        if self.recorder is not None:
            self.recorder.tick()

    def snapshot(self, now_ns: int) -> list[DeviceRow]:
        """Per-device rows for the display (see `StreamStats.snapshot`)."""
        return self.stats.snapshot(now_ns)

    def close(self) -> None:
        """Finish the recording (summary, index) if there is one and write its Foxglove layout beside it."""
        from ropecam.host.recording.layout import write_layout

        recorder = self.recorder
        if recorder is not None:
            recorder.close()
            if recorder.parts:
                device_id = min(self.stats.devices(), default=0)
                self.layout = write_layout(recorder.config.path, device_id, recorder.config.overwrite)
