"""Per-device live statistics: rate, period jitter, sequence accounting, errors, bytes/s, latency, pipeline time.

`StreamStats.observe` is called once per packet (a few microseconds); `StreamStats.snapshot` turns the rolling windows
into one `DeviceRow` per device for the UI or the one-line summaries.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final

import numpy as np

from ropecam.host.receiver import FrameSummary, Packet
from ropecam.shared.protocol.wire import MessageType
from ropecam.shared.transport.sequence import SequenceTracker

__all__ = ["DeviceRow", "StreamStats"]

WINDOW_NS: Final = 2_000_000_000
"""Rates, jitter and latency are computed over the last 2 s of packets."""
PIPELINE_SAMPLES: Final = 512
SYNCED_CLOCK_LIMIT_NS: Final = 10_000_000_000
"""Latency is shown only when device and host clocks agree within 10 s (else they are different clocks)."""
STALL_NS: Final = 2_000_000_000
CHECK_PREFIX: Final = "check_"
"""Status counters of this prefix count the device's self-check failures by reason (`ropecam.device.daemon`)."""


@dataclass(slots=True)
class _Device:
    frame_times: deque[tuple[int, int, int]] = field(default_factory=deque)  # (receive_t_ns, header t_ns, sequence)
    byte_times: deque[tuple[int, int]] = field(default_factory=deque)  # (receive_t_ns, bytes)
    pipeline_us: deque[int] = field(default_factory=lambda: deque(maxlen=PIPELINE_SAMPLES))
    packets: int = 0
    bytes: int = 0
    frames: int = 0
    crc_errors: int = 0
    decode_errors: int = 0
    decoded_frames: int = 0
    last_receive_t_ns: int = 0
    order_confidence: float = math.nan
    tip_px: tuple[float, float] | None = None
    tip_plane_m: tuple[float, float] | None = None
    lost_reported: int = 0
    device_dropped: int = 0
    device_dropped_reported: int = 0
    model_error_mm: float = math.nan
    check_failures: dict[str, int] = field(default_factory=dict)  # the device's counts by reason (its Status)
    check_failures_reported: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class DeviceRow:
    """What the monitor shows for one device (nan where unknown)."""

    device_id: int
    rate_hz: float
    period_jitter_ms: float
    received: int
    lost: int
    duplicates: int
    reordered: int
    crc_errors: int
    decode_errors: int
    bytes_per_s: float
    latency_ms: float
    pipeline_p50_us: float
    pipeline_p99_us: float
    tip_px: tuple[float, float] | None
    tip_plane_m: tuple[float, float] | None
    order_confidence: float
    decoded_fraction: float
    device_dropped: int
    warnings: tuple[str, ...]
    model_error_mm: float = math.nan


