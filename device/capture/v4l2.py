"""A V4L2 camera as a `CameraSource`: format negotiation, manual exposure in us, newest-frame reads, drop counting.

The source talks to the device only through a `V4l2Driver` (see `ropecam.device.capture.driver`): linuxpy by default,
OpenCV's CAP_V4L2 backend when linuxpy is not installed, or a fake in tests. It asks for GREY (8-bit luma, used as
is) or YUYV (the Y samples are copied out), the frame size and rate, switches exposure to manual
(``auto_exposure``/``exposure_auto`` = 1 "Manual Mode", ``exposure_dynamic_framerate``/``exposure_auto_priority`` = 0
so the driver never stretches the frame period) and sets ``exposure_time_absolute`` or the older
``exposure_absolute`` in the driver's 100 us units.

Each `read` requeues the buffer handed over last time, dequeues every filled buffer, keeps the newest and requeues
the others (counted as skipped); gaps in the driver's sequence numbers and buffers flagged corrupt or short count as
dropped. A GREY image without row padding is handed over without a copy: it stays dequeued until the next read.
"""

from __future__ import annotations

import errno
import logging
import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ropecam.device.capture.driver import (
    BYTES_PER_PIXEL,
    ControlInfo,
    DriverBuffer,
    DriverFactory,
    NegotiatedFormat,
    TimestampSource,
    V4l2Driver,
)
from ropecam.device.capture.source import CameraSource, CapturedFrame, ControlUnsupportedError
from ropecam.shared.errors import CaptureError

__all__ = [
    "AUTO_EXPOSURE_CONTROLS",
    "AUTO_PRIORITY_CONTROLS",
    "EXPOSURE_CONTROLS",
    "EXPOSURE_MANUAL",
    "EXPOSURE_UNIT_US",
    "GAIN_CONTROLS",
    "PIXEL_FORMATS",
    "V4l2Source",
    "default_driver_factory",
    "describe_os_error",
]

log = logging.getLogger(__name__)

# Control names as linuxpy spells them (V4L2 control name, lower case, punctuation to "_"); newer kernels first.
EXPOSURE_CONTROLS = ("exposure_time_absolute", "exposure_absolute")
AUTO_EXPOSURE_CONTROLS = ("auto_exposure", "exposure_auto")
AUTO_PRIORITY_CONTROLS = ("exposure_dynamic_framerate", "exposure_auto_priority")
GAIN_CONTROLS = ("gain", "analogue_gain")
AUTO_GAIN_CONTROLS = ("gain_automatic", "autogain")
EXPOSURE_UNIT_US = 100  # V4L2_CID_EXPOSURE_ABSOLUTE counts 100 us
EXPOSURE_MANUAL = 1  # V4L2_EXPOSURE_MANUAL in the auto-exposure menu

# Formats we can turn into an 8-bit luma image, in order of preference; "Y8" is accepted as a name for GREY.
PIXEL_FORMATS = ("GREY", "YUYV")
_ALIASES = {"Y8": "GREY", "Y800": "GREY", "GRAY": "GREY"}


def describe_os_error(path: str, exc: OSError) -> str:
    """Return a one-line explanation of an OS error on camera `path`, with the likely cause."""
    reason = exc.strerror or str(exc)
    hints = {
        errno.ENOENT: "no such device: is the camera plugged in? (`ropecam-device probe` lists cameras)",
        errno.EACCES: "permission denied: add the user to the `video` group",
        errno.EBUSY: "device busy: another program is using the camera",
        errno.ENODEV: "device vanished: camera unplugged or its driver reset",
        errno.ENXIO: "device vanished: camera unplugged or its driver reset",
        errno.EIO: "I/O error: cable, power or USB bandwidth problem",
    }
    hint = hints.get(exc.errno or 0)
    return f"camera {path}: {reason}" + (f" ({hint})" if hint else "")


