"""Acceptance 1 and 2: the rendered rope sits on its ground truth, and the ground truth is self-consistent."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.calibration.geometry import CameraModel, PlanePose, plane_to_pixels
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import SceneSpec, SimConfig
from ropecam.host.sim.generate import TRAJECTORY_FILE, write_frameset


@pytest.mark.parametrize("shape", ["rod", "curl"])
@pytest.mark.parametrize("polarity", ["bright", "dark"])
def test_rope_centre_lies_on_the_ground_truth(
    tmp_path: Path,
    tiny: Callable[..., SimConfig],
    rod_factory: Callable[..., Trajectory],
    curl_factory: Callable[..., Trajectory],
    shape: str,
    polarity: str,
    cross_centres: Callable[..., np.ndarray],
) -> None:
    """Acceptance 1: noise-free, 0.1 ms exposure: weighted centre across the rope within 0.05 px of the truth."""
    config = tiny(clean=True, frames=3, first_exposure_s=0.12, exposure_ms=(0.1,))
    config = dataclasses.replace(config, scene=dataclasses.replace(config.scene, polarity=polarity))
    trajectory = (rod_factory if shape == "rod" else curl_factory)(0.411, 0.2)
    write_frameset(config, trajectory, tmp_path / "set", 0.1)
    frames = FrameSet(tmp_path / "set")
    truth = frames.truth()
    assert truth is not None
    saved = Trajectory.load(tmp_path / "set" / TRAJECTORY_FILE)
    camera = CameraModel(np.array(frames.meta["camera"]["camera_matrix"]), frames.meta["camera"]["distortion"],
                         tuple(frames.meta["camera"]["image_size"]))  # fmt: skip
    plane = PlanePose.from_rvec(frames.meta["plane"]["rvec"], frames.meta["plane"]["tvec_m"])
    background = config.scene.background_level
    all_errors = []
    for k, (record, image) in enumerate(frames):
        # The centre of a 0.1 ms blur is the rope at mid-exposure (it moves up to 0.35 px in 0.1 ms).
        mid_s = 0.5 * (truth["t_begin_ns"][k] + truth["t_end_ns"][k]) * 1e-9
        mid_px = plane_to_pixels(saved.positions([mid_s], truth["s_m"])[0], camera, plane)
        weight = image.astype(np.float64) - background
        if polarity == "dark":
            weight = -weight
        errors = cross_centres(image, np.clip(weight, 0, None), mid_px, skip_px=4 * truth["width_px"][k])
        assert errors.size > 100, f"frame {record.frame}: too few crossings measured"
        all_errors.append(errors)
        # The rendered rope is where the truth says: start and end truth bracket the mid-exposure centreline.
        assert np.abs(truth["begin_px"][k] - mid_px).max() < 0.5
    errors = np.concatenate(all_errors)
    print(f"centre error: max {errors.max():.4f} px, mean {errors.mean():.4f} px, {errors.size} crossings")
    assert errors.max() < 0.05, f"max {errors.max():.4f} px, mean {errors.mean():.4f} px"


def test_metric_truth_reprojects_to_pixel_truth(
    tmp_path: Path, tiny: Callable[..., SimConfig], curl_factory: Callable[..., Trajectory]
) -> None:
    """Acceptance 2: metres -> pixels reproduces the pixel truth within 1e-6 px, with ours and cv2.projectPoints."""
    config = tiny(frames=4, first_exposure_s=0.05)
    trajectory = curl_factory(0.411, 0.2)
    write_frameset(config, trajectory, tmp_path / "set", 4.0)
    frames = FrameSet(tmp_path / "set")
    truth = frames.truth()
    assert truth is not None
    meta = frames.meta
    camera = CameraModel(np.array(meta["camera"]["camera_matrix"]), meta["camera"]["distortion"],
                         tuple(meta["camera"]["image_size"]))  # fmt: skip
    plane = PlanePose.from_rvec(meta["plane"]["rvec"], meta["plane"]["tvec_m"])
    for metres, pixels in (("begin_m", "begin_px"), ("end_m", "end_px")):
        ours = plane_to_pixels(truth[metres], camera, plane)
        assert np.abs(ours - truth[pixels]).max() < 1e-6
        xyz = np.concatenate([truth[metres].reshape(-1, 2), np.zeros((truth[metres][..., 0].size, 1))], axis=1)
        opencv, _ = cv2.projectPoints(xyz, np.array(meta["plane"]["rvec"]), np.array(meta["plane"]["tvec_m"]),
                                      np.array(meta["camera"]["camera_matrix"]),
                                      np.array(meta["camera"]["distortion"]))  # fmt: skip
        assert np.abs(opencv.reshape(truth[pixels].shape) - truth[pixels]).max() < 1e-6
    # The saved trajectory gives the metric truth at the exposure start and end times.
    saved = Trajectory.load(tmp_path / "set" / TRAJECTORY_FILE)
    for k in range(len(frames)):
        np.testing.assert_allclose(saved.positions([truth["t_begin_ns"][k] * 1e-9], truth["s_m"])[0],
                                   truth["begin_m"][k], atol=1e-12)  # fmt: skip
        np.testing.assert_allclose(saved.positions([truth["t_end_ns"][k] * 1e-9], truth["s_m"])[0],
                                   truth["end_m"][k], atol=1e-12)  # fmt: skip
    # Index, times, tips and the fixed end agree with each other.
    assert [r.t_ns for r in frames.records] == truth["t_begin_ns"].tolist()
    assert np.all(truth["t_end_ns"] - truth["t_begin_ns"] == 4_000_000)
    assert all(r.exposure_us == 4000 for r in frames.records)
    np.testing.assert_array_equal(truth["tip_begin_px"], truth["begin_px"][:, -1])
    np.testing.assert_array_equal(truth["tip_end_px"], truth["end_px"][:, -1])
    fixed = plane_to_pixels(np.zeros(2), camera, plane)
    np.testing.assert_allclose(truth["fixed_end_px"], fixed, atol=1e-9)
    np.testing.assert_allclose(truth["begin_px"][:, 0], np.broadcast_to(fixed, (len(frames), 2)), atol=1e-9)
    assert meta["rig"]["fixed_end_px"] == pytest.approx(fixed.tolist())
    # Dense samples: consecutive centreline points at most half a pixel apart.
    assert np.linalg.norm(np.diff(truth["begin_px"], axis=1), axis=-1).max() <= 0.5
    assert truth["s_m"][0] == 0.0 and truth["s_m"][-1] == pytest.approx(0.411)
    assert np.all((truth["width_px"] > 1.5) & (truth["width_px"] < 4.0))
    assert np.all(truth["subframes"] >= 2)


def test_scene_defaults_are_the_documented_levels() -> None:
    assert (SceneSpec().rope_level, SceneSpec().background_level) == (210.0, 25.0)
    assert (SceneSpec(polarity="dark").rope_level, SceneSpec(polarity="dark").background_level) == (35.0, 200.0)
