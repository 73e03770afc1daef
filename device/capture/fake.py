"""An in-process V4L2 camera behind the `V4l2Driver` interface, for tests and demos without hardware.

`FakeCamera` holds the device state (formats, controls, the sequence counter, buffers); the test drives time by
calling `FakeCamera.deliver`, which fills the next free buffer like a driver does at the end of each frame, or
drops the frame (sequence number used, no buffer) when the consumer holds all buffers. `FakeCamera.vanish` makes
every later call fail with ENODEV, as an unplugged USB camera does. Nothing sleeps.
"""

from __future__ import annotations

import errno
import os
from collections import deque
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from ropecam.device.capture.driver import (
    ControlInfo,
    DriverBuffer,
    DriverFactory,
    FormatInfo,
    FrameSizeInfo,
    NegotiatedFormat,
    TimestampSource,
    V4l2Driver,
)

__all__ = ["FakeCamera", "FakeV4l2Driver", "fake_factory", "fake_pattern", "uvc_like_camera"]

_BYTES_PER_PIXEL = {"GREY": 1, "YUYV": 2, "MJPG": 2}


def _os_error(code: int, what: str) -> OSError:
    return OSError(code, os.strerror(code), what)


def fake_pattern(sequence: int, width: int, height: int) -> NDArray[np.uint8]:
    """Return the luma image the fake camera produces for frame `sequence` (a ramp shifted by the sequence)."""
    rows = np.arange(height, dtype=np.int64)[:, None]
    cols = np.arange(width, dtype=np.int64)[None, :]
    return ((rows * 3 + cols + sequence * 7) % 256).astype(np.uint8)


def uvc_like_camera(path: str = "/dev/video0", **kwargs: object) -> FakeCamera:
    """Return a fake camera shaped like a global-shutter UVC board camera (GREY and YUYV, 119/60/30 fps)."""
    sizes = (
        FrameSizeInfo(1280, 800, (119.0, 60.0, 30.0)),
        FrameSizeInfo(1024, 544, (119.0, 60.0, 30.0)),
        FrameSizeInfo(64, 32, (119.0, 60.0, 30.0)),
    )
    formats = [
        FormatInfo("MJPG", "Motion-JPEG", sizes),
        FormatInfo("GREY", "8-bit Greyscale", sizes),
        FormatInfo("YUYV", "YUYV 4:2:2", sizes),
    ]
    controls = {
        "auto_exposure": ControlInfo(
            "auto_exposure", "menu", 0, 3, 1, 3, 3, {1: "Manual Mode", 3: "Aperture Priority Mode"}
        ),
        "exposure_time_absolute": ControlInfo("exposure_time_absolute", "int", 1, 5000, 1, 157, 157),
        "exposure_dynamic_framerate": ControlInfo("exposure_dynamic_framerate", "bool", 0, 1, 1, 1, 1),
        "gain": ControlInfo("gain", "int", 0, 100, 1, 0, 0),
        "brightness": ControlInfo("brightness", "int", -64, 64, 1, 0, 0),
    }
    return FakeCamera(path, formats, controls, **kwargs)  # type: ignore[arg-type]


class FakeCamera:
    """The state of one fake camera node.

    Parameters
    ----------
    path
        Its device node name.
    formats
        Formats offered, with sizes and rates; `set_format` snaps to the nearest listed size like real drivers.
    controls
        Controls by name; values are kept and range-checked (EINVAL/ERANGE as the kernel does).
    row_padding
        Extra bytes at the end of each row (bytes_per_line > width * bytes per pixel).
    timestamp_source
        What the timestamps mark.
    t0_ns
        Timestamp of sequence 0.
    card
        Card name reported by `info`.
    """

    def __init__(
        self,
        path: str,
        formats: Sequence[FormatInfo],
        controls: Mapping[str, ControlInfo],
        row_padding: int = 0,
        timestamp_source: TimestampSource = TimestampSource.START_OF_EXPOSURE,
        t0_ns: int = 5_000_000_000,
        card: str = "Fake global-shutter camera",
    ) -> None:
        self.path = path
        self.format_list = list(formats)
        self.control_info = dict(controls)
        self.values = {name: (c.value if c.value is not None else 0) for name, c in controls.items()}
        self.control_log: list[tuple[str, int]] = []
        self.row_padding = row_padding
        self.timestamp_source = timestamp_source
        self.t0_ns = t0_ns
        self.card = card
        self.vanished = False
        self.busy = False
        first = self.format_list[0]
        size = first.sizes[0] if first.sizes else FrameSizeInfo(640, 480, (30.0,))
        self.format = self._negotiate(size.width, size.height, first.fourcc)
        self.fps = size.fps[0] if size.fps else 30.0
        self.sequence = 0
        self.streaming = False
        self.buffers: list[NDArray[np.uint8]] = []
        self.free: deque[int] = deque()  # queued, waiting to be filled
        self.done: deque[DriverBuffer] = deque()  # filled, waiting to be dequeued
        self.opened = 0
        self.on_wait: Callable[[FakeCamera], None] | None = None

    def _negotiate(self, width: int, height: int, fourcc: str) -> NegotiatedFormat:
        info = next((f for f in self.format_list if f.fourcc == fourcc), self.format_list[0])
        if info.sizes:
            size = min(info.sizes, key=lambda s: abs(s.width - width) + abs(s.height - height))
            width, height = size.width, size.height
        bytes_per_line = width * _BYTES_PER_PIXEL.get(info.fourcc, 1) + self.row_padding
        return NegotiatedFormat(width, height, info.fourcc, bytes_per_line, bytes_per_line * height)

    def vanish(self) -> None:
        """Unplug the camera: every later call on it fails with ENODEV."""
        self.vanished = True

    def reconnect(self) -> None:
        """Plug the camera back in: a fresh node, not streaming, that opens again."""
        self.vanished = False
        self.streaming = False
        self.free.clear()
        self.done.clear()

    def deliver(self, count: int = 1, error: bool = False, short: bool = False) -> int:
        """Let `count` frame periods pass; returns how many frames found a free buffer (the rest are dropped).

        `error` marks the delivered buffers with V4L2_BUF_FLAG_ERROR; `short` fills them only halfway.
        """
        if not self.streaming:
            raise RuntimeError("deliver() while the fake camera is not streaming")
        filled = 0
        fmt = self.format
        for _ in range(count):
            sequence = self.sequence
            self.sequence += 1
            if not self.free:
                continue  # the driver had no buffer: the frame is lost, its sequence number skipped
            index = self.free.popleft()
            data = self.buffers[index]
            data[:] = 0
            rows = data[: fmt.size_image].reshape(fmt.height, fmt.bytes_per_line)
            luma = fake_pattern(sequence, fmt.width, fmt.height)
            if fmt.fourcc == "YUYV":
                rows[:, 0 : 2 * fmt.width : 2] = luma
                rows[:, 1 : 2 * fmt.width : 2] = 128
            else:
                rows[:, : fmt.width] = luma
            t_ns = self.t0_ns + round(sequence * 1e9 / self.fps)
            used = fmt.size_image // 2 if short else fmt.size_image
            self.done.append(DriverBuffer(index, sequence, t_ns, self.timestamp_source, used, data, error))
            filled += 1
        return filled


