"""The small records: Status, Log, Control, ControlAck and RawFrameChunk (FrameResult is in `frame_result`).

Each is a frozen dataclass that validates its fields (ValueError naming the field), with ``pack(t_ns_ref)`` and
``unpack(payload, t_ns_ref)``; unpack raises only `ProtocolError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import ClassVar, Final

import numpy as np

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.bytecodec import ByteReader, ByteWriter, check_int
from ropecam.shared.protocol.frame_result import FrameResult, FrameStatus, Method, ShapeHint
from ropecam.shared.protocol.wire import MAX_PAYLOAD_BYTES, MessageType, register_record

__all__ = [
    "MAX_CHUNK_BYTES",
    "AckResult",
    "Command",
    "Control",
    "ControlAck",
    "FrameResult",
    "FrameStatus",
    "Log",
    "Method",
    "PixelFormat",
    "RawFrameChunk",
    "ShapeHint",
    "Status",
]

_U16: Final = 0xFFFF
_U32: Final = 0xFFFF_FFFF
_U64: Final = (1 << 64) - 1
_F32_MAX: Final = float(np.finfo(np.float32).max)
MAX_TEXT_BYTES: Final = 1024
MAX_COUNTERS: Final = 64
MAX_CHUNK_BYTES: Final = MAX_PAYLOAD_BYTES - 32


def _check_text(name: str, value: object, maximum: int) -> str:
    if not isinstance(value, str) or len(value.encode("utf-8")) > maximum:
        raise ValueError(f"{name} must be a string of <= {maximum} UTF-8 bytes, got {value!r:.80}")
    return value


@register_record
@dataclass(frozen=True, slots=True)
class Status:
    """Device health, sent about once a second.

    Parameters
    ----------
    frame_rate_hz
        Measured camera frame rate.
    frames_captured, frames_dropped
        Frames since start; frames the pipeline skipped or the camera lost.
    messages_dropped
        Messages the transport dropped because the line was full.
    exposure_us, gain
        Current camera settings; ``gain`` is the analogue gain in the CAMERA'S OWN UNITS
        (the V4L2 ``gain`` control, as SET_GAIN sets it; 0 when never set): UVC cameras publish no dB scale.
    uptime_ns
        Time since the daemon started.
    cpu_load, temperature_c
        CPU load in [0, 1] and SoC temperature; nan where the platform does not tell.
    counters
        Further named counters ((name, value) pairs, e.g. ``("control_bad_tag", 3)``), names <= 32 bytes.
    """

    TYPE: ClassVar[MessageType] = MessageType.STATUS

    frame_rate_hz: float
    frames_captured: int
    frames_dropped: int
    messages_dropped: int
    exposure_us: int
    gain: float
    uptime_ns: int
    cpu_load: float = math.nan
    temperature_c: float = math.nan
    counters: tuple[tuple[str, int], ...] = ()

    def __post_init__(self) -> None:
        for name in ("frames_captured", "frames_dropped", "messages_dropped", "uptime_ns"):
            object.__setattr__(self, name, check_int(name, getattr(self, name), high=_U64))
        object.__setattr__(self, "exposure_us", check_int("exposure_us", self.exposure_us, high=_U32))
        for name in ("frame_rate_hz", "gain", "cpu_load", "temperature_c"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
                raise ValueError(f"{name} must be a number, got {value!r}")
            value = float(value)
            # float32 on the wire: refuse here what pack could not write.
            if math.isinf(value) or abs(value) > _F32_MAX:
                raise ValueError(f"{name} must be finite and within +-{_F32_MAX:.7g} (float32), got {value!r}")
            object.__setattr__(self, name, value)
        if not self.frame_rate_hz >= 0:
            raise ValueError(f"frame_rate_hz must be a number >= 0 Hz, got {self.frame_rate_hz!r}")
        if math.isnan(self.gain):
            raise ValueError(f"gain must be a finite number (camera gain units), got {self.gain!r}")
        if not (math.isnan(self.cpu_load) or 0.0 <= self.cpu_load <= 1.0):
            raise ValueError(f"cpu_load must be in [0, 1] (or nan when unknown), got {self.cpu_load!r}")
        counters = tuple((str(name), value) for name, value in self.counters)
        if len(counters) > MAX_COUNTERS:
            raise ValueError(f"counters holds {len(counters)} entries, at most {MAX_COUNTERS}")
        counters = tuple(
            (_check_text("counter name", name, 32), check_int(f"counter {name!r}", value, high=_U64))
            for name, value in counters
        )
        object.__setattr__(self, "counters", counters)

    def pack(self, t_ns_ref: int = 0) -> bytes:
        """Return the payload bytes."""
        w = ByteWriter()
        w.fixed("f", self.frame_rate_hz)
        for value in (self.frames_captured, self.frames_dropped, self.messages_dropped, self.exposure_us):
            w.uvarint(value)
        w.fixed("f", self.gain)
        w.uvarint(self.uptime_ns)
        w.fixed("f", self.cpu_load)
        w.fixed("f", self.temperature_c)
        w.uvarint(len(self.counters))
        for name, value in self.counters:
            w.blob(name.encode("utf-8"))
            w.uvarint(value)
        return w.getvalue()

    @classmethod
    def unpack(cls, payload: bytes, t_ns_ref: int = 0) -> Status:
        """Parse a payload written by `pack`."""
        r = ByteReader(payload)
        rate = r.fixed("f", "frame_rate_hz")
        captured = r.uvarint("frames_captured")
        dropped = r.uvarint("frames_dropped")
        messages_dropped = r.uvarint("messages_dropped")
        exposure = r.uvarint("exposure_us", _U32)
        gain = r.fixed("f", "gain")
        uptime = r.uvarint("uptime_ns")
        load = r.fixed("f", "cpu_load")
        temperature = r.fixed("f", "temperature_c")
        counters = []
        for _ in range(r.uvarint("counter count", MAX_COUNTERS)):
            name = r.text("counter name", 32)
            counters.append((name, r.uvarint(f"counter {name!r}")))
        r.finish("Status")
        return cls(
            rate, captured, dropped, messages_dropped, exposure, gain, uptime, load, temperature, tuple(counters)
        )


@register_record
@dataclass(frozen=True, slots=True)
class Log:
    """A log line from the device: `level` is Python's logging level number (10 debug ... 50 critical)."""

    TYPE: ClassVar[MessageType] = MessageType.LOG

    level: int
    text: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "level", check_int("level", self.level, high=255))
        _check_text("text", self.text, MAX_TEXT_BYTES)

    def pack(self, t_ns_ref: int = 0) -> bytes:
        """Return the payload bytes."""
        w = ByteWriter()
        w.raw(bytes([self.level]))
        w.blob(self.text.encode("utf-8"))
        return w.getvalue()

    @classmethod
    def unpack(cls, payload: bytes, t_ns_ref: int = 0) -> Log:
        """Parse a payload written by `pack`."""
        r = ByteReader(payload)
        level = r.raw(1, "level")[0]
        text = r.text("text", MAX_TEXT_BYTES)
        r.finish("Log")
        return cls(level, text)


