"""Device clock -> host clock, the log and publish times of the decoded channels, and the transform tree."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.host.calibration.geometry import CameraModel, PlanePose, plane_to_pixels
from ropecam.host.monitor.clock import ClockMap
from ropecam.host.recording.frames import device_transforms, quaternion


def test_clock_offset_is_the_smallest_delay_follows_drift_and_resets_after_a_reboot() -> None:
    rng = np.random.default_rng(5)
    clock = ClockMap(window_s=10.0)
    assert clock.offset_ns(1) is None and clock.to_host(1, 5, fallback_ns=99) == 99
    offset = 1_700_000_000_000_000_000
    for k in range(2000):  # 20 s at 100 Hz, delays 0.2-15 ms, the smallest ones every 50th message
        device_t = 3_000_000_000 + k * 10_000_000
        delay = 200_000 if k % 50 == 0 else int(rng.uniform(1e6, 15e6))
        clock.observe(1, device_t, device_t + offset + delay)
    assert clock.offset_ns(1) == offset + 200_000
    # the clocks drift apart by 2 ms: after one window the old minimum is forgotten
    for k in range(2000, 3200):
        device_t = 3_000_000_000 + k * 10_000_000
        clock.observe(1, device_t, device_t + offset + 2_000_000 + 300_000)
    assert clock.offset_ns(1) == offset + 2_300_000
    # the device rebooted: its clock starts again near 0, the next message resets the estimate
    clock.observe(1, 1_000_000, offset + 3_000_000_000 + 3200 * 10_000_000 + 500_000)
    assert clock.to_host(1, 1_000_000, 0) == offset + 3_000_000_000 + 3200 * 10_000_000 + 500_000
    with pytest.raises(ValueError, match="window_s"):
        ClockMap(window_s=0)


def test_scene_log_time_is_the_exposure_on_the_host_clock_and_publish_time_the_receive_time(
    sim_device, tmp_path, read_mcap
) -> None:
    from mcap.reader import make_reader

    from ropecam.host.receiver import check_packet
    from ropecam.host.recording.writer import Recorder, RecordingConfig
    from ropecam.host.session import Session
    from ropecam.shared.protocol import FrameResult, decode_message

    host_minus_device = 1_700_000_000_000_000_000  # a device clock counting from its boot
    session = Session(Recorder(RecordingConfig(tmp_path / "t.mcap")))
    sent = []
    for k, (_, data) in enumerate(sim_device.messages(6, start_t_ns=50_000_000_000)):
        message = decode_message(data)
        receive_t_ns = message.header.t_ns + host_minus_device + (1_000_000 if k % 2 else 300_000)
        session.handle(check_packet(data, receive_t_ns))
        if isinstance(message.record, FrameResult):
            sent.append((message.record, receive_t_ns))
    session.close()
    with open(tmp_path / "t.mcap", "rb") as handle:
        scenes = [m for _, c, m in make_reader(handle).iter_messages(log_time_order=False) if c.topic.endswith("scene")]
    assert len(scenes) == len(sent) == 6
    for scene, (record, receive_t_ns) in zip(scenes, sent, strict=True):
        mid = (record.exposure_start_t_ns + record.exposure_end_t_ns) // 2
        assert scene.publish_time == receive_t_ns
        # the offset known when the frame arrived: the smallest delay so far (0.3 ms, the first message)
        assert scene.log_time == mid + host_minus_device + 300_000


def test_transforms_connect_plane_camera_and_image() -> None:
    from scipy.spatial.transform import Rotation

    camera = CameraModel(np.array([[900.0, 0, 500.0], [0, 900.0, 270.0], [0, 0, 1]]), np.zeros(5), (1024, 544))
    plane = PlanePose.from_rvec([0.2, -0.3, 0.1], [0.05, -0.2, 1.4])
    to_camera, to_image = device_transforms(4, camera, plane)
    assert (to_camera.parent, to_camera.child, to_image.parent, to_image.child) == (
        "device4/plane", "device4/camera", "device4/camera", "device4/image"
    )  # fmt: skip
    rotation = Rotation.from_quat(to_camera.rotation)  # (x, y, z, w), Foxglove's order and scipy's
    points_m = np.array([[0.0, 0.0], [0.3, 0.1], [-0.2, 0.35]])
    for point, pixel in zip(points_m, plane_to_pixels(points_m, camera, plane), strict=True):
        in_camera = plane.rotation @ np.array([*point, 0.0]) + plane.translation_m
        # a point of the camera frame, expressed in the plane frame by the transform, is the plane point
        np.testing.assert_allclose(rotation.apply(in_camera) + to_camera.translation, [*point, 0.0], atol=1e-12)
        # the pixel, placed in the image frame, lies on the point's viewing ray
        ray = np.array([*pixel, 0.0]) + to_image.translation
        np.testing.assert_allclose(np.cross(ray / np.linalg.norm(ray), in_camera / np.linalg.norm(in_camera)), 0,
                                   atol=1e-9)  # fmt: skip
    for matrix in (np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), Rotation.random(5, 1).as_matrix()[0]):
        q = quaternion(matrix)
        np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), matrix, atol=1e-12)
