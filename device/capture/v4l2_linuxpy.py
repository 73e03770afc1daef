"""`V4l2Driver` on linuxpy (`linuxpy.video.device`): memory-mapped streaming with the kernel's own ioctls.

Kept deliberately thin: every method is one or two linuxpy calls, so everything worth testing lives in
`ropecam.device.capture.v4l2.V4l2Source` and is tested against the fake driver. The node is opened non-blocking:
`dequeue` returns None on EAGAIN and `wait` uses select(2), which also wakes up when the device is unplugged (the
next DQBUF then fails with ENODEV).
"""

from __future__ import annotations

import errno
import logging
import mmap
import select
from types import SimpleNamespace
from typing import Any

import numpy as np
from linuxpy.video import device as lvd
from numpy.typing import NDArray

from ropecam.device.capture.driver import (
    ControlInfo,
    DriverBuffer,
    FormatInfo,
    FrameSizeInfo,
    NegotiatedFormat,
    TimestampSource,
    V4l2Driver,
)

__all__ = ["LinuxpyDriver", "config_name", "fourcc_name"]

log = logging.getLogger(__name__)

_CAPTURE = lvd.BufferType.VIDEO_CAPTURE
_MMAP = lvd.Memory.MMAP
_TIMESTAMP_MASK = int(lvd.BufferFlag.TIMESTAMP_MASK)
_TIMESTAMP_MONOTONIC = int(lvd.BufferFlag.TIMESTAMP_MONOTONIC)
_TSTAMP_SRC_MASK = int(lvd.BufferFlag.TSTAMP_SRC_MASK)
_TSTAMP_SRC_SOE = int(lvd.BufferFlag.TSTAMP_SRC_SOE)
_FLAG_ERROR = int(lvd.BufferFlag.ERROR)
_HAS_PAYLOAD = int(lvd.ControlFlag.HAS_PAYLOAD)
_NOT_WRITABLE = int(
    lvd.ControlFlag.READ_ONLY | lvd.ControlFlag.DISABLED | lvd.ControlFlag.GRABBED | lvd.ControlFlag.INACTIVE
)
_MENU = int(lvd.ControlType.MENU)
_INTEGER_MENU = int(lvd.ControlType.INTEGER_MENU)
_SIMPLE_CONTROL_TYPES = frozenset(
    int(t)
    for t in (
        lvd.ControlType.INTEGER,
        lvd.ControlType.BOOLEAN,
        lvd.ControlType.MENU,
        lvd.ControlType.INTEGER_MENU,
        lvd.ControlType.INTEGER64,
        lvd.ControlType.BUTTON,
        lvd.ControlType.BITMASK,
    )
)


def fourcc_name(code: int) -> str:
    """Return the four characters of a V4L2 pixel-format code (``0x59455247`` -> ``"GREY"``)."""
    return int(code).to_bytes(4, "little").decode("ascii", errors="replace").rstrip()


def config_name(name: str) -> str:
    """Return a V4L2 control name as linuxpy and v4l2-ctl spell it (``"Exposure, Auto Priority"`` ->
    ``"exposure_auto_priority"``)."""
    name = name.lower().replace("(", "").replace(")", "").replace(",", "")
    return "_".join(name.split())


def _fps(value: object) -> float:
    return float(value) if value else 0.0  # type: ignore[arg-type]


