"""The one JSON-lines writer of FrameResults (extract output, replay export)."""

from __future__ import annotations

import json

import numpy as np

from ropecam.shared.protocol.frame_result import FrameResult, FrameStatus, Method
from ropecam.shared.protocol.jsonl import frame_result_json


def test_measured_frame_with_unmeasured_material_points_is_strict_json() -> None:
    shape = np.array([[10.0, 20.0], [30.12345, 40.0]])
    record = FrameResult(3, 100, 200, method=Method.PAPER, order_confidence=0.87654321, begin_px=shape, end_px=shape,
                         begin_tip_px=(30.12345, 40.0), fixed_end_px=(10.0, 20.0), material_s_m=(0.1, 0.2),
                         material_begin_px=np.array([[11.0, 21.0], [np.nan, np.nan]]),
                         material_end_px=np.array([[12.0, 22.0], [13.0, 23.0]]), stretch_begin=1.01,
                         pipeline_us=412)  # fmt: skip
    record = FrameResult.unpack(record.pack())  # exactly what a decoded message holds
    line = json.loads(json.dumps(frame_result_json(record, digits=3), allow_nan=False))
    assert (line["frame"], line["t_ns"], line["t_end_ns"]) == (3, 100, 200)
    assert line["status"] == "OK" and line["method"] == "PAPER" and line["order_confidence"] == 0.8765
    assert line["tips"] == {"begin": line["begin"][-1], "end": None}
    assert line["material_points"]["s_m"] == [0.1, 0.2] and line["material_points"]["begin"][1] is None
    assert line["stretch"] == {"begin": 1.01, "end": None}
    assert line["fixed_end"] == [10.0, 20.0] and line["pipeline_us"] == 412
    exact = frame_result_json(record)
    assert exact["begin"] == record.begin_px.tolist()  # digits=None: the decoded values as they are


def test_frame_without_a_shape_has_nulls_and_no_method() -> None:
    line = frame_result_json(FrameResult(4, 0, 10, status=FrameStatus.NO_ROPE))
    assert line["status"] == "NO_ROPE" and line["method"] is None
    assert all(line[key] is None for key in ("begin", "end", "tips", "fixed_end", "material_points", "stretch"))
