"""`ropecam-device extract` end to end: frame set, image folder with a broken file, config, errors."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSetWriter
from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.cli import main

ROPE = SyntheticRope(exposure_us=12000, amplitude_rad=0.7, period_s=0.9, diameter_px=3.0, phase_rad=1.2)


@pytest.fixture(scope="module")
def frames():
    return list(ROPE.frames(4))


def _read(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_extract_frame_set(tmp_path, frames) -> None:
    root = tmp_path / "set"
    with FrameSetWriter(root, (ROPE.width, ROPE.height), ROPE.fps) as writer:
        for f in frames:
            writer.add(f.image, f.t_ns, f.exposure_us)
    out = tmp_path / "out.jsonl"
    assert main(["extract", str(root), "--out", str(out), "--quiet"]) == 0
    records = _read(out)
    assert [r["frame"] for r in records] == [0, 1, 2, 3]
    assert all(r["method"] == "BLUR_SPLIT" for r in records)
    # The rope swings from the first frame: nothing decides that split's time order (kept, not trusted).
    assert [(r["status"], r["reason"]) for r in records] == [("IMPLAUSIBLE", "order")] + [("OK", "")] * 3
    assert records[1]["t_ns"] == frames[1].t_ns
    assert records[1]["t_end_ns"] == frames[1].t_ns + 12_000_000
    tip = np.array(records[2]["tips"]["end"])
    assert np.hypot(*(tip - frames[2].tip_end_uv)) < 2.5


def test_extract_image_folder_with_a_broken_file_and_config(tmp_path, frames) -> None:
    folder = tmp_path / "png"
    folder.mkdir()
    for f in frames:
        cv2.imwrite(str(folder / f"{f.index:03d}.png"), f.image)
    (folder / "001.png").write_bytes(b"not a png")
    config = tmp_path / "device.toml"
    config.write_text('[pipeline]\nmethod = "centerline"\nrope_length_m = 2.0\nmaterial_points_m = [1.0, 2.0]\n')
    out = tmp_path / "out.jsonl"
    argv = ["extract", str(folder), "--out", str(out), "--fps", "119", "--exposure-ms", "12", "--config", str(config)]
    assert main([*argv, "--quiet"]) == 0
    records = _read(out)
    # Frame 0, of a rope already swinging, is measured about a fixed end not yet confirmed (``fixed_end_guess``).
    assert [r["status"] for r in records] == ["IMPLAUSIBLE", "BAD_FRAME", "OK", "OK"]
    assert records[0]["reason"] == "fixed_end_guess"
    assert "001.png" in records[1]["message"]
    assert records[0]["method"] == "CENTERLINE"
    assert records[2]["t_ns"] == round(2 * 1e9 / 119)
    assert records[0]["material_points"]["s_m"] == [1.0, 2.0]
    assert main([*argv, "--method", "paper", "--quiet", "--force"]) == 0
    assert _read(out)[0]["method"] in ("PAPER", None)


def test_extract_errors_are_clear(tmp_path, capsys) -> None:
    assert main(["extract", str(tmp_path / "missing"), "--out", str(tmp_path / "o.jsonl")]) == 1  # runtime
    assert "no such file or folder" in capsys.readouterr().err
    config = tmp_path / "bad.toml"
    config.write_text("[pipeline]\ncanny_lo = 3\n")
    folder = tmp_path / "imgs"
    folder.mkdir()
    cv2.imwrite(str(folder / "a.png"), np.zeros((20, 20), np.uint8))
    assert main(["extract", str(folder), "--out", str(tmp_path / "o.jsonl"), "--config", str(config)]) == 2
    err = capsys.readouterr().err
    assert "canny_lo" in err and "bad.toml" in err


def test_extract_video(tmp_path, frames) -> None:
    path = tmp_path / "run.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 119.0, (ROPE.width, ROPE.height), False)
    if not writer.isOpened():
        pytest.skip("this OpenCV build cannot write MJPG video")
    for f in frames:
        writer.write(f.image)
    writer.release()
    out = tmp_path / "video.jsonl"
    assert main(["extract", str(path), "--out", str(out), "--exposure-ms", "12", "--quiet"]) == 0
    records = _read(out)
    assert len(records) == len(frames)
    assert [r["status"] for r in records[2:]] == ["OK"] * (len(frames) - 2)
    assert (records[0]["status"], records[0]["reason"]) == ("IMPLAUSIBLE", "order")  # its order undecided
    # Frame 1 (the MJPG's outline): OK, or measured about a fixed end not yet confirmed by the frames' motion.
    assert records[1]["status"] == "OK" or records[1]["reason"] == "fixed_end_guess", records[1]
    assert records[1]["t_ns"] == round(1e9 / 119.0)


def test_an_image_folder_without_exposure_time_keeps_going_past_a_broken_file(tmp_path, frames) -> None:
    folder = tmp_path / "png"
    folder.mkdir()
    for f in frames[:3]:
        cv2.imwrite(str(folder / f"{f.index:03d}.png"), f.image)
    (folder / "001.png").write_bytes(b"not a png")
    out = tmp_path / "out.jsonl"
    assert main(["extract", str(folder), "--out", str(out), "--quiet"]) == 0  # no --exposure-ms: unknown
    records = _read(out)
    assert [r["status"] for r in records] == ["OK", "BAD_FRAME", "OK"]
    assert all(r["t_end_ns"] == r["t_ns"] for r in records)
