"""Issue 19 acceptance 9 through every entry point that takes the inputs (`ropecam-device extract` on a frame set
and on an image folder, `run`, `setup` updating an existing device.toml): a mask PNG of the wrong size, a plane
file whose origin projects outside the image, `readout_us` negative or longer than the frame period give a clear
error naming the key or the file, exit status 2, and nothing written (no output file, no result sent)."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSetWriter
from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.cli import main
from ropecam.shared.protocol import FrameResult, decode_message

ROPE = SyntheticRope(exposure_us=12000, amplitude_rad=0.7, period_s=0.9, diameter_px=3.0, phase_rad=1.2)
PlaneYaml = Callable[[Path, tuple[float, float], tuple[int, int]], Path]
"""The `plane_yaml` fixture (tests/device/conftest.py)."""


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory, plane_yaml: PlaneYaml) -> dict[str, Path]:
    """The rope's frames as a frame set (119 FPS) and as a folder of PNGs, and the bad files."""
    root = tmp_path_factory.mktemp("bad_input")
    frames = list(ROPE.frames(6))
    with FrameSetWriter(root / "set", (ROPE.width, ROPE.height), ROPE.fps) as writer:
        for f in frames:
            writer.add(f.image, f.t_ns, f.exposure_us)
    (root / "pngs").mkdir()
    for k, f in enumerate(frames):
        cv2.imwrite(str(root / "pngs" / f"frame_{k:03d}.png"), f.image)
    cv2.imwrite(str(root / "small_mask.png"), np.zeros((20, 32), np.uint8))
    plane_yaml(root / "far.yaml", (ROPE.width + 40.0, 20.0), (ROPE.width, ROPE.height))
    return {"set": root / "set", "pngs": root / "pngs", "mask": root / "small_mask.png", "plane": root / "far.yaml"}


BAD = {
    "mask": ("[pipeline]\nstatic_mask_png = '{mask}'\n", r"static_mask_png: mask {mask} is 32x20 px, the frames are"),
    "background": ("[pipeline]\nbackground_png = '{mask}'\n", r"background_png: {mask} is uint8 with shape"),
    "plane": ("[pipeline]\nplane_file = '{plane}'\n", r"{plane}: the plane origin (the rope's fixed end) projects"),
    "readout_negative": ("[capture]\nreadout_us = -3\n", "readout_us must be >= 0 (0 = global shutter), got -3"),
    "readout_too_long": ("[capture]\nreadout_us = 20000\n", "readout_us is 20000 us, longer than the frame period"),
}


def _config(tmp_path: Path, inputs: dict[str, Path], case: str) -> tuple[Path, str]:
    text, message = BAD[case]
    path = tmp_path / "device.toml"
    path.write_text(text.format(**inputs))
    return path, message.format(**inputs)


@pytest.mark.parametrize("case", sorted(BAD))
@pytest.mark.parametrize("source", ["set", "pngs"])
def test_extract_refuses_bad_input_and_writes_nothing(
    tmp_path: Path, inputs: dict[str, Path], capsys: pytest.CaptureFixture[str], case: str, source: str
) -> None:
    config, message = _config(tmp_path, inputs, case)
    out = tmp_path / "out.jsonl"
    argv = ["extract", str(inputs[source]), "--out", str(out), "--config", str(config), "--fps", "119", "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err
    if case.startswith("readout"):
        assert f"{config} [capture] readout_us" in err  # the file and the key
    assert not out.exists()


@pytest.mark.parametrize("case", sorted(BAD))
def test_the_daemon_refuses_bad_input_and_sends_no_result(
    tmp_path: Path, inputs: dict[str, Path], capsys: pytest.CaptureFixture[str], case: str
) -> None:
    config, message = _config(tmp_path, inputs, case)
    host = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    host.bind(("127.0.0.1", 0))
    host.settimeout(0.2)
    port = host.getsockname()[1]
    threads = set(threading.enumerate())
    try:
        argv = [
            "run",
            "--config",
            str(config),
            "--source",
            f"frames:{inputs['set']}",
            "--sink",
            f"udp://127.0.0.1:{port}",
        ]
        assert main(argv) == 2
        assert message in capsys.readouterr().err
        received = []
        while True:
            try:
                received.append(decode_message(host.recv(65536)).record)
            except TimeoutError:
                break
    finally:
        host.close()
    assert not any(isinstance(record, FrameResult) for record in received)
    # The link is closed with its control listener's thread (one left running aborted the process at exit).
    deadline = time.monotonic() + 2.0
    while set(threading.enumerate()) - threads and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not set(threading.enumerate()) - threads


@pytest.mark.parametrize("case", ["plane", "readout_negative", "readout_too_long"])
def test_setup_refuses_the_bad_settings_it_would_keep(
    tmp_path: Path, inputs: dict[str, Path], capsys: pytest.CaptureFixture[str], case: str
) -> None:
    """setup rewrites only the [pipeline] keys it decides: a plane file or readout time of the existing file that
    does not fit the frames is refused, and the file is left as it was (setup decides the mask itself)."""
    config, message = _config(tmp_path, inputs, case)
    before = config.read_text()
    assert main(["setup", str(inputs["set"]), "--out", str(config), "--force", "--quiet"]) == 2
    assert message in capsys.readouterr().err
    assert config.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["device.toml"]  # no mask, no overlay
