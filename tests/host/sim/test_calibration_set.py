"""`ropecam simulate --calibration-views`: a calibration set through the preset's camera and motion plane, which
our calibration recovers (issue 3, acceptance 3), and which then maps the rope's pixel truth to its metric truth."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from ropecam.device.capture.frameset import FrameSet
from ropecam.host.calibration.files import read_plane
from ropecam.host.calibration.geometry import pixels_to_plane
from ropecam.host.cli import main


def test_rig_calibration_set_recovers_camera_and_plane(tmp_path: Path) -> None:
    out = tmp_path / "rig"
    assert main(["simulate", "rig", "--out", str(out), "--frames", "1", "--calibration-views", "14", "-q"]) == 0
    calib = out / "calibration"
    truth = json.loads((calib / "truth.json").read_text())
    views = sorted(str(p) for p in calib.glob("view_*.png"))
    assert len(views) == 14
    board = ["--board", "8x7", "--square-mm", "20"]
    assert main(["calibrate", "intrinsics", *views, *board, "--out", str(tmp_path / "cam.yaml")]) == 0
    origin = "{:g},{:g}".format(*truth["origin_mm"])
    planes = [str(calib / name) for name in ("plane.png", "plane_01.png", "plane_02.png")]
    args = ["calibrate", "plane", *planes, "--camera", str(tmp_path / "cam.yaml"), *board, f"--origin-mm={origin}"]
    assert main([*args, "--out", str(tmp_path / "plane.yaml")]) == 0

    files = read_plane(tmp_path / "plane.yaml")
    k_true = np.array(truth["camera_matrix"])
    assert abs(files.camera.fx / k_true[0, 0] - 1) < 0.003
    assert abs(files.camera.fy / k_true[1, 1] - 1) < 0.003
    rotation_true, _ = cv2.Rodrigues(np.array(truth["plane_pose"]["rvec"]))
    delta = files.plane.rotation @ rotation_true.T
    angle_deg = np.degrees(np.arccos(np.clip((np.trace(delta) - 1) / 2, -1.0, 1.0)))
    assert angle_deg < 0.5
    assert np.linalg.norm(files.plane.translation_m - truth["plane_pose"]["tvec_m"]) < 1e-3
    # The same camera and plane as the rope frames: the calibrated conversion maps pixel truth onto metric truth.
    rope = FrameSet(out).truth()
    assert rope is not None
    metres = pixels_to_plane(rope["begin_px"][0], files.camera, files.plane)
    assert np.max(np.abs(metres - rope["begin_m"][0])) < 1e-4
