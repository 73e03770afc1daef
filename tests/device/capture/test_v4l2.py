"""The V4L2 source against the fake device layer: formats, exposure, timestamps, sequence gaps, newest frame, loss."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.capture.driver import ControlInfo, FormatInfo, FrameSizeInfo, TimestampSource
from ropecam.device.capture.fake import FakeCamera, fake_factory, fake_pattern, uvc_like_camera
from ropecam.device.capture.v4l2 import V4l2Source
from ropecam.shared.errors import CaptureError

PERIOD_NS = round(1e9 / 119.0)


def _source(camera: FakeCamera, **kwargs: object) -> V4l2Source:
    options: dict[str, object] = {"width": 64, "height": 32, "fps": 119.0}
    options.update(kwargs)
    return V4l2Source(camera.path, driver_factory=fake_factory(camera), **options)  # type: ignore[arg-type]


def _old_kernel_camera() -> FakeCamera:
    """Controls as kernels before 5.x named them (exposure_absolute, exposure_auto, exposure_auto_priority)."""
    sizes = (FrameSizeInfo(64, 32, (119.0,)),)
    controls = {
        "exposure_auto": ControlInfo("exposure_auto", "menu", 0, 3, 1, 3, 3, {1: "Manual Mode", 3: "Aperture"}),
        "exposure_absolute": ControlInfo("exposure_absolute", "int", 3, 2047, 1, 250, 250),
        "exposure_auto_priority": ControlInfo("exposure_auto_priority", "bool", 0, 1, 1, 1, 1),
    }
    return FakeCamera("/dev/video1", [FormatInfo("YUYV", "YUYV 4:2:2", sizes)], controls)


# -- format negotiation --------------------------------------------------------------------------------------------
def test_prefers_grey_over_other_formats_and_hands_over_the_mapped_buffer() -> None:
    camera = uvc_like_camera()  # lists MJPG first
    with _source(camera) as source:
        assert source.pixel_format == "GREY" and source.image_size == (64, 32) and source.fps == 119.0
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None
        np.testing.assert_array_equal(frame.image, fake_pattern(0, 64, 32))
        assert frame.image.flags.c_contiguous and not frame.image.flags.writeable
        assert any(np.shares_memory(frame.image, buffer) for buffer in camera.buffers)  # zero copy


@pytest.mark.parametrize("name", ["Y8", "grey", "GREY"])
def test_y8_is_an_alias_of_grey(name: str) -> None:
    with _source(uvc_like_camera(), pixel_format=name) as source:
        assert source.pixel_format == "GREY"


def test_yuyv_takes_the_luma_samples() -> None:
    camera = uvc_like_camera()
    with _source(camera, pixel_format="YUYV") as source:
        camera.deliver(2)
        frame = source.read(0)
        assert frame is not None and source.pixel_format == "YUYV"
        np.testing.assert_array_equal(frame.image, fake_pattern(1, 64, 32))
        assert frame.image.shape == (32, 64) and frame.image.flags.c_contiguous


def test_padded_rows_are_copied_without_the_padding() -> None:
    camera = uvc_like_camera(row_padding=16)
    with _source(camera) as source:
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None and frame.image.flags.c_contiguous
        np.testing.assert_array_equal(frame.image, fake_pattern(0, 64, 32))


def test_a_size_the_driver_changes_is_an_error_listing_the_sizes() -> None:
    with pytest.raises(
        CaptureError, match=r"asked for 640x480 GREY.*granted 1024x544 GREY; sizes for GREY: 1280x800, 1024x544, 64x32"
    ):
        _source(uvc_like_camera(), width=640, height=480, pixel_format="GREY").start()
    with pytest.raises(CaptureError, match=r"asked for 640x480 GREY/YUYV, the driver granted 1024x544 YUYV"):
        _source(uvc_like_camera(), width=640, height=480).start()


def test_missing_and_unusable_formats_are_named() -> None:
    camera = FakeCamera("/dev/video0", [FormatInfo("MJPG", "Motion-JPEG", (FrameSizeInfo(64, 32, (30.0,)),))], {})
    with pytest.raises(CaptureError, match="offers MJPG; ropecam needs GREY"):
        _source(camera, fps=None).start()
    with pytest.raises(CaptureError, match="pixel format YUYV not offered; the camera offers MJPG"):
        _source(camera, fps=None, pixel_format="YUYV").start()
    with pytest.raises(ValueError, match="pixel_format must be one of"):
        _source(camera, pixel_format="RGB3")


def test_a_frame_rate_the_driver_cannot_grant_is_an_error_with_the_rates() -> None:
    with pytest.raises(CaptureError, match=r"asked for 100 fps.*granted 119; rates listed: 30, 60, 119"):
        _source(uvc_like_camera(), fps=100.0).start()


def test_keeps_the_current_size_when_none_is_asked() -> None:
    with _source(uvc_like_camera(), width=None, height=None) as source:
        assert source.image_size == (1280, 800)


# -- exposure and gain ---------------------------------------------------------------------------------------------
def test_exposure_goes_manual_first_then_sets_100us_units() -> None:
    camera = uvc_like_camera()
    with _source(camera, exposure_us=2000) as source:
        assert camera.control_log == [
            ("auto_exposure", 1),
            ("exposure_dynamic_framerate", 0),
            ("exposure_time_absolute", 20),
        ]
        assert source.exposure_us == 2000
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None and frame.exposure_us == 2000
        assert source.set_exposure_us(4260) == 4300  # rounded to the driver's 100 us steps
        assert camera.values["exposure_time_absolute"] == 43
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None and frame.exposure_us == 4300


def test_exposure_on_kernels_with_the_old_control_names() -> None:
    camera = _old_kernel_camera()
    with _source(camera, exposure_us=1500) as source:
        assert camera.control_log == [("exposure_auto", 1), ("exposure_auto_priority", 0), ("exposure_absolute", 15)]
        assert source.exposure_us == 1500 and source.pixel_format == "YUYV"


def test_exposure_out_of_range_or_longer_than_a_frame_is_refused() -> None:
    camera = _old_kernel_camera()  # range 300 .. 204700 us
    with _source(camera) as source:
        with pytest.raises(ValueError, match=r"out of the camera's range \[300, 204700\] us"):
            source.set_exposure_us(100)
        with pytest.raises(ValueError, match="longer than the frame period 8403 us at 119 fps"):
            source.set_exposure_us(9000)
        with pytest.raises(ValueError, match="positive integer"):
            source.set_exposure_us(-5)
        assert source.exposure_us == 25000  # untouched by the refused values


def test_camera_without_manual_exposure() -> None:
    sizes = (FrameSizeInfo(64, 32, (119.0,)),)
    auto_only = {
        "auto_exposure": ControlInfo("auto_exposure", "menu", 3, 3, 1, 3, 3, {3: "Aperture Priority Mode"}),
        "exposure_time_absolute": ControlInfo("exposure_time_absolute", "int", 1, 100, 1, 10, 10),
    }
    camera = FakeCamera("/dev/video0", [FormatInfo("GREY", "grey", sizes)], auto_only)
    with pytest.raises(CaptureError, match=r"cannot apply the settings: .*auto_exposure has no manual mode"):
        _source(camera, exposure_us=1000).start()
    no_exposure = FakeCamera("/dev/video0", [FormatInfo("GREY", "grey", sizes)], {})
    with pytest.raises(CaptureError, match="no exposure control"):
        _source(no_exposure, exposure_us=1000).start()
    with _source(no_exposure) as source:
        with pytest.raises(ValueError, match="no gain control"):
            source.set_gain(3)  # a control error at run time: reported, the camera keeps streaming
        with pytest.raises(ValueError, match="no exposure control"):
            source.set_exposure_us(1000)
        assert source.started


def test_gain() -> None:
    camera = uvc_like_camera()
    with _source(camera, gain=7) as source:
        assert camera.values["gain"] == 7
        assert source.set_gain(12) == 12
        with pytest.raises(ValueError, match=r"gain=101 out of the camera's range \[0, 100\]"):
            source.set_gain(101)


# -- timestamps ----------------------------------------------------------------------------------------------------
def test_start_of_exposure_timestamps_pass_through() -> None:
    camera = uvc_like_camera(t0_ns=7_000_000_000)
    with _source(camera) as source:
        times = []
        for _ in range(3):
            camera.deliver(1)
            frame = source.read(0)
            assert frame is not None
            times.append(frame.t_ns)
    assert times == [7_000_000_000 + round(k * 1e9 / 119.0) for k in range(3)]


def test_end_of_frame_timestamps_are_moved_back_by_the_exposure() -> None:
    camera = uvc_like_camera(t0_ns=7_000_000_000, timestamp_source=TimestampSource.END_OF_FRAME)
    with _source(camera, exposure_us=3000) as source:
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None and frame.t_ns == 7_000_000_000 - 3_000_000


def test_timestamps_that_are_not_monotonic_are_replaced_by_the_clock() -> None:
    camera = uvc_like_camera(timestamp_source=TimestampSource.NOT_MONOTONIC)
    source = V4l2Source(
        camera.path, 64, 32, 119.0, exposure_us=1000, driver_factory=fake_factory(camera), clock=lambda: 42_000_000
    )
    with source:
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None and frame.t_ns == 42_000_000 - 1_000_000


# -- newest frame, sequence gaps, bad buffers, timeouts ----------------------------------------------------------
def test_read_hands_over_the_newest_frame_and_requeues_the_rest() -> None:
    camera = uvc_like_camera()
    with _source(camera, buffer_count=4) as source:
        camera.deliver(3)
        frame = source.read(0)
        assert frame is not None and frame.sequence == 2
        np.testing.assert_array_equal(frame.image, fake_pattern(2, 64, 32))
        assert source.counters.as_dict() == {"delivered": 1, "skipped": 2, "dropped": 0, "timeouts": 0}
        assert len(camera.free) == 3  # two skipped buffers back with the driver, one held by the consumer
        camera.deliver(1)
        assert len(camera.free) == 2  # the consumer's buffer goes back only on its next read
        frame = source.read(0)
        assert frame is not None and frame.sequence == 3 and len(camera.free) == 3


def test_sequence_gaps_count_as_drops() -> None:
    camera = uvc_like_camera()
    with _source(camera, buffer_count=2) as source:
        camera.deliver(1)
        assert source.read(0) is not None  # holds one of the two buffers
        assert camera.deliver(3) == 1  # frames 2 and 3 find no buffer: the driver drops them
        first = source.read(0)
        camera.deliver(1)
        second = source.read(0)
        assert first is not None and second is not None
        assert (first.sequence, second.sequence) == (1, 4)
        counters = source.counters
        assert counters.dropped == 2 and counters.delivered == 3 and counters.skipped == 0
        assert counters.delivered + counters.skipped + counters.dropped == second.sequence + 1


def test_corrupt_and_short_buffers_are_dropped() -> None:
    camera = uvc_like_camera()
    with _source(camera) as source:
        camera.deliver(1, error=True)
        camera.deliver(1, short=True)
        assert source.read(0) is None
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None and frame.sequence == 2
        assert source.counters.dropped == 2 and source.counters.timeouts == 1


def test_sequence_wrap_is_not_a_drop() -> None:
    camera = uvc_like_camera()
    with _source(camera) as source:
        camera.sequence = 2**32 - 1
        camera.deliver(1)
        assert source.read(0) is not None
        camera.sequence = 0  # the u32 counter wraps
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None and frame.sequence == 0 and source.counters.dropped == 0


def test_timeout_returns_none_and_a_frame_arriving_during_the_wait_is_read() -> None:
    camera = uvc_like_camera()
    with _source(camera) as source:
        assert source.read(0.01) is None
        assert source.counters.timeouts == 1
        camera.on_wait = lambda cam: cam.deliver(1)
        frame = source.read(0.5)
        assert frame is not None and frame.sequence == 0 and source.counters.timeouts == 1


# -- losing the device -----------------------------------------------------------------------------------------
def test_a_camera_that_vanishes_raises_capture_error_and_stops_cleanly() -> None:
    camera = uvc_like_camera()
    source = _source(camera)
    with source:
        camera.deliver(1)
        assert source.read(0) is not None
        camera.vanish()
        with pytest.raises(
            CaptureError, match=r"camera /dev/video0: No such device \(device vanished: camera unplugged"
        ):
            source.read(0.1)
        with pytest.raises(CaptureError, match="No such device"):
            source.read(0.1)  # stays lost: no frame from a dead device
    assert not source.started


def test_the_camera_can_be_restarted_after_it_returns() -> None:
    camera = uvc_like_camera()
    source = _source(camera)
    with source:
        camera.vanish()
        with pytest.raises(CaptureError):
            source.read(0)
    camera.reconnect()
    with source:
        camera.deliver(1)
        frame = source.read(0)
        assert frame is not None and frame.sequence == 0 and source.counters.delivered == 1


@pytest.mark.parametrize(
    ("prepare", "message"),
    [
        (lambda cam: None, "No such file or directory.*no such device: is the camera plugged in"),
        (lambda cam: setattr(cam, "busy", True), "another program is using the camera"),
    ],
)
def test_open_errors_are_explained(prepare, message: str) -> None:  # type: ignore[no-untyped-def]
    camera = uvc_like_camera("/dev/video0")
    prepare(camera)
    path = "/dev/video9" if "file" in message else "/dev/video0"
    with pytest.raises(CaptureError, match=message):
        V4l2Source(path, driver_factory=fake_factory(camera)).start()


def test_read_before_start_and_bad_arguments() -> None:
    source = _source(uvc_like_camera())
    with pytest.raises(CaptureError, match="before start"):
        source.read(0)
    with pytest.raises(ValueError, match="both width and height"):
        V4l2Source("/dev/video0", width=64, driver_factory=fake_factory())
    with pytest.raises(ValueError, match="buffer_count"):
        V4l2Source("/dev/video0", buffer_count=1, driver_factory=fake_factory())


def test_stop_releases_the_device() -> None:
    camera = uvc_like_camera()
    with _source(camera):
        assert camera.streaming
    assert not camera.streaming and camera.opened == 1
