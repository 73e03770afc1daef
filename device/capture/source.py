"""The frame-source interface the rig daemon reads: `CameraSource`, `CapturedFrame` and `CaptureCounters`.

Every source (a V4L2 camera, a recorded frame set) hands over the NEWEST frame on each `CameraSource.read` and
counts what it could not hand over:

- ``skipped``: frames that arrived but were overtaken by a newer one before the consumer asked (newest-frame policy),
- ``dropped``: frames the driver never delivered, seen as gaps in the driver's sequence numbers (and frames the
  driver flagged as corrupt or short),
- ``timeouts``: reads that waited `timeout_s` without a frame.

``delivered + skipped + dropped`` therefore equals the span of sequence numbers seen since `start`.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass
from types import TracebackType
from typing import Final, Self

import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import CaptureError

__all__ = ["SEQUENCE_MODULUS", "CameraSource", "CaptureCounters", "CapturedFrame", "ControlUnsupportedError"]

log = logging.getLogger(__name__)

# V4L2 sequence numbers are u32 and wrap; gaps are computed modulo this.
SEQUENCE_MODULUS: Final = 2**32


class ControlUnsupportedError(ValueError):
    """The source has no such control at all (a recording has no exposure; a camera without a gain control)."""


@dataclass(frozen=True, slots=True)
class CapturedFrame:
    """One frame handed to the pipeline.

    Attributes
    ----------
    image
        (height, width) uint8, C-contiguous, read-only. A VIEW into the source's buffer (a mapped driver buffer or
        the preloaded frame set): valid only until the next `CameraSource.read` or `CameraSource.stop`; copy it to
        keep it.
    sequence
        The driver's frame sequence number (continues across loops of a recorded set).
    t_ns
        Start of the exposure, CLOCK_MONOTONIC in integer nanoseconds (driver timestamp).
    exposure_us
        Exposure time in microseconds in effect for this frame (the control value; a change takes a few frames).
    """

    image: NDArray[np.uint8]
    sequence: int
    t_ns: int
    exposure_us: int


@dataclass(slots=True)
class CaptureCounters:
    """Running counts of a source since `CameraSource.start` (see the module docstring)."""

    delivered: int = 0
    skipped: int = 0
    dropped: int = 0
    timeouts: int = 0

    def as_dict(self) -> dict[str, int]:
        """Return the counters as a plain dict (for Status messages and logs)."""
        return asdict(self)


class CameraSource(ABC):
    """A frame source: a context manager that hands over the newest frame on each `read`.

    Subclasses implement `_open`, `_close`, `_read` and the properties; this base keeps the counters, the
    started/stopped state and the sequence-gap accounting.
    """

    _last_sequence: int | None

    def __init__(self, name: str) -> None:
        self.name = name
        self.counters = CaptureCounters()
        self._started = False
        self._last_sequence = None

    # -- lifecycle -----------------------------------------------------------------------------------------------
    def start(self) -> None:
        """Open the device and start streaming; resets the counters.

        Raises
        ------
        CaptureError
            The device cannot be opened, configured or started (the message names it and the reason).
        """
        if self._started:
            return
        self.counters = CaptureCounters()
        self._last_sequence = None
        self._open()
        self._started = True

    def stop(self) -> None:
        """Stop streaming and release the device; never raises (errors are logged). Safe to call twice."""
        if not self._started:
            return
        self._started = False
        self._close()

    @property
    def started(self) -> bool:
        """True between `start` and `stop`."""
        return self._started

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    # -- frames --------------------------------------------------------------------------------------------------
    def read(self, timeout_s: float = 1.0) -> CapturedFrame | None:
        """Wait up to `timeout_s` for a frame and return the newest one available.

        Parameters
        ----------
        timeout_s
            Longest wait in seconds (>= 0; 0 polls).

        Returns
        -------
        CapturedFrame or None
            The newest frame (its image is valid until the next read); None on timeout (counted in
            ``counters.timeouts``) or when a finite recording has ended (`finished` is then True).

        Raises
        ------
        CaptureError
            The source is not started, or the device was lost (unplugged, driver error).
        """
        if not self._started:
            raise CaptureError(f"{self.name}: read() before start(): use the source as a context manager")
        if not timeout_s >= 0:
            raise ValueError(f"timeout_s must be >= 0, got {timeout_s!r}")
        frame = self._read(float(timeout_s))
        if frame is not None:
            self.counters.delivered += 1
        elif not self.finished:
            self.counters.timeouts += 1
        return frame

    @property
    def finished(self) -> bool:
        """True when a finite source (a recording without loop) has handed over its last frame."""
        return False

    def _count_sequence(self, sequence: int) -> None:
        """Count the frames missing between the previous sequence number and `sequence` as dropped."""
        last = self._last_sequence
        if last is not None:
            gap = (sequence - last - 1) % SEQUENCE_MODULUS
            # A huge "gap" is a counter that went backwards (driver restart), not four billion lost frames.
            if gap < SEQUENCE_MODULUS // 2:
                self.counters.dropped += gap
            else:
                log.warning("%s: sequence number went back from %d to %d", self.name, last, sequence)
        self._last_sequence = sequence

    # -- controls ------------------------------------------------------------------------------------------------
    def set_exposure_us(self, exposure_us: int) -> int:
        """Set the exposure time in microseconds; returns the exposure the device actually uses.

        Control errors are `ValueError` (report them and keep running); `CaptureError` means the device is lost.

        Raises
        ------
        ValueError
            `exposure_us` is out of the device's range or longer than the frame period, or the source has no manual
            exposure.
        CaptureError
            The device was lost while setting it.
        """
        raise ControlUnsupportedError(f"{self.name}: this source cannot change the exposure")

    def set_gain(self, gain: int) -> int:
        """Set the analogue gain in the device's own units; returns the value in effect.

        Raises
        ------
        ValueError
            The value is out of range or the source has no gain control.
        CaptureError
            The device was lost while setting it.
        """
        raise ControlUnsupportedError(f"{self.name}: this source has no gain control")

    def describe(self) -> dict[str, object]:
        """Return the settings in effect (for logs and Status): name, size, fps, exposure, pixel format."""
        width, height = self.image_size
        return {
            "source": self.name,
            "width": width,
            "height": height,
            "fps": self.fps,
            "exposure_us": self.exposure_us,
            "pixel_format": self.pixel_format,
        }

    @property
    @abstractmethod
    def image_size(self) -> tuple[int, int]:
        """(width, height) of the frames in pixels."""

    @property
    @abstractmethod
    def fps(self) -> float:
        """Frame rate in frames per second."""

    @property
    @abstractmethod
    def exposure_us(self) -> int:
        """Exposure time in microseconds."""

    @property
    @abstractmethod
    def pixel_format(self) -> str:
        """Pixel format the device delivers (FourCC such as ``GREY`` or ``YUYV``; ``frames`` for a recording)."""

    @abstractmethod
    def _open(self) -> None: ...

    @abstractmethod
    def _close(self) -> None: ...

    @abstractmethod
    def _read(self, timeout_s: float) -> CapturedFrame | None: ...