def default_driver_factory(backend: str = "auto") -> DriverFactory:
    """Return the function that opens a V4L2 node: linuxpy, or OpenCV's CAP_V4L2 when linuxpy is missing.

    Parameters
    ----------
    backend
        ``"auto"``, ``"linuxpy"`` or ``"opencv"``.

    Raises
    ------
    CaptureError
        The requested backend is not installed.
    ValueError
        Unknown `backend`.
    """
    if backend not in ("auto", "linuxpy", "opencv"):
        raise ValueError(f"backend must be 'auto', 'linuxpy' or 'opencv', got {backend!r}")
    if backend in ("auto", "linuxpy"):
        try:
            from ropecam.device.capture.v4l2_linuxpy import LinuxpyDriver
        except ImportError as exc:
            if backend == "linuxpy":
                raise CaptureError(f"the linuxpy backend needs linuxpy: pip install 'ropecam[device]' ({exc})") from exc
            log.info("linuxpy not installed; using OpenCV's V4L2 backend (no driver sequence numbers)")
        else:
            return LinuxpyDriver
    from ropecam.device.capture.v4l2_opencv import OpenCvDriver

    return OpenCvDriver


def _check_gain_value(gain: object) -> None:
    if isinstance(gain, bool) or not isinstance(gain, int | np.integer):
        raise ValueError(f"gain must be an integer in the camera's units, got {gain!r}")


def _find(controls: dict[str, ControlInfo], names: tuple[str, ...]) -> ControlInfo | None:
    return next((controls[name] for name in names if name in controls), None)


