"""Frame sources for the rig daemon: V4L2 cameras and recorded frame sets behind one interface.

Public API::

    from ropecam.device.capture import open_camera_source, CameraSource, CapturedFrame
    with open_camera_source("v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY", exposure_us=2000) as cam:
        frame = cam.read(timeout_s=1.0)      # newest frame or None; frame.image valid until the next read
        cam.counters                          # delivered, skipped, dropped, timeouts

- `ropecam.device.capture.config`: `CaptureConfig` (the ``[capture]`` table: source URL, fps, exposure_us, loop)
- `ropecam.device.capture.source`: `CameraSource`, `CapturedFrame`, `CaptureCounters`
- `ropecam.device.capture.v4l2`: `V4l2Source` (over a `V4l2Driver`: linuxpy, OpenCV fallback, or the fake)
- `ropecam.device.capture.replay`: `FrameSetSource` (recorded frame sets, paced or as fast as possible)
- `ropecam.device.capture.fake`: `FakeCamera`, `fake_factory` (an in-process camera for tests and demos)
- `ropecam.device.capture.probe`: `probe_cameras` and the `ropecam-device probe` command
- `ropecam.device.capture.frameset`: the frame-set format (reader and writer)

Importing this package does not import OpenCV or linuxpy; the modules that need them do.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__all__ = ["CameraSource", "CaptureCounters", "CapturedFrame", "open_camera_source"]

if TYPE_CHECKING:
    from ropecam.device.capture.source import CameraSource, CaptureCounters, CapturedFrame
    from ropecam.device.capture.url import open_camera_source


def __getattr__(name: str) -> Any:
    if name in ("CameraSource", "CaptureCounters", "CapturedFrame"):
        from ropecam.device.capture import source

        return getattr(source, name)
    if name == "open_camera_source":
        from ropecam.device.capture.url import open_camera_source

        return open_camera_source
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
