"""The thin V4L2 device layer `V4l2Source` talks to, and the records it exchanges.

`V4l2Driver` is the whole OS boundary: open a /dev/video node, list and set formats, frame rates and controls,
stream into mapped buffers, dequeue and requeue them. Implementations: `ropecam.device.capture.v4l2_linuxpy`
(linuxpy, the normal one), `ropecam.device.capture.v4l2_opencv` (OpenCV's CAP_V4L2, when linuxpy is missing) and
`ropecam.device.capture.fake` (an in-process camera for tests and demos). Drivers raise `OSError` (with the errno the
kernel gave) and leave the translation into `CaptureError` to the source.
"""

from __future__ import annotations

import enum
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType
from typing import Self

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ControlInfo",
    "DriverBuffer",
    "DriverFactory",
    "FormatInfo",
    "FrameSizeInfo",
    "NegotiatedFormat",
    "TimestampSource",
    "V4l2Driver",
]


class TimestampSource(enum.Enum):
    """What instant a driver timestamp marks (V4L2_BUF_FLAG_TSTAMP_SRC_* and TIMESTAMP_MONOTONIC)."""

    START_OF_EXPOSURE = "soe"
    END_OF_FRAME = "eof"
    NOT_MONOTONIC = "not-monotonic"


@dataclass(frozen=True, slots=True)
class FrameSizeInfo:
    """A frame size a format supports, with its frame rates (fps) or (min_fps, max_fps) when stepwise."""

    width: int
    height: int
    fps: tuple[float, ...] = ()
    fps_range: tuple[float, float] | None = None


@dataclass(frozen=True, slots=True)
class FormatInfo:
    """A pixel format the device offers: FourCC, description and sizes (empty when the driver lists none)."""

    fourcc: str
    description: str
    sizes: tuple[FrameSizeInfo, ...] = ()
    size_range: tuple[int, int, int, int] | None = None  # min_width, max_width, min_height, max_height


@dataclass(frozen=True, slots=True)
class NegotiatedFormat:
    """The format the driver granted: size, FourCC, bytes per line and bytes per image."""

    width: int
    height: int
    fourcc: str
    bytes_per_line: int
    size_image: int


@dataclass(frozen=True, slots=True)
class ControlInfo:
    """A device control by its V4L2 config name (``exposure_time_absolute``); ranges None when unknown."""

    name: str
    kind: str  # "int", "bool", "menu", "button", ...
    minimum: int | None = None
    maximum: int | None = None
    step: int | None = None
    default: int | None = None
    value: int | None = None
    menu: dict[int, str] = field(default_factory=dict)
    writable: bool = True


@dataclass(frozen=True, slots=True)
class DriverBuffer:
    """A dequeued buffer: its index (to requeue), sequence number, timestamp and bytes.

    `data` is a uint8 view of the mapped buffer (at least `bytes_used` long), valid until the buffer is requeued.
    """

    index: int
    sequence: int
    timestamp_ns: int
    timestamp_source: TimestampSource
    bytes_used: int
    data: NDArray[np.uint8]
    error: bool = False


class V4l2Driver(ABC):
    """One opened V4L2 capture node. Methods raise `OSError` on failure (errno as the kernel gave it)."""

    path: str

    @abstractmethod
    def info(self) -> dict[str, str]:
        """Return ``card``, ``driver`` and ``bus_info`` strings."""

    @abstractmethod
    def formats(self) -> list[FormatInfo]:
        """Return the capture formats with their sizes and frame rates."""

    @abstractmethod
    def get_format(self) -> NegotiatedFormat:
        """Return the current format."""

    @abstractmethod
    def set_format(self, width: int, height: int, fourcc: str) -> NegotiatedFormat:
        """Ask for a format; returns what the driver granted (it may differ)."""

    @abstractmethod
    def get_fps(self) -> float:
        """Return the frame rate in effect."""

    @abstractmethod
    def set_fps(self, fps: float) -> float:
        """Ask for a frame rate; returns the one granted."""

    @abstractmethod
    def controls(self) -> dict[str, ControlInfo]:
        """Return the controls by config name."""

    @abstractmethod
    def get_control(self, name: str) -> int:
        """Return a control's current value."""

    @abstractmethod
    def set_control(self, name: str, value: int) -> None:
        """Set a control."""

    @abstractmethod
    def start(self, buffer_count: int) -> int:
        """Allocate, map and queue `buffer_count` buffers and start streaming; returns the count granted."""

    @abstractmethod
    def wait(self, timeout_s: float) -> bool:
        """Wait until a buffer can be dequeued; False on timeout."""

    @abstractmethod
    def dequeue(self) -> DriverBuffer | None:
        """Dequeue a filled buffer without blocking; None when none is ready."""

    @abstractmethod
    def queue(self, index: int) -> None:
        """Give buffer `index` back to the driver."""

    @abstractmethod
    def stop(self) -> None:
        """Stop streaming and free the buffers."""

    @abstractmethod
    def close(self) -> None:
        """Close the device node."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


DriverFactory = Callable[[str], V4l2Driver]
"""Opens the node at a path (``/dev/video0``) and returns its driver; raises `OSError`."""
