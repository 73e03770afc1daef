"""Rolling shutter on the host: each material point is compared with the model at its own row's time."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.host.compare.measurement import read_extract_jsonl, tracks_from_frames
from ropecam.host.compare.tracks import model_positions, point_errors
from ropecam.host.model.trajectory import Trajectory

CAMERA = CameraModel(np.array([[1000.0, 0, 500], [0, 1000.0, 300], [0, 0, 1]]), np.zeros(5), (1000, 600))
PLANE = PlanePose(np.eye(3), np.array([0.0, 0.0, 1.0]))  # fronto-parallel at 1 m: 1 px = 1 mm, origin (500, 300)
LENGTH_M = 0.2
SPEED_M_S = 1.0
READOUT_NS = 6_000_000


def _trajectory() -> Trajectory:
    """A straight rope hanging along +y, moving along +x at `SPEED_M_S` (one ANCF element: exact)."""
    times = np.array([0.0, 0.1])
    q = np.array([[SPEED_M_S * t, 0.0, 0.0, 1.0, SPEED_M_S * t, LENGTH_M, 0.0, 1.0] for t in times])
    qdot = np.tile([SPEED_M_S, 0.0, 0.0, 0.0] * 2, (2, 1))
    return Trajectory(LENGTH_M, times, q, qdot)


def _shape_px(t_ns: int) -> list[list[float]]:
    """The rope as a rolling shutter sees it from `t_ns`: the point on row v at t_ns + v / 600 * readout."""
    s = np.linspace(0.0, LENGTH_M, 21)
    rows = 300.0 + 1000.0 * s
    t_s = t_ns * 1e-9 + rows / 600.0 * READOUT_NS * 1e-9
    return np.column_stack([500.0 + 1000.0 * SPEED_M_S * t_s, rows]).tolist()


def _errors_mm(tmp_path: Path, readout_ns: int) -> float:
    records = []
    for frame in range(3):
        t_ns = 10_000_000 + frame * 8_000_000
        t_end_ns = t_ns + 4_000_000
        records.append(
            {"frame": frame, "t_ns": t_ns, "t_end_ns": t_end_ns, "status": "OK", "readout_ns": readout_ns,
             "begin": _shape_px(t_ns), "end": _shape_px(t_end_ns)}
        )  # fmt: skip
    path = tmp_path / f"m{readout_ns}.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    frames = read_extract_jsonl(path)
    assert frames[0].readout_ns == readout_ns
    tracks, _ = tracks_from_frames(frames, CAMERA, PLANE, [0.1, 0.2], LENGTH_M)
    return 1000.0 * point_errors(tracks, model_positions(_trajectory(), tracks, 0.0)).overall_rms_m


def test_each_point_is_compared_at_its_rows_time(tmp_path: Path) -> None:
    # With readout_ns the host times each point by its row: the model matches the measurement exactly.
    assert _errors_mm(tmp_path, READOUT_NS) < 1e-6
    # Read as a global shutter (readout_ns 0), the same shapes are 2.5-5 mm (row 400-500: 4-5 ms at 1 m/s) off.
    wrong = tmp_path / "wrong"
    wrong.mkdir()
    records = [json.loads(line) for line in (tmp_path / f"m{READOUT_NS}.jsonl").read_text().splitlines()]
    for record in records:
        record["readout_ns"] = 0
    (wrong / "m.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    frames = read_extract_jsonl(wrong / "m.jsonl")
    tracks, _ = tracks_from_frames(frames, CAMERA, PLANE, [0.1, 0.2], LENGTH_M)
    rms_mm = 1000.0 * point_errors(tracks, model_positions(_trajectory(), tracks, 0.0)).overall_rms_m
    assert 3.5 < rms_mm < 5.0


def test_the_model_error_channel_times_the_points_as_compare_does() -> None:
    """`replay --model` / the live monitor's ModelError: the same rows' times as compare; read at the exposure's
    start and end instead, the same shapes are 4-5 mm off."""
    from ropecam.host.model_overlay import ModelOverlay
    from ropecam.shared.protocol.records import FrameResult

    t_ns, t_end_ns = 10_000_000, 14_000_000
    shapes = {"begin_px": np.array(_shape_px(t_ns)), "end_px": np.array(_shape_px(t_end_ns))}
    overlay = ModelOverlay(_trajectory(), 0.0, LENGTH_M, (0.1, 0.2), (CAMERA, PLANE))
    begin, end = overlay.frame_errors_mm(FrameResult(3, t_ns, t_end_ns, readout_ns=READOUT_NS, **shapes))
    assert max(begin + end) < 1e-6
    begin, end = overlay.frame_errors_mm(FrameResult(3, t_ns, t_end_ns, **shapes))
    assert min(begin + end) > 3.9 and max(begin + end) < 5.1  # rows 400 and 500: 4 and 5 ms at 1 m/s
