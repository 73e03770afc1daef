"""The OS-facing drivers: OpenCV fallback against a stand-in VideoCapture, linuxpy's error path, backend choice."""

from __future__ import annotations

import itertools
import mmap
import os
import sys
from collections import deque
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from ropecam.device.capture.fake import fake_pattern
from ropecam.device.capture.v4l2 import V4l2Source, default_driver_factory
from ropecam.device.capture.v4l2_opencv import OpenCvDriver
from ropecam.shared.errors import CaptureError

W, H = 16, 8


class StandInCapture:
    """Enough of cv2.VideoCapture's V4L2 behaviour: properties, grab/retrieve, buffer timestamps in ms."""

    def __init__(self, fourcc: str = "GREY") -> None:
        self.props: dict[int, float] = {
            cv2.CAP_PROP_FRAME_WIDTH: W,
            cv2.CAP_PROP_FRAME_HEIGHT: H,
            cv2.CAP_PROP_FOURCC: cv2.VideoWriter.fourcc(*fourcc),
            cv2.CAP_PROP_FPS: 100.0,
            cv2.CAP_PROP_EXPOSURE: 157,
            cv2.CAP_PROP_AUTO_EXPOSURE: 3,
            cv2.CAP_PROP_GAIN: 0,
            cv2.CAP_PROP_POS_MSEC: 0.0,
        }
        self.frames: deque[tuple[float, np.ndarray]] = deque()
        self.current: np.ndarray | None = None
        self.released = False

    def open_as(self, path: str, api: int) -> StandInCapture:
        assert api == cv2.CAP_V4L2
        return self

    def isOpened(self) -> bool:
        return True

    def set(self, prop: int, value: float) -> bool:
        self.props[prop] = value
        return True

    def get(self, prop: int) -> float:
        return self.props.get(prop, 0.0)

    def grab(self) -> bool:
        if not self.frames:
            return False
        t_ms, self.current = self.frames.popleft()
        self.props[cv2.CAP_PROP_POS_MSEC] = t_ms
        return True

    def retrieve(self) -> tuple[bool, np.ndarray | None]:
        return self.current is not None, self.current

    def release(self) -> None:
        self.released = True


def _opencv_source(node: Path, capture: StandInCapture, **kwargs: object) -> V4l2Source:
    def factory(path: str) -> OpenCvDriver:
        return OpenCvDriver(path, capture_factory=capture.open_as)

    return V4l2Source(str(node), W, H, 100.0, driver_factory=factory, **kwargs)  # type: ignore[arg-type]


def test_opencv_fallback_frames_sequence_from_timestamps_and_exposure(tmp_path: Path) -> None:
    node = tmp_path / "video0"
    node.touch()
    capture = StandInCapture()
    for k in (0, 1, 4):  # frames 2 and 3 never came
        capture.frames.append((1000.0 + 10.0 * k, fake_pattern(k, W, H)))
    with _opencv_source(node, capture, exposure_us=2000) as source:
        assert capture.props[cv2.CAP_PROP_CONVERT_RGB] == 0
        assert capture.props[cv2.CAP_PROP_AUTO_EXPOSURE] == 1 and capture.props[cv2.CAP_PROP_EXPOSURE] == 20
        frames = [source.read(0.1) for _ in range(3)]
        assert [f.sequence for f in frames if f] == [0, 1, 4]
        assert [f.t_ns for f in frames if f] == [1_000_000_000 + k * 10_000_000 for k in (0, 1, 4)]
        np.testing.assert_array_equal(frames[2].image, fake_pattern(4, W, H))  # type: ignore[union-attr]
        assert source.counters.dropped == 2
        assert source.read(0.01) is None and source.counters.timeouts == 1
        node.unlink()  # unplugged: the node disappears
        with pytest.raises(CaptureError, match="device vanished"):
            source.read(0.01)
    assert capture.released


def test_opencv_fallback_yuyv_raw_and_a_converted_frame(tmp_path: Path) -> None:
    node = tmp_path / "video0"
    node.touch()
    capture = StandInCapture("YUYV")
    raw = np.full((H, 2 * W), 128, np.uint8)
    raw[:, 0::2] = fake_pattern(0, W, H)
    capture.frames.append((5.0, raw.reshape(1, -1)))  # OpenCV hands raw YUYV as one row of bytes
    capture.frames.append((15.0, np.zeros((H, W, 3), np.uint8)))  # a BGR image is no luma: dropped
    with _opencv_source(node, capture, pixel_format="YUYV") as source:
        frame = source.read(0.1)
        assert frame is not None
        np.testing.assert_array_equal(frame.image, fake_pattern(0, W, H))
        assert source.read(0.1) is None and source.counters.dropped == 1