class Command(IntEnum):
    """What a Control message asks the device to do; the values each takes are in `COMMAND_VALUES`."""

    SET_EXPOSURE = 1
    """values: (exposure_us,)"""
    SET_GAIN = 2
    """values: (gain,) analogue gain in the camera's own units (an integer: the V4L2 gain control), not dB"""
    SET_THRESHOLDS = 3
    """values: (low, high) edge thresholds, grey levels"""
    RESET_ROI = 4
    START = 5
    STOP = 6
    REQUEST_RAW_FRAME = 7
    """The device answers with RawFrameChunk messages of its next frame."""
    SET_MATERIAL_POINTS = 8
    """values: arc lengths s in metres of unstretched rope, 1..64 of them"""


COMMAND_VALUES: Final[dict[Command, tuple[int, int]]] = {
    Command.SET_EXPOSURE: (1, 1),
    Command.SET_GAIN: (1, 1),
    Command.SET_THRESHOLDS: (2, 2),
    Command.RESET_ROI: (0, 0),
    Command.START: (0, 0),
    Command.STOP: (0, 0),
    Command.REQUEST_RAW_FRAME: (0, 0),
    Command.SET_MATERIAL_POINTS: (1, 64),
}
"""Smallest and largest number of values per command."""


@register_record
@dataclass(frozen=True, slots=True)
class Control:
    """A command from the host. The device applies it only with a valid tag and a fresh counter (`auth`)."""

    TYPE: ClassVar[MessageType] = MessageType.CONTROL

    command: Command
    values: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "command", Command(self.command))
        values = tuple(float(v) for v in self.values)
        low, high = COMMAND_VALUES[self.command]
        if not low <= len(values) <= high or not all(math.isfinite(v) for v in values):
            raise ValueError(f"{self.command.name} takes {low}..{high} finite values, got {values}")
        object.__setattr__(self, "values", values)

    def pack(self, t_ns_ref: int = 0) -> bytes:
        """Return the payload bytes."""
        w = ByteWriter()
        w.raw(bytes([self.command]))
        w.uvarint(len(self.values))
        for value in self.values:
            w.fixed("d", value)
        return w.getvalue()

    @classmethod
    def unpack(cls, payload: bytes, t_ns_ref: int = 0) -> Control:
        """Parse a payload written by `pack`."""
        r = ByteReader(payload)
        code = r.raw(1, "command")[0]
        try:
            command = Command(code)
        except ValueError as exc:
            raise ProtocolError(f"Control: unknown command {code}") from exc
        values = tuple(float(r.fixed("d", "value")) for _ in range(r.uvarint("value count", 64)))
        r.finish("Control")
        return cls(command, values)


