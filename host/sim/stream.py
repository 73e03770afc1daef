"""A simulated device on the wire: real encoded FrameResults of the rig scenario, Status each second, Log lines.

Encoding a FrameResult costs ~1.4 ms (shape fitting), more than a 119 FPS frame period on a slow machine, so the
stream encodes one swing of frames once and then re-stamps each message (sequence number, device time, CRC) as it
sends it. The payload codes the exposure times relative to the header time, so re-stamped frames carry consistent
times. `ropecam sim-device` sends such a stream to a monitor (try the monitor without a camera).
"""

from __future__ import annotations

import argparse
import logging
import struct
import time
import zlib
from collections.abc import Iterator
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:  # the protocol imports Numba: load it only when a stream is made, not for `ropecam --help`
    from ropecam.shared.protocol.records import FrameResult, Log, Status

__all__ = ["SimulatedDevice", "restamp", "rig_frame_results"]

_CRC: Final = struct.Struct("<I")


def rig_frame_results(
    count: int, seed: int = 0, fps: float = 119.0, noise: str = "uniform", stretch_wobble: float = 0.0
) -> list[FrameResult]:
    """Return `count` FrameResults of the simulated rig swing (``host.sim.rig_polylines``), as a device reports them.

    Parameters
    ----------
    count, seed, fps, noise
        As `ropecam.host.sim.rig_polylines.rig_frames` (device polyline noise: uniform, gaussian or none).
    stretch_wobble
        Amplitude of a slow variation of the reported stretch ratios around 1 (0: exactly 1), so that they cost
        the bytes real ones do.
    """
    import math

    from ropecam.host.sim.rig_polylines import rig_frames
    from ropecam.shared.protocol.records import FrameResult

    results = []
    for index, frame in enumerate(rig_frames(count, seed=seed, fps=fps, noise=noise)):
        results.append(
            FrameResult(
                frame_index=index,
                exposure_start_t_ns=frame.t_start_ns,
                exposure_end_t_ns=frame.t_end_ns,
                order_confidence=0.9,
                begin_px=frame.begin_px,
                end_px=frame.end_px,
                begin_tip_px=tuple(frame.begin_px[-1]),
                end_tip_px=tuple(frame.end_px[-1]),
                fixed_end_px=tuple(frame.fixed_end_px),
                material_s_m=frame.material_s_m,
                material_begin_px=frame.material_begin_px,
                material_end_px=frame.material_end_px,
                stretch_begin=1.0 + stretch_wobble * math.sin(index / 9),
                stretch_end=1.0 + stretch_wobble * math.sin((index + 0.5) / 9),
                pipeline_us=2500 + 37 * (index % 11),
            )
        )
    return results


def restamp(message: bytes, sequence: int, t_ns: int) -> bytes:
    """Return `message` (an unauthenticated encoded message) with a new sequence number, device time and CRC."""
    from ropecam.shared.protocol.wire import CRC_BYTES, HEADER_BYTES, Header, peek_header

    header = peek_header(message)
    if header.flags:
        raise ValueError("restamp cannot re-sign authenticated messages")
    stamped = Header(header.type, header.device_id, sequence, t_ns, header.payload_length).pack()
    body = stamped + message[HEADER_BYTES : len(message) - CRC_BYTES]
    return body + _CRC.pack(zlib.crc32(body))