def test_opencv_fallback_settles_on_yuyv_when_the_camera_refuses_grey(tmp_path: Path) -> None:
    node = tmp_path / "video0"
    node.touch()
    capture = StandInCapture("YUYV")
    original_set = capture.set

    def refuse_grey(prop: int, value: float) -> bool:
        if prop == cv2.CAP_PROP_FOURCC and value == cv2.VideoWriter.fourcc(*"GREY"):
            return False  # a YUYV-only camera: the format stays YUYV
        return original_set(prop, value)

    capture.set = refuse_grey  # type: ignore[method-assign]
    with _opencv_source(node, capture) as source:
        assert source.pixel_format == "YUYV"


def test_linuxpy_driver_names_a_missing_device() -> None:
    pytest.importorskip("linuxpy")
    with pytest.raises(CaptureError, match=r"camera /dev/video-ropecam-missing: No such file or directory"):
        V4l2Source("/dev/video-ropecam-missing", backend="linuxpy").start()


def test_backend_choice_falls_back_to_opencv_without_linuxpy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ropecam.device.capture.v4l2_linuxpy", None)  # import fails
    assert default_driver_factory("auto") is OpenCvDriver
    with pytest.raises(CaptureError, match=r"needs linuxpy: pip install 'ropecam\[device\]'"):
        default_driver_factory("linuxpy")
    with pytest.raises(ValueError, match="backend must be"):
        default_driver_factory("gstreamer")


def test_opencv_driver_names_a_missing_device() -> None:
    with pytest.raises(CaptureError, match=r"camera /dev/video-ropecam-missing: .*no such device"):
        V4l2Source("/dev/video-ropecam-missing", backend="opencv").start()


@pytest.mark.hardware
def test_real_camera_streams_newest_frames() -> None:
    """On a rig: the first camera delivers frames with increasing sequence numbers and monotonic timestamps."""
    with V4l2Source("/dev/video0", exposure_us=2000) as source:
        frames = [source.read(2.0) for _ in range(20)]
        got = [(f.sequence, f.t_ns) for f in frames if f is not None]
        assert len(got) == 20
        assert all(b[0] > a[0] and b[1] > a[1] for a, b in itertools.pairwise(got))
        assert source.image_size == (frames[0].image.shape[1], frames[0].image.shape[0])  # type: ignore[union-attr]


# -- linuxpy adapter: the flag and timestamp mapping, with linuxpy's ioctl wrappers replaced -------------------------
@pytest.mark.parametrize(
    ("flags", "source", "error"),
    [
        (0x2000 | 0x10000, "START_OF_EXPOSURE", False),  # TIMESTAMP_MONOTONIC | TSTAMP_SRC_SOE (uvcvideo)
        (0x2000, "END_OF_FRAME", False),  # TIMESTAMP_MONOTONIC | TSTAMP_SRC_EOF
        (0x4000, "NOT_MONOTONIC", False),  # TIMESTAMP_COPY
        (0x2000 | 0x10000 | 0x40, "START_OF_EXPOSURE", True),  # V4L2_BUF_FLAG_ERROR
    ],
)
def test_linuxpy_dequeue_maps_flags_and_timestamps(
    monkeypatch: pytest.MonkeyPatch, flags: int, source: str, error: bool
) -> None:
    pytest.importorskip("linuxpy")
    from linuxpy.video import raw

    from ropecam.device.capture import v4l2_linuxpy
    from ropecam.device.capture.driver import TimestampSource

    buffer = raw.v4l2_buffer()
    buffer.index, buffer.sequence, buffer.flags, buffer.bytesused = 1, 7, flags, 10
    buffer.timestamp.secs, buffer.timestamp.usecs = 3, 250
    monkeypatch.setattr(v4l2_linuxpy.lvd, "dequeue_buffer", lambda *args: buffer)
    driver = object.__new__(v4l2_linuxpy.LinuxpyDriver)
    driver._device = None
    driver._arrays = [np.zeros(10, np.uint8), np.ones(10, np.uint8)]
    got = driver.dequeue()
    assert got is not None
    assert (got.index, got.sequence, got.timestamp_ns, got.bytes_used) == (1, 7, 3_000_250_000, 10)
    assert got.timestamp_source is TimestampSource[source] and got.error is error
    assert got.data is driver._arrays[1]

    def empty(*args: object) -> None:
        raise BlockingIOError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(v4l2_linuxpy.lvd, "dequeue_buffer", empty)
    assert driver.dequeue() is None


