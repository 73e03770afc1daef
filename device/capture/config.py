"""`CaptureConfig`: the ``[capture]`` table of the device config, validated when loaded."""

from __future__ import annotations

from dataclasses import dataclass

from ropecam.device.capture.driver import DriverFactory
from ropecam.device.capture.source import CameraSource
from ropecam.device.capture.url import open_camera_source, parse_source_url
from ropecam.shared.config import check_range, check_readout

__all__ = ["CaptureConfig"]


@dataclass(frozen=True, slots=True)
class CaptureConfig:
    """Where frames come from and how the camera is set.

    Attributes
    ----------
    source
        Source URL: ``v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY`` or ``frames:DIR?loop=1``
        (see docs/capture.md).
    fps
        Frame rate; overrides the URL's. None: the URL's, else the camera's or the recording's own.
    exposure_us
        Manual exposure in microseconds (cameras only); overrides the URL's. None leaves the camera's setting.
    loop
        Replay a frame set in a loop; overrides the URL's.
    read_timeout_s
        Longest wait for one frame before a read counts a timeout.
    readout_us
        The sensor's rolling-shutter frame readout time in microseconds (height line times, as datasheets give
        it); 0 = global shutter. Row r of a frame starts its exposure ``r / height * readout_us`` after row 0
        (docs/pipeline.md, "Time of a shape point"); at most the frame period.
    """

    source: str = "v4l2:///dev/video0"
    fps: float | None = None
    exposure_us: int | None = None
    loop: bool | None = None
    read_timeout_s: float = 1.0
    readout_us: int = 0

    def __post_init__(self) -> None:
        parse_source_url(self.source)
        if self.fps is not None:
            check_range("capture.fps", self.fps, 0.1, 10_000.0)
        if self.exposure_us is not None:
            check_range("capture.exposure_us", self.exposure_us, 1, 10_000_000)
        check_range("capture.read_timeout_s", self.read_timeout_s, 0.001, 60.0)
        check_readout("capture.readout_us", self.readout_us, self.fps)

    def open(self, driver_factory: DriverFactory | None = None) -> CameraSource:
        """Build the (not started) source; see `open_camera_source`."""
        return open_camera_source(
            self.source, fps=self.fps, exposure_us=self.exposure_us, loop=self.loop, driver_factory=driver_factory
        )
