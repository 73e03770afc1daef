"""`ropecam.shared.plane`: the device's plane.yaml reader agrees with the host's OpenCV files and geometry."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.host.calibration.files import read_plane, write_plane
from ropecam.host.calibration.geometry import CameraModel, PlanePose, pixels_to_plane, plane_to_pixels
from ropecam.shared.errors import ConfigError
from ropecam.shared.plane import read_plane_file

CAMERA = CameraModel(
    np.array([[1100.0, 0.0, 515.0], [0.0, 1090.0, 268.0], [0.0, 0.0, 1.0]]),
    np.array([-0.12, 0.07, 0.0015, -0.002, 0.01]),
    (1024, 544),
)
PLANE = PlanePose.from_rvec([0.12, -0.05, 0.03], [0.02, -0.25, 1.6])


@pytest.fixture(scope="module")
def plane_yaml(tmp_path_factory: pytest.TempPathFactory):
    path = tmp_path_factory.mktemp("plane") / "plane.yaml"
    return write_plane(path, CAMERA, PLANE, {"origin_px": np.array([3.0, 4.0])})


def test_reads_what_calibration_writes_and_maps_as_opencv(plane_yaml) -> None:
    plane = read_plane_file(plane_yaml)
    host = read_plane(plane_yaml)
    assert plane.image_size == (1024, 544)
    points_m = np.array([[0.0, 0.0], [0.15, 0.4], [-0.3, 0.2]])
    np.testing.assert_allclose(plane.project(points_m), plane_to_pixels(points_m, host.camera, host.plane), atol=1e-9)
    pixels = np.array([[5.0, 7.0], [512.0, 300.0], [1010.0, 530.0]])
    np.testing.assert_allclose(plane.to_plane(pixels), pixels_to_plane(pixels, host.camera, host.plane), atol=1e-12)
    np.testing.assert_allclose(plane.origin_uv(), plane_to_pixels(np.zeros(2), CAMERA, PLANE), atol=1e-9)


def test_origin_outside_the_image_names_the_file(tmp_path) -> None:
    path = write_plane(tmp_path / "far.yaml", CAMERA, PlanePose.from_rvec([0.0, 0.0, 0.0], [2.0, 0.0, 1.0]))
    plane = read_plane_file(path)
    with pytest.raises(ConfigError, match=r"far\.yaml.*plane origin.*outside the 1024x544 image"):
        plane.check_image((1024, 544))


def test_missing_key_and_not_yaml(tmp_path, plane_yaml) -> None:
    text = plane_yaml.read_text()
    start = text.index("plane_rotation:")
    broken = tmp_path / "broken.yaml"
    broken.write_text(text[:start] + text[text.index("plane_translation_m:") :])
    with pytest.raises(ConfigError, match=r"broken\.yaml: key 'plane_rotation' is missing"):
        read_plane_file(broken)
    other = tmp_path / "other.yaml"
    other.write_text("plane: 1\n")
    with pytest.raises(ConfigError, match=r"other\.yaml: not an OpenCV FileStorage"):
        read_plane_file(other)
    with pytest.raises(ConfigError, match=r"nowhere\.yaml: cannot read"):
        read_plane_file(tmp_path / "nowhere.yaml")


def test_check_readout() -> None:
    from ropecam.shared.config import check_readout

    check_readout("readout_us", 0, 119.0)
    check_readout("readout_us", 8000, 119.0)
    with pytest.raises(ConfigError, match=r"capture\.readout_us must be >= 0"):
        check_readout("capture.readout_us", -1, None)
    with pytest.raises(ConfigError, match=r"readout_us is 9000 us, longer than the frame period 8403 us"):
        check_readout("readout_us", 9000, 119.0)