def test_linuxpy_fourcc_names() -> None:
    pytest.importorskip("linuxpy")
    from ropecam.device.capture.v4l2_linuxpy import fourcc_name

    assert fourcc_name(1448695129) == "YUYV" and fourcc_name(0x59455247) == "GREY"


def test_linuxpy_controls_from_the_raw_queries(monkeypatch: pytest.MonkeyPatch) -> None:
    """Controls are read from QUERY_EXT_CTRL records and named like v4l2-ctl; menus, read-only and class headers."""
    pytest.importorskip("linuxpy")
    from linuxpy.video import raw
    from linuxpy.video.device import ControlFlag, ControlType

    from ropecam.device.capture import v4l2_linuxpy

    def record(cid: int, name: bytes, ctype: int, low: int, high: int, default: int, flags: int = 0) -> object:
        info = raw.v4l2_query_ext_ctrl()
        info.id, info.name, info.type, info.flags = cid, name, ctype, flags
        info.minimum, info.maximum, info.step, info.default_value = low, high, 1, default
        return info

    records = [
        record(0x9A0001, b"Camera Controls", ControlType.CTRL_CLASS, 0, 0, 0),
        record(0x9A0901, b"Auto Exposure", ControlType.MENU, 0, 3, 3),
        record(0x9A0902, b"Exposure Time, Absolute", ControlType.INTEGER, 1, 5000, 157),
        record(0x9A0903, b"Exposure, Dynamic Framerate", ControlType.BOOLEAN, 0, 1, 0),
        record(0x980913, b"Gain (Analog)", ControlType.INTEGER, 0, 100, 0, flags=ControlFlag.READ_ONLY),
    ]
    values = {0x9A0901: 3, 0x9A0902: 157, 0x9A0903: 1, 0x980913: 4}
    written: list[tuple[int, int]] = []

    def menu(device: object, shim: object) -> list[object]:
        items = []
        for index, label in ((1, b"Manual Mode"), (3, b"Aperture Priority Mode")):
            item = raw.v4l2_querymenu()
            item.id, item.index, item.name = shim.id, index, label  # type: ignore[attr-defined]
            items.append(item)
        return items

    monkeypatch.setattr(v4l2_linuxpy.lvd, "iter_read_controls", lambda device: iter(records))
    monkeypatch.setattr(v4l2_linuxpy.lvd, "iter_read_menu", menu)
    monkeypatch.setattr(v4l2_linuxpy.lvd, "get_controls_values", lambda device, infos: [values[infos[0].id]])
    monkeypatch.setattr(
        v4l2_linuxpy.lvd, "set_controls_values", lambda device, pairs: written.append((pairs[0][0].id, pairs[0][1]))
    )
    driver = object.__new__(v4l2_linuxpy.LinuxpyDriver)
    driver._device, driver._controls, driver.path = None, None, "/dev/video0"
    controls = driver.controls()
    assert list(controls) == ["auto_exposure", "exposure_time_absolute", "exposure_dynamic_framerate", "gain_analog"]
    assert controls["auto_exposure"].menu == {1: "Manual Mode", 3: "Aperture Priority Mode"}
    assert controls["exposure_time_absolute"].maximum == 5000 and controls["exposure_time_absolute"].value == 157
    assert not controls["gain_analog"].writable and controls["exposure_dynamic_framerate"].kind == "boolean"
    driver.set_control("exposure_time_absolute", 20)
    assert written == [(0x9A0902, 20)] and driver.get_control("gain_analog") == 4
    with pytest.raises(OSError, match="no control 'focus_absolute'"):
        driver.get_control("focus_absolute")


