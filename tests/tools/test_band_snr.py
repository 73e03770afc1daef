"""`evaluate.py band-snr`: the band's step, the plate's noise and the fitted far end and side of a band drawn with a
known contrast, sweep and noise."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSetWriter

RunTool = Callable[..., subprocess.CompletedProcess[str]]

CONTRAST_DN, WIDTH_PX, SWEEP_PX, NOISE_DN = 60.0, 2.0, 6.0, 4.0
ROW_PX, FIRST_COL, TIP_COL = 60.0, 20.0, 220.0


def _write_band_set(root: Path, frames: int = 3) -> None:
    """A straight rope along a row sweeping SWEEP_PX down during the exposure: a band of level contrast * w / (w + d)
    from its begin edge to its end edge, ending at the tip's column, lens-blurred, with Gaussian noise."""
    height, width = 120, 260
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)
    top, bottom = ROW_PX - WIDTH_PX / 2, ROW_PX + SWEEP_PX + WIDTH_PX / 2
    # each pixel's covered area (pixel i spans i - 0.5 .. i + 0.5)
    across = np.clip(np.minimum(rows + 0.5, bottom) - np.maximum(rows - 0.5, top), 0.0, 1.0)
    band = across * np.clip(TIP_COL + 0.5 - cols, 0.0, 1.0)
    level = CONTRAST_DN * WIDTH_PX / (WIDTH_PX + SWEEP_PX)
    clean = cv2.GaussianBlur(40.0 + level * band, (0, 0), 0.7)
    arc = np.arange(FIRST_COL, TIP_COL + 0.01, 0.5)
    begin = np.stack([arc, np.full_like(arc, ROW_PX)], axis=1)
    end = begin + np.array([0.0, SWEEP_PX])
    rng = np.random.default_rng(3)
    with FrameSetWriter(root, (width, height), 100.0) as writer:
        for i in range(frames):
            noisy = clean + rng.normal(0.0, NOISE_DN, clean.shape)
            writer.add(np.clip(np.round(noisy), 0, 255).astype(np.uint8), i * 10_000_000, 4000)
        writer.write_truth({
            "begin_px": np.repeat(begin[None], frames, 0), "end_px": np.repeat(end[None], frames, 0),
            "tip_begin_px": np.repeat(begin[-1:], frames, 0), "tip_end_px": np.repeat(end[-1:], frames, 0),
            "width_px": np.full(frames, WIDTH_PX),
        })  # fmt: skip


def test_band_snr_reads_the_drawn_band(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "tools"))
    from ropecam_tools.eval_band_snr import measure_set, summarise

    _write_band_set(tmp_path / "band")
    rows = measure_set(tmp_path / "band")
    assert len(rows) == 3
    level = CONTRAST_DN * WIDTH_PX / (WIDTH_PX + SWEEP_PX)
    for row in rows:
        assert row["sweep_px"] == pytest.approx(SWEEP_PX)
        assert row["noise"] == pytest.approx(NOISE_DN, rel=0.15)
        assert row["step"] == pytest.approx(level, rel=0.15)
        assert row["snr_px"] == pytest.approx(level / NOISE_DN, rel=0.25)
        assert abs(row["cap_px"]) < 0.3  # the band ends at the tip's column
        assert row["side_px"] == pytest.approx(-WIDTH_PX / 2, abs=0.3)  # the begin side: half a width behind
    (summary,) = summarise(rows)
    assert summary["frames"] == 3 and summary["sweep_from_px"] == 3.0
    # the band stands still from frame to frame: the prediction is the truth, from frame 2 on
    (predicted,) = measure_set(tmp_path / "band", predicted=True)
    assert predicted["frame"] == 2 and predicted["cap_px"] == pytest.approx(rows[2]["cap_px"], abs=1e-6)


def test_band_snr_command_prints_its_table(tmp_path: Path, run_tool_here: RunTool) -> None:
    _write_band_set(tmp_path / "band", frames=2)
    done = run_tool_here("evaluate.py", "band-snr", str(tmp_path / "band"))
    assert done.returncode == 0, done.stderr
    assert "| 3-10 | 2 |" in done.stdout and "simulated" in done.stdout