class LinuxpyDriver(V4l2Driver):
    """Open V4L2 node `path` with linuxpy (non-blocking); raises `OSError` when it cannot."""

    def __init__(self, path: str) -> None:
        self.path = path
        self._device = lvd.Device(path, blocking=False)
        self._device.open()
        self._controls: dict[str, Any] | None = None
        self._maps: list[mmap.mmap] = []
        self._arrays: list[NDArray[np.uint8]] = []

    def info(self) -> dict[str, str]:
        info = self._device.info
        return {"card": info.card, "driver": info.driver, "bus_info": info.bus_info}

    def formats(self) -> list[FormatInfo]:
        info = self._device.info
        result = []
        for image_format in info.formats:
            if image_format.type != _CAPTURE:
                continue
            sizes: list[FrameSizeInfo] = []
            size_range = None
            for frame_size in info.format_frame_sizes(image_format.pixel_format):
                if frame_size.type == lvd.FrameSizeType.DISCRETE:
                    width, height = frame_size.info.width, frame_size.info.height
                    types = info.fps_intervals(image_format.pixel_format, width, height)
                    rates = tuple(sorted({_fps(t.max_fps) for t in types if t.min_fps == t.max_fps}, reverse=True))
                    ranges = [(_fps(t.min_fps), _fps(t.max_fps)) for t in types if t.min_fps != t.max_fps]
                    sizes.append(FrameSizeInfo(width, height, rates, ranges[0] if ranges else None))
                else:
                    s = frame_size.info
                    size_range = (s.min_width, s.max_width, s.min_height, s.max_height)
            fourcc = fourcc_name(image_format.pixel_format)
            result.append(FormatInfo(fourcc, image_format.description, tuple(sizes), size_range))
        return result

    def get_format(self) -> NegotiatedFormat:
        fmt = lvd.get_format(self._device, _CAPTURE)
        return NegotiatedFormat(fmt.width, fmt.height, fourcc_name(fmt.pixel_format), fmt.bytes_per_line, fmt.size)

    def set_format(self, width: int, height: int, fourcc: str) -> NegotiatedFormat:
        lvd.set_format(self._device, _CAPTURE, width, height, fourcc.ljust(4))
        return self.get_format()

    def get_fps(self) -> float:
        try:
            return float(lvd.get_fps(self._device, _CAPTURE))
        except ZeroDivisionError:  # driver reports no frame interval
            return 0.0

    def set_fps(self, fps: float) -> float:
        lvd.set_fps(self._device, _CAPTURE, fps)
        return self.get_fps()

    def _raw_controls(self) -> dict[str, Any]:
        """Query the controls once, by config name (raw `v4l2_query_ext_ctrl` records).

        Raw records rather than linuxpy's `Controls` objects: those refuse a whole device when one control has an
        odd range, and silently clip values; here every value is range-checked by `V4l2Source` and written as is.
        """
        if self._controls is None:
            found = {}
            for info in lvd.iter_read_controls(self._device):
                if info.type not in _SIMPLE_CONTROL_TYPES or info.flags & _HAS_PAYLOAD:
                    continue  # class headers, strings, compound controls
                found[config_name(info.name.decode(errors="replace"))] = info
            self._controls = found
        return self._controls

    def _menu(self, info: Any) -> dict[int, str]:
        if info.type not in (_MENU, _INTEGER_MENU):
            return {}
        shim = SimpleNamespace(id=info.id, _info=info)
        return {
            int(item.index): item.name.decode(errors="replace") if info.type == _MENU else str(item.value)
            for item in lvd.iter_read_menu(self._device, shim)
        }

    def controls(self) -> dict[str, ControlInfo]:
        result = {}
        for name, info in self._raw_controls().items():
            try:
                value = int(lvd.get_controls_values(self._device, (info,))[0])
            except OSError:
                value = None  # write-only or inactive controls cannot be read
            result[name] = ControlInfo(
                name=name,
                kind=lvd.ControlType(info.type).name.lower(),
                minimum=int(info.minimum),
                maximum=int(info.maximum),
                step=int(info.step),
                default=int(info.default_value),
                value=value,
                menu=self._menu(info),
                writable=not info.flags & _NOT_WRITABLE,
            )
        return result

    def _control(self, name: str) -> Any:
        info = self._raw_controls().get(name)
        if info is None:
            raise OSError(errno.EINVAL, f"no control {name!r}", self.path)
        return info

    def get_control(self, name: str) -> int:
        return int(lvd.get_controls_values(self._device, (self._control(name),))[0])

    def set_control(self, name: str, value: int) -> None:
        lvd.set_controls_values(self._device, ((self._control(name), int(value)),))

    def start(self, buffer_count: int) -> int:
        request = lvd.request_buffers(self._device, _CAPTURE, _MMAP, buffer_count)
        for index in range(request.count):
            buffer = lvd.query_buffer(self._device, _CAPTURE, _MMAP, index)
            mapped = lvd.mmap_from_buffer(self._device, buffer)
            self._maps.append(mapped)
            self._arrays.append(np.frombuffer(mapped, dtype=np.uint8))
            lvd.enqueue_buffer(self._device, _CAPTURE, _MMAP, 0, index)
        lvd.stream_on(self._device, _CAPTURE)
        return int(request.count)

    def wait(self, timeout_s: float) -> bool:
        readable, _, failed = select.select((self._device,), (), (self._device,), timeout_s)
        return bool(readable or failed)

    def dequeue(self) -> DriverBuffer | None:
        try:
            buffer = lvd.dequeue_buffer(self._device, _CAPTURE, _MMAP)
        except BlockingIOError:
            return None
        flags = int(buffer.flags)
        if flags & _TIMESTAMP_MASK != _TIMESTAMP_MONOTONIC:
            source = TimestampSource.NOT_MONOTONIC
        elif flags & _TSTAMP_SRC_MASK == _TSTAMP_SRC_SOE:
            source = TimestampSource.START_OF_EXPOSURE
        else:
            source = TimestampSource.END_OF_FRAME
        t_ns = int(buffer.timestamp.secs) * 1_000_000_000 + int(buffer.timestamp.usecs) * 1000
        return DriverBuffer(
            int(buffer.index),
            int(buffer.sequence),
            t_ns,
            source,
            int(buffer.bytesused),
            self._arrays[buffer.index],
            bool(flags & _FLAG_ERROR),
        )

    def queue(self, index: int) -> None:
        lvd.enqueue_buffer(self._device, _CAPTURE, _MMAP, 0, index)

    def stop(self) -> None:
        try:
            lvd.stream_off(self._device, _CAPTURE)
        finally:
            self._arrays.clear()
            for mapped in self._maps:
                try:
                    mapped.close()
                except BufferError:
                    log.debug("%s: a frame view is still alive; the mapping closes with it", self.path)
            self._maps.clear()
            try:
                lvd.free_buffers(self._device, _CAPTURE, _MMAP)
            except OSError as exc:  # EBUSY while a mapping lives on; closing the node frees them
                log.debug("%s: buffers not freed before close: %s", self.path, exc)

    def close(self) -> None:
        self._device.close()