class SimulatedDevice:
    """Produce the message stream of one simulated device.

    Parameters
    ----------
    device_id
        Header device id.
    fps
        Frame rate; a Status follows every `fps` frames.
    frame_count
        Distinct frames encoded up front (the stream cycles through them).
    seed
        Noise seed of the simulated polylines.
    """

    def __init__(self, device_id: int, fps: float = 119.0, frame_count: int = 65, seed: int = 0) -> None:
        if fps <= 0 or frame_count < 1:
            raise ValueError(f"fps must be > 0 and frame_count >= 1, got {fps}, {frame_count}")
        from ropecam.shared.protocol.records import ShapeHint
        from ropecam.shared.protocol.wire import encode_message

        self.device_id = device_id
        self.fps = fps
        hint = ShapeHint()
        self.frames = rig_frame_results(frame_count, seed, fps)
        self._encoded = [
            encode_message(r, device_id=device_id, sequence=0, t_ns=r.exposure_start_t_ns, pack_options={"hint": hint})
            for r in self.frames
        ]
        self.sequence = 0

    def _rest_message(self) -> bytes:
        """The rope held still before the release: frame 0's start shape at both ends of the exposure."""
        import dataclasses

        from ropecam.shared.protocol.wire import encode_message

        first = self.frames[0]
        rest = dataclasses.replace(
            first,
            end_px=first.begin_px,
            end_tip_px=first.begin_tip_px,
            material_end_px=first.material_begin_px,
        )
        return encode_message(rest, device_id=self.device_id, sequence=0, t_ns=rest.exposure_start_t_ns)

    def messages(
        self, count: int, start_t_ns: int | None = None, rest_frames: int = 0
    ) -> Iterator[tuple[float, bytes]]:
        """Yield (send offset in s from the start, message bytes) for `count` frames plus Status and Log messages.

        The first `rest_frames` frames show the rope held at rest; the swing (the release) starts after them, at
        ``start_t_ns + rest_frames / fps``.
        """
        from ropecam.shared.protocol.records import Log, Status

        start_t_ns = time.time_ns() if start_t_ns is None else start_t_ns
        period_ns = round(1e9 / self.fps)
        per_status = max(1, round(self.fps))
        yield (
            0.0,
            self._next(
                Log(logging.INFO, f"simulated device {self.device_id} streaming at {self.fps:g} FPS"), start_t_ns
            ),
        )
        rest = self._rest_message() if rest_frames else b""
        for k in range(count):
            t_ns = start_t_ns + k * period_ns
            self.sequence = (self.sequence + 1) & 0xFFFF_FFFF
            encoded = rest if k < rest_frames else self._encoded[(k - rest_frames) % len(self._encoded)]
            yield k * period_ns / 1e9, restamp(encoded, self.sequence, t_ns)
            if (k + 1) % per_status == 0:
                status = Status(
                    frame_rate_hz=self.fps,
                    frames_captured=k + 1,
                    frames_dropped=0,
                    messages_dropped=0,
                    exposure_us=4000,
                    gain=0.0,
                    uptime_ns=k * period_ns,
                    cpu_load=0.4,
                    temperature_c=55.0,
                )
                yield k * period_ns / 1e9, self._next(status, t_ns)

    def _next(self, record: Log | Status, t_ns: int) -> bytes:
        from ropecam.shared.protocol.wire import encode_message

        self.sequence = (self.sequence + 1) & 0xFFFF_FFFF
        return encode_message(record, device_id=self.device_id, sequence=self.sequence, t_ns=t_ns)


def send_paced(device: SimulatedDevice, url: str, duration_s: float) -> tuple[int, int]:
    """Send `duration_s` of the device's stream to `url` in real time; return (sent, dropped by the transport)."""
    from ropecam.shared.transport import open_transport

    count = round(duration_s * device.fps)
    with open_transport(url) as link:
        start = time.monotonic()
        for offset_s, data in device.messages(count):
            delay = start + offset_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            link.send(data)
        link.drain(1.0)
        return link.stats.sent, link.stats.send_dropped


def _run(args: argparse.Namespace) -> int:
    device = SimulatedDevice(args.device_id, args.fps, seed=args.device_id)
    print(f"device {args.device_id}: sending {args.duration_s:g} s at {args.fps:g} FPS to {args.to}")
    sent, dropped = send_paced(device, args.to, args.duration_s)
    print(f"device {args.device_id}: sent {sent} messages, {dropped} dropped by the transport")
    return 0


HELP = """\
Send the message stream of a simulated device (the rig swing of `ropecam.host.sim.rig_polylines` as FrameResults at
the camera rate, a Status every second, a Log line at start) to a host: try `ropecam monitor` without hardware.

example (two terminals):
  ropecam monitor --source udp://127.0.0.1:5600
  ropecam sim-device --to udp://127.0.0.1:5600 --device-id 3 --duration-s 20
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `sim-device` sub-command."""
    parser = subparsers.add_parser(
        "sim-device",
        help="stream a simulated device",
        description=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--to", default="udp://127.0.0.1:5600", help="transport URL (default udp://127.0.0.1:5600)")
    parser.add_argument("--device-id", type=int, default=1, help="device id in the headers (default 1)")
    parser.add_argument("--fps", type=float, default=119.0, help="frame rate (default 119)")
    parser.add_argument("--duration-s", type=float, default=10.0, help="how long to send (default 10 s)")
    parser.set_defaults(func=_run)