class AckResult(IntEnum):
    """Outcome of an authenticated Control message."""

    APPLIED = 0
    INVALID = 1
    """The values are out of range for the device."""
    UNSUPPORTED = 2
    FAILED = 3
    """The device tried and failed (the detail says why)."""


@register_record
@dataclass(frozen=True, slots=True)
class ControlAck:
    """The device's answer to an authenticated Control message (forged or replayed ones get no answer)."""

    TYPE: ClassVar[MessageType] = MessageType.CONTROL_ACK

    acked_sequence: int
    command: Command
    result: AckResult
    detail: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "acked_sequence", check_int("acked_sequence", self.acked_sequence, high=_U32))
        object.__setattr__(self, "command", Command(self.command))
        object.__setattr__(self, "result", AckResult(self.result))
        _check_text("detail", self.detail, 256)

    def pack(self, t_ns_ref: int = 0) -> bytes:
        """Return the payload bytes."""
        w = ByteWriter()
        w.fixed("I", self.acked_sequence)
        w.raw(bytes([self.command, self.result]))
        w.blob(self.detail.encode("utf-8"))
        return w.getvalue()

    @classmethod
    def unpack(cls, payload: bytes, t_ns_ref: int = 0) -> ControlAck:
        """Parse a payload written by `pack`."""
        r = ByteReader(payload)
        sequence = int(r.fixed("I", "acked_sequence"))
        command_code, result_code = r.raw(2, "command and result")
        detail = r.text("detail", 256)
        r.finish("ControlAck")
        try:
            return cls(sequence, Command(command_code), AckResult(result_code), detail)
        except ValueError as exc:
            raise ProtocolError(f"ControlAck: {exc}") from exc


class PixelFormat(IntEnum):
    """Pixel layout of a raw frame."""

    GRAY8 = 1


@register_record
@dataclass(frozen=True, slots=True)
class RawFrameChunk:
    """One piece of a whole camera frame (`rawframe.split_frame` cuts, `rawframe.FrameAssembler` joins)."""

    TYPE: ClassVar[MessageType] = MessageType.RAW_FRAME_CHUNK

    frame_index: int
    width: int
    height: int
    pixel_format: PixelFormat
    chunk_index: int
    chunk_count: int
    offset: int
    data: bytes

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        put("frame_index", check_int("frame_index", self.frame_index, high=_U32))
        put("width", check_int("width", self.width, low=1, high=_U16))
        put("height", check_int("height", self.height, low=1, high=_U16))
        put("pixel_format", PixelFormat(self.pixel_format))
        put("chunk_count", check_int("chunk_count", self.chunk_count, low=1, high=_U16))
        put("chunk_index", check_int("chunk_index", self.chunk_index, high=self.chunk_count - 1))
        if not isinstance(self.data, bytes) or not 0 < len(self.data) <= MAX_CHUNK_BYTES:
            raise ValueError(f"data must be 1..{MAX_CHUNK_BYTES} bytes, got {type(self.data).__name__}")
        put("offset", check_int("offset", self.offset, high=self.frame_bytes - len(self.data)))

    @property
    def frame_bytes(self) -> int:
        """Size of the whole frame in bytes."""
        return self.width * self.height

    def pack(self, t_ns_ref: int = 0) -> bytes:
        """Return the payload bytes."""
        w = ByteWriter()
        w.fixed("I", self.frame_index)
        w.fixed("H", self.width)
        w.fixed("H", self.height)
        w.raw(bytes([self.pixel_format]))
        w.fixed("H", self.chunk_index)
        w.fixed("H", self.chunk_count)
        w.fixed("I", self.offset)
        w.raw(self.data)
        return w.getvalue()

    @classmethod
    def unpack(cls, payload: bytes, t_ns_ref: int = 0) -> RawFrameChunk:
        """Parse a payload written by `pack`."""
        r = ByteReader(payload)
        frame_index = int(r.fixed("I", "frame_index"))
        width = int(r.fixed("H", "width"))
        height = int(r.fixed("H", "height"))
        format_code = r.raw(1, "pixel format")[0]
        chunk_index = int(r.fixed("H", "chunk_index"))
        chunk_count = int(r.fixed("H", "chunk_count"))
        offset = int(r.fixed("I", "offset"))
        data = r.raw(r.remaining, "data")
        try:
            return cls(frame_index, width, height, PixelFormat(format_code), chunk_index, chunk_count, offset, data)
        except ValueError as exc:
            raise ProtocolError(f"RawFrameChunk: {exc}") from exc