class V4l2Source(CameraSource):
    """A V4L2 camera as a `CameraSource`.

    Parameters
    ----------
    path
        Device node, ``/dev/video0``.
    width, height
        Frame size in pixels; None keeps the driver's current size.
    fps
        Frame rate; None keeps the driver's. A rate the driver cannot grant within 2 % is an error.
    pixel_format
        ``"GREY"`` (alias ``"Y8"``) or ``"YUYV"``; None takes the first of those the camera offers.
    exposure_us
        Manual exposure time in microseconds; None leaves the camera's exposure settings alone.
    gain
        Analogue gain in the camera's units; None leaves it alone.
    buffer_count
        Driver buffers to stream into (2..32); one is held by the consumer between reads.
    driver_factory
        Opens the node (tests pass a fake); default: `default_driver_factory` with `backend`.
    backend
        ``"auto"``, ``"linuxpy"`` or ``"opencv"``, used when `driver_factory` is None.
    clock
        Monotonic clock in ns, used only when the driver's timestamps are not monotonic.
    """

    def __init__(
        self,
        path: str = "/dev/video0",
        width: int | None = None,
        height: int | None = None,
        fps: float | None = None,
        pixel_format: str | None = None,
        exposure_us: int | None = None,
        gain: int | None = None,
        buffer_count: int = 4,
        driver_factory: DriverFactory | None = None,
        backend: str = "auto",
        clock: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        super().__init__(f"v4l2://{path}")
        if (width is None) != (height is None):
            raise ValueError(f"give both width and height or neither, got width={width!r} height={height!r}")
        for label, value in (("width", width), ("height", height)):
            if value is not None and not (isinstance(value, int) and 0 < value <= 16384):
                raise ValueError(f"{label} must be an integer in [1, 16384], got {value!r}")
        if fps is not None and not (np.isfinite(fps) and 0 < fps <= 10_000):
            raise ValueError(f"fps must be in (0, 10000], got {fps!r}")
        if pixel_format is not None:
            pixel_format = _ALIASES.get(pixel_format.upper(), pixel_format.upper())
            if pixel_format not in PIXEL_FORMATS:
                raise ValueError(f"pixel_format must be one of GREY, Y8, YUYV, got {pixel_format!r}")
        if not (isinstance(buffer_count, int) and 2 <= buffer_count <= 32):
            raise ValueError(f"buffer_count must be an integer in [2, 32], got {buffer_count!r}")
        if gain is not None:
            _check_gain_value(gain)
        self.path = path
        self._requested = (width, height, fps, pixel_format)
        self._requested_exposure_us = exposure_us
        self._requested_gain = gain
        self.buffer_count = buffer_count
        self._factory = driver_factory or default_driver_factory(backend)
        self._clock = clock
        self._driver: V4l2Driver | None = None
        self._format = NegotiatedFormat(width or 0, height or 0, pixel_format or "", 0, 0)
        self._fps = float(fps or 0.0)
        if exposure_us is not None:
            self._check_exposure_value(exposure_us)  # the camera's own range is checked at `start`
        self._exposure_us = int(exposure_us or 0)
        self._controls: dict[str, ControlInfo] = {}
        self._held: int | None = None
        self._image: NDArray[np.uint8] | None = None
        self._lost: str | None = None
        self._warned_timestamps = False

    # -- properties ----------------------------------------------------------------------------------------------
    @property
    def image_size(self) -> tuple[int, int]:
        return self._format.width, self._format.height

    @property
    def fps(self) -> float:
        return self._fps

    @property
    def exposure_us(self) -> int:
        """Exposure time in us (0 when the camera has no exposure control and none was set)."""
        return self._exposure_us

    @property
    def pixel_format(self) -> str:
        return self._format.fourcc

    @property
    def driver(self) -> V4l2Driver:
        """The open driver (after `start`)."""
        if self._driver is None:
            raise CaptureError(f"{self.name}: not started")
        return self._driver

    # -- lifecycle -----------------------------------------------------------------------------------------------
    def _open(self) -> None:
        self._lost = None
        self._held = None
        try:
            self._driver = self._factory(self.path)
        except OSError as exc:
            raise CaptureError(describe_os_error(self.path, exc)) from exc
        try:
            self._configure(self._driver)
            granted = self._driver.start(self.buffer_count)
        except OSError as exc:
            self._release()
            raise CaptureError(describe_os_error(self.path, exc)) from exc
        except BaseException:
            self._release()
            raise
        log.info(
            "%s: streaming %dx%d %s at %.2f fps, exposure %d us, %d buffers",
            self.name,
            *self.image_size,
            self.pixel_format,
            self._fps,
            self._exposure_us,
            granted,
        )

    def _configure(self, driver: V4l2Driver) -> None:
        width, height, fps, fourcc = self._requested
        offered = {f.fourcc: f for f in driver.formats()}
        usable = [name for name in PIXEL_FORMATS if name in offered]
        if fourcc is None:
            if not usable:
                raise CaptureError(
                    f"{self.name}: the camera offers {', '.join(offered) or 'no formats'}; "
                    f"ropecam needs GREY (Y8) or YUYV"
                )
            candidates = usable
        elif fourcc not in offered:
            raise CaptureError(
                f"{self.name}: pixel format {fourcc} not offered; the camera offers {', '.join(offered)}"
            )
        else:
            candidates = [fourcc]
        if width is None or height is None:
            current = driver.get_format()
            width, height = current.width, current.height
        # Without a format asked for, take the first usable one the driver really grants (the OpenCV backend
        # cannot list formats, so its offer is a guess that set_format settles).
        for fourcc in candidates:
            granted = driver.set_format(width, height, fourcc)
            if (granted.width, granted.height, granted.fourcc) == (width, height, fourcc):
                break
        else:
            sizes = ", ".join(f"{s.width}x{s.height}" for s in offered[fourcc].sizes) or "not listed"
            raise CaptureError(
                f"{self.name}: asked for {width}x{height} {'/'.join(candidates)}, the driver granted "
                f"{granted.width}x{granted.height} {granted.fourcc}; sizes for {fourcc}: {sizes}"
            )
        row_bytes = width * BYTES_PER_PIXEL[fourcc]
        if granted.bytes_per_line < row_bytes:
            raise CaptureError(f"{self.name}: driver reports {granted.bytes_per_line} bytes per line, < {row_bytes}")
        self._format = granted
        if fourcc == "GREY" and granted.bytes_per_line == width:
            self._image = None  # zero copy: the mapped buffer is the image
        else:
            self._image = np.empty((height, width), dtype=np.uint8)
        if fps is not None:
            got = driver.set_fps(fps)
            if abs(got - fps) > 0.02 * fps:
                rates = sorted(
                    {r for s in offered[fourcc].sizes if (s.width, s.height) == (width, height) for r in s.fps}
                )
                listed = ", ".join(f"{r:g}" for r in rates) or "not listed"
                raise CaptureError(
                    f"{self.name}: asked for {fps:g} fps at {width}x{height} {fourcc}, the driver granted {got:g}; "
                    f"rates listed: {listed}"
                )
        self._fps = float(driver.get_fps())
        self._controls = driver.controls()
        try:
            if self._requested_exposure_us is not None:
                self._apply_exposure(driver, self._requested_exposure_us)
            else:
                exposure = _find(self._controls, EXPOSURE_CONTROLS)
                self._exposure_us = driver.get_control(exposure.name) * EXPOSURE_UNIT_US if exposure else 0
                auto = _find(self._controls, AUTO_EXPOSURE_CONTROLS)
                if auto is not None and driver.get_control(auto.name) != EXPOSURE_MANUAL:
                    log.warning(
                        "%s: exposure is automatic (%s = %s): motion blur will vary; set exposure_us",
                        self.name,
                        auto.name,
                        auto.menu.get(driver.get_control(auto.name), driver.get_control(auto.name)),
                    )
            if self._requested_gain is not None:
                self._apply_gain(driver, self._requested_gain)
        except ValueError as exc:
            raise CaptureError(f"{self.name}: cannot apply the settings: {exc}") from exc

    def _release(self) -> None:
        driver, self._driver = self._driver, None
        self._held = None
        if driver is None:
            return
        for step in (driver.stop, driver.close):
            try:
                step()
            except OSError as exc:
                log.warning("%s: %s while releasing the camera", self.name, describe_os_error(self.path, exc))

    def _close(self) -> None:
        self._release()

    # -- controls ------------------------------------------------------------------------------------------------
    def set_exposure_us(self, exposure_us: int) -> int:
        if self._driver is None:
            self._check_exposure_value(exposure_us)
            self._requested_exposure_us = int(exposure_us)
            return int(exposure_us)
        try:
            return self._apply_exposure(self._driver, exposure_us)
        except OSError as exc:
            raise CaptureError(describe_os_error(self.path, exc)) from exc

    def _check_exposure_value(self, exposure_us: int) -> None:
        if isinstance(exposure_us, bool) or not isinstance(exposure_us, int | np.integer) or exposure_us <= 0:
            raise ValueError(f"exposure_us must be a positive integer, got {exposure_us!r}")
        if self._fps > 0 and exposure_us > 1e6 / self._fps:
            period_us = 1e6 / self._fps
            raise ValueError(
                f"exposure_us={exposure_us} is longer than the frame period {period_us:.0f} us at {self._fps:g} fps"
            )

    def _apply_exposure(self, driver: V4l2Driver, exposure_us: int) -> int:
        self._check_exposure_value(exposure_us)
        exposure = _find(self._controls, EXPOSURE_CONTROLS)
        if exposure is None:
            raise ControlUnsupportedError(
                f"{self.name}: no exposure control (looked for {', '.join(EXPOSURE_CONTROLS)}); "
                f"controls: {', '.join(self._controls) or 'none'}"
            )
        auto = _find(self._controls, AUTO_EXPOSURE_CONTROLS)
        if auto is not None:
            if auto.menu and EXPOSURE_MANUAL not in auto.menu:
                raise ValueError(f"{self.name}: {auto.name} has no manual mode (menu {auto.menu})")
            driver.set_control(auto.name, EXPOSURE_MANUAL)
        priority = _find(self._controls, AUTO_PRIORITY_CONTROLS)
        if priority is not None and priority.writable:
            driver.set_control(priority.name, 0)
        units = round(exposure_us / EXPOSURE_UNIT_US)
        low, high, step = exposure.minimum, exposure.maximum, exposure.step or 1
        if low is not None and high is not None:
            if not low <= units <= high:
                raise ValueError(
                    f"exposure_us={exposure_us} out of the camera's range "
                    f"[{low * EXPOSURE_UNIT_US}, {high * EXPOSURE_UNIT_US}] us ({exposure.name} in 100 us units)"
                )
            units = min(high, low + round((units - low) / step) * step)
        driver.set_control(exposure.name, units)
        self._exposure_us = driver.get_control(exposure.name) * EXPOSURE_UNIT_US
        if self._exposure_us != exposure_us:
            log.info("%s: exposure %d us asked, %d us in effect", self.name, exposure_us, self._exposure_us)
        return self._exposure_us

    def set_gain(self, gain: int) -> int:
        """Set the analogue gain in the camera's units; returns the gain in effect.

        Before `start` the value is only checked for type (the camera's range is known once it is open) and applied
        at `start`.

        Raises
        ------
        ValueError
            `gain` is not an integer, is out of the camera's range, or the camera has no gain control.
        CaptureError
            The camera failed while the control was set.
        """
        _check_gain_value(gain)
        if self._driver is None:
            self._requested_gain = int(gain)
            return int(gain)
        try:
            return self._apply_gain(self._driver, gain)
        except OSError as exc:
            raise CaptureError(describe_os_error(self.path, exc)) from exc

    def _apply_gain(self, driver: V4l2Driver, gain: int) -> int:
        _check_gain_value(gain)
        control = _find(self._controls, GAIN_CONTROLS)
        if control is None:
            raise ControlUnsupportedError(
                f"{self.name}: this camera has no gain control (looked for {', '.join(GAIN_CONTROLS)})"
            )
        low, high = control.minimum, control.maximum
        if low is not None and high is not None and not low <= gain <= high:
            raise ValueError(f"gain={gain} out of the camera's range [{low}, {high}] ({control.name})")
        automatic = _find(self._controls, AUTO_GAIN_CONTROLS)
        if automatic is not None and automatic.writable:
            driver.set_control(automatic.name, 0)
        driver.set_control(control.name, int(gain))
        return driver.get_control(control.name)

    # -- frames --------------------------------------------------------------------------------------------------
    def _read(self, timeout_s: float) -> CapturedFrame | None:
        if self._lost is not None:
            raise CaptureError(self._lost)
        driver = self.driver
        try:
            if self._held is not None:
                held, self._held = self._held, None
                driver.queue(held)
            newest = self._dequeue_newest(driver, timeout_s)
        except OSError as exc:
            self._lost = describe_os_error(self.path, exc)
            raise CaptureError(self._lost) from exc
        if newest is None:
            return None
        self._held = newest.index
        return CapturedFrame(
            self._to_image(newest), newest.sequence, self._exposure_start_ns(newest), self._exposure_us
        )

    def _dequeue_newest(self, driver: V4l2Driver, timeout_s: float) -> DriverBuffer | None:
        deadline = time.monotonic() + timeout_s
        newest: DriverBuffer | None = None
        while True:
            buffer = driver.dequeue()
            if buffer is None:
                if newest is not None:
                    return newest
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not driver.wait(remaining):
                    return None
                continue
            self._count_sequence(buffer.sequence)
            if buffer.error or buffer.bytes_used < self._format.bytes_per_line * self._format.height:
                self.counters.dropped += 1
                driver.queue(buffer.index)
                if self.counters.dropped < 10 or self.counters.dropped % 1000 == 0:
                    log.warning(
                        "%s: frame %d corrupt or short (%d bytes); dropped (%d so far)",
                        self.name,
                        buffer.sequence,
                        buffer.bytes_used,
                        self.counters.dropped,
                    )
                continue
            if newest is not None:
                driver.queue(newest.index)
                self.counters.skipped += 1
            newest = buffer

    def _to_image(self, buffer: DriverBuffer) -> NDArray[np.uint8]:
        fmt = self._format
        rows = buffer.data[: fmt.bytes_per_line * fmt.height].reshape(fmt.height, fmt.bytes_per_line)
        if self._image is None:
            image = rows.view()
            image.flags.writeable = False
            return image
        if fmt.fourcc == "YUYV":
            np.copyto(self._image, rows[:, 0 : 2 * fmt.width : 2])
        else:
            np.copyto(self._image, rows[:, : fmt.width])
        image = self._image.view()
        image.flags.writeable = False
        return image

    def _exposure_start_ns(self, buffer: DriverBuffer) -> int:
        source = buffer.timestamp_source
        if source is TimestampSource.START_OF_EXPOSURE:
            return buffer.timestamp_ns
        if not self._warned_timestamps:
            self._warned_timestamps = True
            log.warning(
                "%s: driver timestamps %s; t_ns = %s minus the exposure time (readout time not known)",
                self.name,
                "mark the end of the frame" if source is TimestampSource.END_OF_FRAME else "are not monotonic",
                "timestamp" if source is TimestampSource.END_OF_FRAME else "time of dequeue",
            )
        end_ns = buffer.timestamp_ns if source is TimestampSource.END_OF_FRAME else self._clock()
        return end_ns - self._exposure_us * 1000