class StandInKernel:
    """linuxpy's ioctl wrappers replaced by a tiny in-memory V4L2 driver (real anonymous mmaps as buffers)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, width: int = W, height: int = H) -> None:
        from fractions import Fraction

        from linuxpy.video import device as lvd
        from linuxpy.video import raw

        self.raw, self.width, self.height = raw, width, height
        self.maps: list[object] = []
        self.free: list[int] = []
        self.done: list[object] = []
        self.calls: list[str] = []
        self.fps = Fraction(30)
        self.read_fd, self.write_fd = os.pipe()
        kernel = self
        frame_size = SimpleNamespace(type=lvd.FrameSizeType.DISCRETE, info=SimpleNamespace(width=W, height=H))
        frame_type = SimpleNamespace(min_fps=Fraction(119), max_fps=Fraction(119))
        grey = SimpleNamespace(type=lvd.BufferType.VIDEO_CAPTURE, pixel_format=lvd.PixelFormat.GREY, description="Grey")
        info = SimpleNamespace(
            card="Stand-in",
            driver="standin",
            bus_info="test",
            formats=[grey],
            format_frame_sizes=lambda pf: [frame_size],
            fps_intervals=lambda pf, w, h: [frame_type],
        )

        class Device:
            def __init__(self, path: str, blocking: bool) -> None:
                assert blocking is False
                self.info = info

            def open(self) -> None:
                kernel.calls.append("open")

            def close(self) -> None:
                kernel.calls.append("close")

            def fileno(self) -> int:
                return kernel.read_fd

        def fmt() -> SimpleNamespace:
            return SimpleNamespace(width=W, height=H, pixel_format=lvd.PixelFormat.GREY, size=W * H, bytes_per_line=W)

        def query_buffer(device: object, btype: object, memory: object, index: int) -> object:
            buffer = raw.v4l2_buffer()
            buffer.index, buffer.length = index, W * H
            return buffer

        def mmap_from_buffer(device: object, buffer: object) -> mmap.mmap:
            mapped = mmap.mmap(-1, buffer.length)  # type: ignore[attr-defined]
            kernel.maps.append(mapped)
            return mapped

        def dequeue(device: object, btype: object, memory: object) -> object:
            if not kernel.done:
                raise BlockingIOError(11, "Resource temporarily unavailable")
            return kernel.done.pop(0)

        def set_fps(device: object, btype: object, fps: float) -> None:
            kernel.fps = Fraction(fps).limit_denominator(1000)

        patches = {
            "Device": Device,
            "get_format": lambda device, btype: fmt(),
            "set_format": lambda device, btype, w, h, fourcc: kernel.calls.append(f"set_format {w}x{h} {fourcc}"),
            "get_fps": lambda device, btype: kernel.fps,
            "set_fps": set_fps,
            "iter_read_controls": lambda device: iter(()),
            "request_buffers": lambda device, btype, memory, count: SimpleNamespace(count=count),
            "query_buffer": query_buffer,
            "mmap_from_buffer": mmap_from_buffer,
            "enqueue_buffer": lambda device, btype, memory, size, index: kernel.free.append(index),
            "dequeue_buffer": dequeue,
            "stream_on": lambda device, btype: kernel.calls.append("stream_on"),
            "stream_off": lambda device, btype: kernel.calls.append("stream_off"),
            "free_buffers": lambda device, btype, memory: kernel.calls.append("free_buffers"),
        }
        for name, value in patches.items():
            monkeypatch.setattr(lvd, name, value)

    def produce(self, sequence: int) -> None:
        index = self.free.pop(0)
        self.maps[index][: W * H] = fake_pattern(sequence, W, H).tobytes()  # type: ignore[index]
        buffer = self.raw.v4l2_buffer()
        buffer.index, buffer.sequence, buffer.bytesused, buffer.flags = index, sequence, W * H, 0x2000 | 0x10000
        buffer.timestamp.secs, buffer.timestamp.usecs = 10, sequence * 8403
        self.done.append(buffer)


def test_v4l2_source_over_linuxpy_with_a_stand_in_kernel(monkeypatch: pytest.MonkeyPatch) -> None:
    """The linuxpy driver end to end under V4l2Source: mapped buffers, newest frame, requeue, timeout, stop."""
    pytest.importorskip("linuxpy")
    from ropecam.device.capture.v4l2_linuxpy import LinuxpyDriver

    kernel = StandInKernel(monkeypatch)
    source = V4l2Source("/dev/video0", W, H, 119.0, "GREY", buffer_count=3, driver_factory=LinuxpyDriver)
    with source:
        assert kernel.calls[:2] == ["open", f"set_format {W}x{H} GREY"] and "stream_on" in kernel.calls
        assert source.fps == 119.0 and kernel.free == [0, 1, 2]
        for sequence in range(3):
            kernel.produce(sequence)
        frame = source.read(0)
        assert frame is not None and frame.sequence == 2 and frame.t_ns == 10_000_000_000 + 2 * 8_403_000
        np.testing.assert_array_equal(frame.image, fake_pattern(2, W, H))
        assert source.counters.skipped == 2 and sorted(kernel.free) == [0, 1]  # buffer 2 is with the consumer
        assert source.read(0.01) is None  # select on the node times out
        assert sorted(kernel.free) == [0, 1, 2]
        del frame
    assert kernel.calls[-3:] == ["stream_off", "free_buffers", "close"]
    assert all(m.closed for m in kernel.maps)  # type: ignore[attr-defined]
