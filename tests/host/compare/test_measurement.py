"""Reading extract results and tracking material points in metres."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest

from ropecam.host.calibration.geometry import CameraModel, PlanePose
from ropecam.host.compare.measurement import (
    measured_frame,
    points_at_arc_lengths,
    read_extract_jsonl,
    tracks_from_frames,
)
from ropecam.shared.errors import DataError
from ropecam.shared.protocol import FrameStatus, MessageType, decode_message, encode_message
from ropecam.shared.protocol.examples import example_records
from ropecam.shared.protocol.quality import WIRE_TOLERANCE_KEY

CAMERA = CameraModel(np.array([[1000.0, 0, 500], [0, 1000.0, 300], [0, 0, 1]]), np.zeros(5), (1000, 600))
PLANE = PlanePose(np.eye(3), np.array([0.0, 0.0, 1.0]))  # fronto-parallel at 1 m: 1 px = 1 mm, origin at (500, 300)


def _write(path: Path, records: list[dict]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    return path


def test_uniform_stretch_tracking_on_a_straight_curve() -> None:
    curve = np.column_stack([np.linspace(0.0, 0.22, 23), np.zeros(23)])  # 0.22 m measured for a 0.2 m rope
    points, stretch = points_at_arc_lengths(curve, np.array([0.0, 0.1, 0.2]), 0.2)
    assert stretch == pytest.approx(1.1)
    np.testing.assert_allclose(points, [[0.0, 0.0], [0.11, 0.0], [0.22, 0.0]], atol=1e-12)


def test_frames_become_metric_tracks_and_bad_frames_nan(tmp_path: Path) -> None:
    line = [[500.0, 300.0], [600.0, 300.0], [700.0, 300.0]]  # 0.2 m along +x
    records = [
        {"frame": 0, "t_ns": 0, "t_end_ns": 4_000_000, "status": "OK", "begin": line, "end": line},
        {"frame": 1, "t_ns": 8_000_000, "t_end_ns": 12_000_000, "status": "LOST_TRACK", "begin": line, "end": line},
        {"frame": 2, "t_ns": 16_000_000, "t_end_ns": 20_000_000, "status": "NO_ROPE", "begin": None, "end": None},
    ]
    frames = read_extract_jsonl(_write(tmp_path / "m.jsonl", records))
    tracks, stretch = tracks_from_frames(frames, CAMERA, PLANE, [0.1, 0.2], 0.2)
    np.testing.assert_allclose(tracks.times_s, [0, 0.004, 0.008, 0.012, 0.016, 0.020])
    np.testing.assert_allclose(tracks.positions_m[0], [[0.1, 0.0], [0.2, 0.0]], atol=1e-9)
    assert tracks.measured.tolist() == [[True, True], [True, True]] + [[False, False]] * 4
    np.testing.assert_allclose(stretch[:2], 1.0, atol=1e-9)


@pytest.mark.parametrize(
    ("record", "message"),
    [
        ({"frame": 0, "t_ns": 0, "begin": [[1, 2], [3, 4]], "end": [[1, 2], [3, 4]]}, "needs 't_end_ns'"),
        ({"frame": 0, "t_ns": 5, "t_end_ns": 5, "end": [[1, 2], [3, 4]]}, "needs 't_end_ns' after 't_ns'"),
        ({"frame": 0, "t_ns": 0, "t_end_ns": 4, "begin": [[1, 2]]}, "begin: expected a list of at least two"),
        ({"t_ns": 0}, "needs frame, t_ns"),
    ],
)
def test_malformed_records_name_file_and_line(tmp_path: Path, record: dict, message: str) -> None:
    good = {"frame": 0, "t_ns": 0, "t_end_ns": 4, "begin": None, "end": None}
    path = _write(tmp_path / "bad.jsonl", [good, record])
    with pytest.raises(DataError, match=message) as info:
        read_extract_jsonl(path)
    assert f"{path}:2" in str(info.value)


def test_a_shape_off_the_plane_is_skipped_and_named_and_most_off_is_an_error(tmp_path: Path) -> None:
    from ropecam.shared.errors import ConfigError

    tilted = PlanePose.from_rvec([0.6, 0, 0], [0, 0, 1.0])  # rows far below the image meet it behind the camera
    line = [[500.0, 100.0], [500.0, 200.0]]
    wild = [[500.0, 100.0], [500.0, 3000.0]]
    records = [
        {"frame": 4, "t_ns": 0, "t_end_ns": 4, "status": "OK", "begin": line, "end": line},
        {"frame": 5, "t_ns": 8, "t_end_ns": 12, "status": "OK", "begin": wild, "end": line},
    ]
    frames = read_extract_jsonl(_write(tmp_path / "m.jsonl", records))
    skipped: list[str] = []
    tracks, _ = tracks_from_frames(frames, CAMERA, tilted, [0.1], 0.2, skipped)
    assert tracks.measured.sum() == 3  # the other shapes are kept
    assert len(skipped) == 1 and re.search(r"frame 5 \(t_ns 8\): .*behind the camera.*skipped", skipped[0])
    records[0]["begin"] = records[0]["end"] = wild
    frames = read_extract_jsonl(_write(tmp_path / "m.jsonl", records))
    with pytest.raises(DataError, match=r"3 of 4 measured shapes miss the motion plane, e.g. frame 4 .*calibration"):
        tracks_from_frames(frames, CAMERA, tilted, [0.1], 0.2)
    records[0]["begin"] = records[0]["end"] = line
    records[1]["status"] = "LOST_TRACK"  # a frame the comparison ignores is never converted
    frames = read_extract_jsonl(_write(tmp_path / "m.jsonl", records))
    assert tracks_from_frames(frames, CAMERA, tilted, [0.1], 0.2)[0].measured.sum() == 2
    with pytest.raises(ConfigError, match=r"must lie in \[0, 0.2\] m"):
        tracks_from_frames(frames, CAMERA, tilted, [0.1, 0.3], 0.2)


def test_no_measured_shape_is_a_data_error(tmp_path: Path) -> None:
    from ropecam.host.compare.release import fit_release
    from ropecam.host.model.config import RopeConfig, SolverConfig

    records = [{"frame": 0, "t_ns": 0, "t_end_ns": 4, "status": "NO_ROPE", "begin": None, "end": None}]
    frames = read_extract_jsonl(_write(tmp_path / "m.jsonl", records))
    with pytest.raises(DataError, match=r"m\.jsonl: no frame has a measured rope shape"):
        fit_release(frames, (CAMERA, PLANE), RopeConfig(length_m=0.2), SolverConfig(), label=str(tmp_path / "m.jsonl"))


def test_a_frame_the_senders_byte_budget_cut_gives_no_samples() -> None:
    """Shapes the sender coded looser than the stream's tolerance (or left out) to fit the serial budget are not
    measured shapes for the tracks: decoded from the wire, that frame's samples are NaN, the other frame's not."""
    example = example_records()[MessageType.FRAME_RESULT]
    shape = np.column_stack([500.0 + np.linspace(0.0, 200.0, 41), np.full(41, 300.0)])  # 0.2 m from the origin
    sent = dataclasses.replace(example, status=FrameStatus.OK, begin_px=shape, end_px=shape + np.array([0.0, 1.0]))
    frames = []
    for i, quality in enumerate(({}, {WIRE_TOLERANCE_KEY: 1.0})):
        start = sent.exposure_start_t_ns + i * 8_400_000  # the next frame at 119 FPS
        record = dataclasses.replace(
            sent, frame_index=sent.frame_index + i, exposure_start_t_ns=start, exposure_end_t_ns=start + 4_000_000,
            quality={**sent.quality, **quality},
        )  # fmt: skip
        message = encode_message(record, device_id=1, sequence=1, t_ns=record.exposure_start_t_ns)
        frames.append(measured_frame(decode_message(message).record))
    assert frames[0].begin_px is not None and frames[1].begin_px is None and frames[1].end_px is None
    tracks, _ = tracks_from_frames(frames, CAMERA, PLANE, [0.1], 0.2)
    assert np.all(np.isfinite(tracks.positions_m[:2])) and np.all(np.isnan(tracks.positions_m[2:]))