class FakeV4l2Driver(V4l2Driver):
    """A `V4l2Driver` over a `FakeCamera`."""

    def __init__(self, camera: FakeCamera) -> None:
        if camera.vanished:
            raise _os_error(errno.ENOENT, camera.path)
        if camera.busy:
            raise _os_error(errno.EBUSY, camera.path)
        self.camera = camera
        self.path = camera.path
        self.closed = False
        camera.opened += 1

    def _check(self) -> FakeCamera:
        if self.camera.vanished:
            raise _os_error(errno.ENODEV, self.path)
        if self.closed:
            raise _os_error(errno.EBADF, self.path)
        return self.camera

    def info(self) -> dict[str, str]:
        return {"card": self._check().card, "driver": "fake", "bus_info": "fake:0"}

    def formats(self) -> list[FormatInfo]:
        return list(self._check().format_list)

    def get_format(self) -> NegotiatedFormat:
        return self._check().format

    def set_format(self, width: int, height: int, fourcc: str) -> NegotiatedFormat:
        camera = self._check()
        if camera.streaming:
            raise _os_error(errno.EBUSY, self.path)
        camera.format = camera._negotiate(width, height, fourcc)
        return camera.format

    def get_fps(self) -> float:
        return self._check().fps

    def set_fps(self, fps: float) -> float:
        camera = self._check()
        info = next(f for f in camera.format_list if f.fourcc == camera.format.fourcc)
        rates = [
            r for s in info.sizes if (s.width, s.height) == (camera.format.width, camera.format.height) for r in s.fps
        ]
        camera.fps = min(rates, key=lambda r: abs(r - fps)) if rates else fps
        return camera.fps

    def controls(self) -> dict[str, ControlInfo]:
        camera = self._check()
        return {
            name: ControlInfo(c.name, c.kind, c.minimum, c.maximum, c.step, c.default, camera.values[name], c.menu)
            for name, c in camera.control_info.items()
        }

    def get_control(self, name: str) -> int:
        camera = self._check()
        if name not in camera.values:
            raise _os_error(errno.EINVAL, name)
        return camera.values[name]

    def set_control(self, name: str, value: int) -> None:
        camera = self._check()
        info = camera.control_info.get(name)
        if info is None:
            raise _os_error(errno.EINVAL, name)
        if info.menu and value not in info.menu:
            raise _os_error(errno.EINVAL, f"{name}={value}")
        if info.minimum is not None and info.maximum is not None and not info.minimum <= value <= info.maximum:
            raise _os_error(errno.ERANGE, f"{name}={value}")
        camera.values[name] = int(value)
        camera.control_log.append((name, int(value)))

    def start(self, buffer_count: int) -> int:
        camera = self._check()
        size = camera.format.size_image
        camera.buffers = [np.zeros(size, dtype=np.uint8) for _ in range(buffer_count)]
        camera.free = deque(range(buffer_count))
        camera.done.clear()
        camera.sequence = 0
        camera.streaming = True
        return buffer_count

    def wait(self, timeout_s: float) -> bool:
        camera = self._check()
        if not camera.done and camera.on_wait is not None:
            camera.on_wait(camera)
            camera = self._check()
        return bool(camera.done)

    def dequeue(self) -> DriverBuffer | None:
        camera = self._check()
        return camera.done.popleft() if camera.done else None

    def queue(self, index: int) -> None:
        camera = self._check()
        if index in camera.free or any(b.index == index for b in camera.done):
            raise _os_error(errno.EINVAL, f"buffer {index} queued twice")
        camera.free.append(index)

    def stop(self) -> None:
        camera = self._check()
        camera.streaming = False
        camera.free.clear()
        camera.done.clear()

    def close(self) -> None:
        self.closed = True


def fake_factory(*cameras: FakeCamera) -> DriverFactory:
    """Return a driver factory that opens the given fake cameras by path (ENOENT for any other path)."""
    by_path = {camera.path: camera for camera in cameras}

    def open_fake(path: str) -> V4l2Driver:
        camera = by_path.get(path)
        if camera is None:
            raise _os_error(errno.ENOENT, path)
        return FakeV4l2Driver(camera)

    return open_fake