class StreamStats:
    """Accumulate per-device statistics from packets.

    Sequence numbers are tracked per device across everything the device sends (data, logs, status and control
    acks share one counter per device, as the protocol defines); only host -> device `CONTROL` messages are left
    out. Packets whose header cannot be read have no device and are counted in `bad_packets`.
    """

    def __init__(self) -> None:
        self.tracker = SequenceTracker()
        self._devices: dict[int, _Device] = {}
        self.bad_packets = 0
        self.packets = 0
        self.last_receive_t_ns = 0
        """Receive time of the newest packet (replay takes its snapshot there)."""

    def devices(self) -> list[int]:
        """Device ids seen so far."""
        return sorted(self._devices)

    def _device(self, device_id: int) -> _Device:
        device = self._devices.get(device_id)
        if device is None:
            device = self._devices[device_id] = _Device()
        return device

    def observe(self, packet: Packet, summary: FrameSummary | None = None) -> bool:
        """Account for one packet; return True when it should be used (sound and neither duplicate nor stale)."""
        self.packets += 1
        self.last_receive_t_ns = max(self.last_receive_t_ns, packet.receive_t_ns)
        header = packet.header
        if header is None:
            self.bad_packets += 1
            return False
        device = self._device(header.device_id)
        now = packet.receive_t_ns
        device.packets += 1
        device.bytes += len(packet.data)
        device.last_receive_t_ns = now
        device.byte_times.append((now, len(packet.data)))
        _trim(device.byte_times, now)
        if not packet.ok:
            device.crc_errors += packet.crc_error
            device.decode_errors += not packet.crc_error
            return False
        if header.type == MessageType.CONTROL:
            return True  # host -> device commands have the host's own sequence numbers
        if not self.tracker.observe(header.device_id, header.sequence).accept:
            return False
        if header.type == MessageType.FRAME_RESULT:
            device.frames += 1
            device.frame_times.append((now, header.t_ns, header.sequence))
            _trim(device.frame_times, now)
            if summary is not None:
                device.pipeline_us.append(summary.pipeline_us)
                device.order_confidence = summary.order_confidence
        return True

    def decode_failed(self, device_id: int) -> None:
        """Count a packet whose envelope was sound but whose payload the full decode refused."""
        self._device(device_id).decode_errors += 1

    def frame_decoded(
        self, device_id: int, tip_px: tuple[float, float] | None, tip_plane_m: tuple[float, float] | None
    ) -> None:
        """Record the latest decoded tip (end of exposure) of a device's FrameResult."""
        device = self._device(device_id)
        device.decoded_frames += 1
        if tip_px is not None:
            device.tip_px = tip_px
            device.tip_plane_m = tip_plane_m

    def model_compared(self, device_id: int, rms_error_mm: float) -> None:
        """Record the RMS distance (mm) of the latest frame's material points from the model."""
        self._device(device_id).model_error_mm = rms_error_mm

    def status_received(self, device_id: int, frames_dropped: int, counters: Sequence[tuple[str, int]] = ()) -> None:
        """Record the device's own count of dropped frames and its self-check failures by reason (the
        ``check_<reason>`` counters of its Status)."""
        device = self._device(device_id)
        device.device_dropped = frames_dropped
        for name, count in counters:
            if name.startswith(CHECK_PREFIX):
                device.check_failures[name[len(CHECK_PREFIX) :]] = count

    def snapshot(self, now_ns: int) -> list[DeviceRow]:
        """Return one row per device, computed over the last `WINDOW_NS` before `now_ns`."""
        rows = []
        for device_id in sorted(self._devices):
            device = self._devices[device_id]
            _trim(device.frame_times, now_ns)
            _trim(device.byte_times, now_ns)
            seq = self.tracker.stats(device_id)
            frame_times = device.frame_times
            rate_hz = jitter_ms = latency_ms = math.nan
            if len(frame_times) >= 2:
                span_ns = frame_times[-1][0] - frame_times[0][0]
                if span_ns > 0:
                    rate_hz = (len(frame_times) - 1) * 1e9 / span_ns
                times = np.array([(t, s) for _, t, s in frame_times], dtype=np.int64)
                consecutive = np.diff(times[:, 1]) % (1 << 32) == 1
                periods = np.diff(times[:, 0])[consecutive]
                if len(periods) >= 2:
                    jitter_ms = float(np.std(periods)) / 1e6
            if frame_times:
                latencies = np.array([r - t for r, t, _ in frame_times], dtype=np.float64)
                median = float(np.median(latencies))
                if abs(median) < SYNCED_CLOCK_LIMIT_NS:
                    latency_ms = median / 1e6
            bytes_per_s = sum(b for _, b in device.byte_times) * 1e9 / WINDOW_NS
            p50 = p99 = math.nan
            if device.pipeline_us:
                pipeline = np.fromiter(device.pipeline_us, dtype=np.float64)
                p50, p99 = (float(v) for v in np.percentile(pipeline, [50, 99]))
            warnings = []
            if seq.lost > device.lost_reported:
                warnings.append(f"LOSS +{seq.lost - device.lost_reported}")
            device.lost_reported = seq.lost
            if device.device_dropped > device.device_dropped_reported:
                warnings.append(f"DEVICE DROPPED +{device.device_dropped - device.device_dropped_reported} frames")
            device.device_dropped_reported = device.device_dropped
            for reason, count in sorted(device.check_failures.items()):
                if count > device.check_failures_reported.get(reason, 0):
                    warnings.append(f"CHECK {reason} +{count - device.check_failures_reported.get(reason, 0)}")
                device.check_failures_reported[reason] = count
            if now_ns - device.last_receive_t_ns > STALL_NS:
                warnings.append(f"silent {(now_ns - device.last_receive_t_ns) / 1e9:.0f} s")
            if device.crc_errors or device.decode_errors:
                warnings.append(f"{device.crc_errors + device.decode_errors} bad")
            if seq.restarts:
                warnings.append(f"{seq.restarts} restart(s)")
            rows.append(
                DeviceRow(
                    device_id=device_id,
                    rate_hz=rate_hz,
                    period_jitter_ms=jitter_ms,
                    received=seq.received,
                    lost=seq.lost,
                    duplicates=seq.duplicates,
                    reordered=seq.reordered,
                    crc_errors=device.crc_errors,
                    decode_errors=device.decode_errors,
                    bytes_per_s=bytes_per_s,
                    latency_ms=latency_ms,
                    pipeline_p50_us=p50,
                    pipeline_p99_us=p99,
                    tip_px=device.tip_px,
                    tip_plane_m=device.tip_plane_m,
                    order_confidence=device.order_confidence,
                    decoded_fraction=device.decoded_frames / device.frames if device.frames else math.nan,
                    device_dropped=device.device_dropped,
                    warnings=tuple(warnings),
                    model_error_mm=device.model_error_mm,
                )
            )
        return rows


def _trim(window: deque, now_ns: int) -> None:
    while window and now_ns - window[0][0] > WINDOW_NS:
        window.popleft()
