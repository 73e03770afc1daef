"""`V4l2Driver` on OpenCV's V4L2 backend (``cv2.VideoCapture(path, cv2.CAP_V4L2)``), the fallback without linuxpy.

OpenCV hides the V4L2 buffer queue, so this driver is weaker than the linuxpy one, and says so:

- no format or control listing: GREY and YUYV are offered "unverified" and the granted format is read back;
- no driver sequence numbers: they are derived from the buffer timestamps (``CAP_PROP_POS_MSEC``, the driver's
  monotonic timestamp in ms), a gap of n frame periods counting n - 1 drops;
- no newest-frame selection across queued buffers: each read takes the next frame OpenCV grabs, so keep
  ``buffer_count`` small (it sets ``CAP_PROP_BUFFERSIZE``);
- the timestamp is taken as the start of exposure (what uvcvideo reports); an unplugged camera is recognised by its
  device node disappearing after a failed grab.

Controls map to OpenCV properties that this backend passes to V4L2 unchanged: ``exposure_time_absolute`` to
``CAP_PROP_EXPOSURE`` (100 us units), ``auto_exposure`` to ``CAP_PROP_AUTO_EXPOSURE`` (1 = manual), ``gain`` to
``CAP_PROP_GAIN``. Images come raw (``CAP_PROP_CONVERT_RGB = 0``).
"""

from __future__ import annotations

import errno
import os
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.device.capture.driver import (
    ControlInfo,
    DriverBuffer,
    FormatInfo,
    NegotiatedFormat,
    TimestampSource,
    V4l2Driver,
)

__all__ = ["OpenCvDriver"]

_BYTES_PER_PIXEL = {"GREY": 1, "YUYV": 2}
_CONTROLS = {
    "auto_exposure": (cv2.CAP_PROP_AUTO_EXPOSURE, "menu", {1: "Manual Mode", 3: "Aperture Priority Mode"}),
    "exposure_time_absolute": (cv2.CAP_PROP_EXPOSURE, "int", {}),
    "gain": (cv2.CAP_PROP_GAIN, "int", {}),
}


def _fourcc_text(code: float) -> str:
    return int(code).to_bytes(4, "little").decode("ascii", errors="replace").rstrip("\x00 ")


class OpenCvDriver(V4l2Driver):
    """Open V4L2 node `path` through OpenCV; raises `OSError` when it cannot.

    Parameters
    ----------
    path
        Device node.
    capture_factory
        ``cv2.VideoCapture`` or a stand-in with the same methods (tests).
    """

    def __init__(self, path: str, capture_factory: Callable[[str, int], Any] | None = None) -> None:
        self.path = path
        self._cap = (capture_factory or cv2.VideoCapture)(path, cv2.CAP_V4L2)
        if not self._cap.isOpened():
            code = errno.EIO if os.path.exists(path) else errno.ENOENT
            raise OSError(code, "OpenCV's V4L2 backend cannot open the camera", path)
        self._cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
        self._pending: NDArray[np.uint8] | None = None
        self._pending_t_ns = 0
        self._sequence = -1
        self._last_t_ns: int | None = None
        self._buffer = np.zeros(0, dtype=np.uint8)

    def info(self) -> dict[str, str]:
        return {"card": "(not reported by OpenCV)", "driver": "opencv-v4l2", "bus_info": ""}

    def formats(self) -> list[FormatInfo]:
        return [FormatInfo(name, "unverified (OpenCV backend cannot list formats)") for name in _BYTES_PER_PIXEL]

    def get_format(self) -> NegotiatedFormat:
        width = int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        height = int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        fourcc = _fourcc_text(self._cap.get(cv2.CAP_PROP_FOURCC))
        row = width * _BYTES_PER_PIXEL.get(fourcc, 1)
        return NegotiatedFormat(width, height, fourcc, row, row * height)

    def set_format(self, width: int, height: int, fourcc: str) -> NegotiatedFormat:
        self._cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*fourcc.ljust(4)))
        self._cap.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        self._cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        return self.get_format()

    def get_fps(self) -> float:
        return float(self._cap.get(cv2.CAP_PROP_FPS))

    def set_fps(self, fps: float) -> float:
        self._cap.set(cv2.CAP_PROP_FPS, fps)
        return self.get_fps()

    def controls(self) -> dict[str, ControlInfo]:
        return {
            name: ControlInfo(name, kind, value=int(self._cap.get(prop)), menu=dict(menu))
            for name, (prop, kind, menu) in _CONTROLS.items()
        }

    def get_control(self, name: str) -> int:
        if name not in _CONTROLS:
            raise OSError(errno.EINVAL, f"no control {name!r} through OpenCV", self.path)
        return round(self._cap.get(_CONTROLS[name][0]))

    def set_control(self, name: str, value: int) -> None:
        if name not in _CONTROLS or not self._cap.set(_CONTROLS[name][0], value):
            raise OSError(errno.EINVAL, f"OpenCV could not set {name}={value}", self.path)

    def start(self, buffer_count: int) -> int:
        self._cap.set(cv2.CAP_PROP_BUFFERSIZE, buffer_count)
        self._sequence = -1
        self._last_t_ns = None
        return buffer_count

    def wait(self, timeout_s: float) -> bool:
        if self._pending is not None:
            return True
        self._cap.set(cv2.CAP_PROP_READ_TIMEOUT_MSEC, max(1, round(timeout_s * 1000)))
        if not self._cap.grab():
            if not os.path.exists(self.path):
                raise OSError(errno.ENODEV, "camera node disappeared", self.path)
            return False
        ok, raw = self._cap.retrieve()
        if not ok or raw is None:
            raise OSError(errno.EIO, "OpenCV grabbed a frame but could not retrieve it", self.path)
        self._pending = np.ascontiguousarray(raw, dtype=np.uint8).reshape(-1)
        self._pending_t_ns = round(self._cap.get(cv2.CAP_PROP_POS_MSEC) * 1e6)
        return True

    def dequeue(self) -> DriverBuffer | None:
        if self._pending is None:
            return None
        data, self._pending = self._pending, None
        t_ns = self._pending_t_ns
        fps = self.get_fps()
        if self._last_t_ns is not None and fps > 0 and t_ns > 0:
            self._sequence += max(1, round((t_ns - self._last_t_ns) * fps / 1e9))
        else:
            self._sequence += 1
        self._last_t_ns = t_ns
        source = TimestampSource.START_OF_EXPOSURE if t_ns > 0 else TimestampSource.NOT_MONOTONIC
        # Anything but the raw image size (e.g. a BGR conversion the backend did anyway) is not usable as luma.
        wrong_size = data.size != self.get_format().size_image
        return DriverBuffer(0, self._sequence, t_ns, source, int(data.size), data, error=wrong_size)

    def queue(self, index: int) -> None:
        """OpenCV requeues its buffers itself."""

    def stop(self) -> None:
        self._pending = None

    def close(self) -> None:
        self._cap.release()
