"""One deterministic example of every record type: golden files, fuzzing seeds, documentation and demos."""

from __future__ import annotations

import numpy as np

from ropecam.shared.protocol.records import (
    AckResult,
    Command,
    Control,
    ControlAck,
    FrameResult,
    FrameStatus,
    Log,
    Method,
    PixelFormat,
    RawFrameChunk,
    Status,
)
from ropecam.shared.protocol.wire import MessageType, Record

__all__ = ["arc_polyline", "example_records"]


def arc_polyline(
    start_px: tuple[float, float], length_px: float, heading_rad: float, curvature_per_px: float, noise_px: float = 0.0
) -> np.ndarray:
    """Return a circular arc sampled once per pixel, (n, 2) float64, with optional uniform noise (seeded, fixed)."""
    count = int(length_px) + 1
    s = np.linspace(0.0, length_px, count)
    angle = heading_rad + curvature_per_px * s
    if abs(curvature_per_px) < 1e-12:
        u = start_px[0] + s * np.cos(heading_rad)
        v = start_px[1] + s * np.sin(heading_rad)
    else:
        u = start_px[0] + (np.sin(angle) - np.sin(heading_rad)) / curvature_per_px
        v = start_px[1] - (np.cos(angle) - np.cos(heading_rad)) / curvature_per_px
    points = np.column_stack([u, v])
    if noise_px:
        points += np.random.default_rng(12345).uniform(-noise_px, noise_px, points.shape)
    return points


def example_records() -> dict[MessageType, Record]:
    """Return a fixed, fully populated example record for each message type."""
    begin = arc_polyline((508.0, 73.5), 400.0, 0.9, 0.0012, noise_px=0.02)
    end = arc_polyline((508.0, 73.5), 402.0, 0.93, 0.0013, noise_px=0.02)
    frame = FrameResult(
        frame_index=1234,
        exposure_start_t_ns=1_700_000_000_000_000_000,
        exposure_end_t_ns=1_700_000_000_004_000_000,
        status=FrameStatus.OK,
        method=Method.BLUR_SPLIT,
        order_confidence=0.875,
        begin_px=begin,
        end_px=end,
        begin_tip_px=(float(begin[-1, 0]), float(begin[-1, 1])),
        end_tip_px=(float(end[-1, 0]), float(end[-1, 1])),
        fixed_end_px=(508.0, 73.5),
        material_s_m=(0.1, 0.2, 0.3, 0.411),
        material_begin_px=begin[[100, 200, 300, 400]],
        material_end_px=end[[100, 200, 300, 402]],
        stretch_begin=1.0021,
        stretch_end=0.9987,
        pipeline_us=2750,
        readout_ns=7_500_000,
        quality={"length_ratio": 1.002, "width_ratio": 0.987, "fixed_end_px": 1.3, "tip_separation_px": 12.4},
    )
    image = (np.arange(64 * 48, dtype=np.uint32) * 7 % 251).astype(np.uint8).tobytes()
    return {
        MessageType.FRAME_RESULT: frame,
        MessageType.STATUS: Status(
            frame_rate_hz=119.0,
            frames_captured=123456,
            frames_dropped=12,
            messages_dropped=3,
            exposure_us=4000,
            gain=6.0,
            uptime_ns=1_037_000_000_000,
            cpu_load=0.5,
            temperature_c=61.5,
            counters=(("control_bad_tag", 2), ("control_replayed", 1)),
        ),
        MessageType.LOG: Log(30, "exposure clipped to 8000 us (frame period 8403 us)"),
        MessageType.CONTROL: Control(Command.SET_THRESHOLDS, (40.0, 90.0)),
        MessageType.CONTROL_ACK: ControlAck(77, Command.SET_EXPOSURE, AckResult.APPLIED, "exposure_us=4000"),
        MessageType.RAW_FRAME_CHUNK: RawFrameChunk(1234, 64, 48, PixelFormat.GRAY8, 2, 3, 2048, image[2048:3072]),
    }
