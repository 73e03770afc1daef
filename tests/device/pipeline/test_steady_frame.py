"""`steady_frame` (a steady frame in one kernel call) against the same kernels called one by one from the stages,
and the table of buffers it reads (`buffer_table`)."""

from __future__ import annotations

import copy
import dataclasses
import functools
import pickle

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline import steady as steady_module
from ropecam.device.pipeline._views import FrameSlot, RecordCells, array_layout_known, buffer_table
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus
from ropecam.device.pipeline.workspace import steady_constants
from ropecam.shared.plane import PlaneCalibration

pytestmark = pytest.mark.kernel


def _rope(phase_rad: float) -> SyntheticRope:
    return SyntheticRope(
        exposure_us=4000, amplitude_rad=0.6, period_s=0.9, diameter_px=3.0, phase_rad=phase_rad, fps=119.0
    )


@functools.cache
def _frames(count: int) -> tuple[tuple[np.ndarray, int, int, float], ...]:
    """A swinging rope; at frame 24 the rope of another phase at the same time (a jump the band misses)."""
    rope = _rope(0.0)
    frames = [(f.image, f.index, f.t_ns, f.exposure_us) for f in rope.frames(count)]
    jump = next(iter(_rope(1.0).frames(1, start=24)))
    frames[24] = (jump.image, 24, frames[24][2], jump.exposure_us)
    return tuple(frames)


_RUNS: dict[tuple[bool, bool, bool], tuple[list[dict], list[int]]] = {}
_CHECKED: dict[tuple[bool, bool, bool], list[int]] = {}
"""The self-checks' code each `steady_frame` call wrote (-1: it left the check to the stages' Python)."""
_PLACED: dict[tuple[bool, bool, bool], list[int]] = {}
"""Whether each call placed the material points on the plane (1) or left them to the stages' Python (-1)."""


def _plane() -> PlaneCalibration:
    """A camera looking at the rope's plane, tilted, its origin projected at the synthetic rope's fixed end."""
    tilt = 0.3
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(tilt), -np.sin(tilt)], [0.0, np.sin(tilt), np.cos(tilt)]])
    camera = np.array([[400.0, 0.0, 160.0], [0.0, 400.0, 120.0], [0.0, 0.0, 1.0]])
    distance_m = 2.0
    origin = np.array([(160.3 - 160.0) / 400.0 * distance_m, (20.6 - 120.0) / 400.0 * distance_m, distance_m])
    return PlaneCalibration(camera, np.zeros(5), (320, 240), rotation, origin)


def _run(
    monkeypatch: pytest.MonkeyPatch, fused: bool, read_only: bool = False, plane: bool = False
) -> tuple[list[dict], list[int]]:
    """Every PipelineResult field (but the time) and the state that links frames, after each frame; and the
    `steady_frame` returns. Without `fused`, the pipeline never takes the one-call path; with `plane`, the
    material points are placed on `_plane`."""
    run = (fused, read_only, plane)
    if run in _RUNS:
        return _RUNS[run]
    stops: list[int] = []
    real = K.steady_frame

    outs: list[np.ndarray] = []  # the pipeline's `STEADY_OUT` record

    def counted(*args):
        stops.append(int(real(*args)))
        _CHECKED[run].append(int(outs[0][0]["check"]))
        _PLACED[run].append(int(outs[0][0]["placed"]))
        return stops[-1]

    _CHECKED[run], _PLACED[run] = [], []

    with monkeypatch.context() as patch:
        patch.setattr(K, "steady_frame", counted)
        frames = _frames(46)
        pipeline = Pipeline(
            PipelineConfig(), (frames[0][0].shape[1], frames[0][0].shape[0]), plane=_plane() if plane else None
        )
        pipeline.one_call = fused
        outs.append(pipeline.workspace.steady_out)
        rows = []
        for image, index, t_ns, exposure_us in frames:
            if read_only:
                image = image.copy()
                image.flags.writeable = False
            result = pipeline.process(image, index, t_ns, exposure_us)
            row = {
                f.name: _copy(getattr(result, f.name)) for f in dataclasses.fields(result) if f.name != "pipeline_us"
            }
            motion, order = pipeline._motion, pipeline._time_order
            row.update(
                lo=pipeline.lo.copy(), hi=pipeline.hi.copy(), motion_state=motion.state.copy(),
                motion_log=motion.log.copy(), need=motion.need.copy(), profile=motion.profile.copy(),
                band=motion.band.copy(), owed=motion.owed, order_state=order.state.copy(),
                order_hist=order.hist_rc.copy(), sweep=pipeline.splitter.sweep_px, count=pipeline.tracer.count,
                counters=(pipeline.frames_roi, pipeline.frames_coarse, pipeline.frames_full, pipeline.roi_retries),
            )  # fmt: skip
            rows.append(row)
    _RUNS[run] = (rows, stops)
    return rows, stops


def _copy(value):
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, tuple):
        return tuple(_copy(v) for v in value)
    return value


def _assert_identical(got: list[dict], want: list[dict]) -> None:
    for index, (row_got, row_want) in enumerate(zip(got, want, strict=True)):
        assert row_got.keys() == row_want.keys()
        for key, value in row_want.items():
            other = row_got[key]
            if isinstance(value, np.ndarray) or isinstance(other, np.ndarray):
                assert isinstance(other, np.ndarray) and isinstance(value, np.ndarray), f"frame {index} {key}"
                np.testing.assert_array_equal(other, value, err_msg=f"frame {index} {key}")
                assert other.dtype == value.dtype, f"frame {index} {key}"
            elif isinstance(value, tuple) and any(isinstance(v, np.ndarray) for v in value):
                for a, b in zip(other, value, strict=True):
                    np.testing.assert_array_equal(a, b, err_msg=f"frame {index} {key}")
            elif isinstance(value, float) and np.isnan(value):
                assert isinstance(other, float) and np.isnan(other), f"frame {index} {key}: {other} != nan"
            elif isinstance(value, dict):  # the quality record: nan where a measure does not apply
                assert other.keys() == value.keys(), f"frame {index} {key}"
                np.testing.assert_array_equal(list(other.values()), list(value.values()), f"frame {index} {key}")
            else:
                assert other == value, f"frame {index} {key}: {other!r} != {value!r}"


@pytest.mark.jit_only  # 46 frames of a pipeline: minutes in plain Python; the parts below run there
def test_steady_frames_are_the_calls_one_by_one(monkeypatch: pytest.MonkeyPatch) -> None:
    fused, stops = _run(monkeypatch, fused=True)
    steps, no_stops = _run(monkeypatch, fused=False)
    assert not no_stops
    # Every way out of the kernel was taken: the whole frame, a split that is not two shapes (the rope at a
    # turning point: static), the jumped rope the band misses (and the frame after it, searched anew).
    assert stops.count(K.STEADY_DONE) >= 5
    assert K.STEADY_AFTER_SPLIT in stops
    assert K.STEADY_AFTER_CONTOUR in stops
    assert fused[24]["counters"][1] > fused[23]["counters"][1]  # the jump: the band missed, the coarse search ran
    # The self-checks ran inside the call on most steady frames (the first settled ones have no prediction yet).
    assert sum(code >= 0 for code in _CHECKED[(True, False, False)]) >= 5
    assert set(_PLACED[(True, False, False)]) == {-1}  # no plane: nothing placed
    _assert_identical(fused, steps)


@pytest.mark.jit_only
def test_steady_frames_on_a_plane_are_the_calls_one_by_one(monkeypatch: pytest.MonkeyPatch) -> None:
    # The call places the material points on the plane (`place_on_plane`) as `ResultFinisher` does.
    fused, stops = _run(monkeypatch, fused=True, plane=True)
    steps, _ = _run(monkeypatch, fused=False, plane=True)
    assert stops.count(K.STEADY_DONE) >= 5
    assert _PLACED[(True, False, True)].count(1) == stops.count(K.STEADY_DONE)
    in_pixels = _run(monkeypatch, fused=True)[0]
    assert any(  # the plane moved the material points
        a["material_begin"] is not None
        and b["material_begin"] is not None
        and not np.array_equal(a["material_begin"], b["material_begin"])
        for a, b in zip(fused, in_pixels, strict=True)
    )
    _assert_identical(fused, steps)


@pytest.mark.jit_only
def test_steady_frames_of_read_only_frames(monkeypatch: pytest.MonkeyPatch) -> None:
    read_only, stops = _run(monkeypatch, fused=True, read_only=True)
    assert stops.count(K.STEADY_DONE) >= 5
    _assert_identical(read_only, _run(monkeypatch, fused=True)[0])


def _table_buffers() -> dict[str, np.ndarray | FrameSlot]:
    buffers: dict[str, np.ndarray | FrameSlot] = {
        name: np.zeros((3,) * ndim, dtype) for name, dtype, ndim in K.STEADY_BUFFERS
    }
    buffers["frame_slot"] = FrameSlot(3, 3)
    return buffers


def test_steady_frame_refuses_bad_tables_and_frames_before_any_call() -> None:
    buffers = _table_buffers()
    slot = buffers["frame_slot"]
    assert isinstance(slot, FrameSlot)
    band_state = buffers["band_state"].copy()
    frame = np.zeros((3, 3), np.uint8)

    def call(**replaced: np.ndarray) -> int:
        table = buffer_table({**buffers, **replaced}, K.STEADY_BUFFERS)
        slot.hold(frame)
        try:
            return int(K.steady_frame(table.ctypes.data))
        finally:
            slot.release()

    out = buffers["out"]
    assert isinstance(out, np.ndarray)
    assert call(constants=np.zeros(0, K.STEADY_CONSTANTS)) == K.INVALID  # no constants record
    assert call(out=np.zeros(0, K.STEADY_OUT)) == K.INVALID  # no result record
    assert call(args=np.zeros(0, K.STEADY_ARGS)) == K.INVALID  # no record of the frame's scalars
    frame = np.zeros((3, 4), np.uint8)  # a frame of another size than the slot's
    assert call() == K.INVALID
    frame = np.zeros((3, 6), np.uint8)[:, ::2]  # of the slot's size, not C-contiguous
    assert call() == K.INVALID
    frame = np.zeros((3, 3), np.uint8)
    table = buffer_table(buffers, K.STEADY_BUFFERS)  # an empty slot
    assert K.steady_frame(table.ctypes.data) == K.INVALID
    # The split's state and info shorter than the kernels need: refused too (the split's state is 3 long).
    assert call() == K.INVALID
    np.testing.assert_array_equal(buffers["band_state"], band_state)  # nothing written: band_stage did not run
    assert not out.view(np.uint8).any()


def test_record_cells_read_and_write_the_records_fields() -> None:
    """`steady_frame`'s per-frame scalars are written, its results read, cell by cell (`RecordCells`): each cell is
    its field, ints and floats exactly."""
    record = np.zeros(1, K.STEADY_ARGS)
    cells = RecordCells(record)
    cells.ints[cells.slot("t_ns")] = 2**62 + 3
    cells.ints[cells.slot("predict")] = True
    cells.floats[cells.slot("last_sweep_px")] = 0.1
    cells.floats[cells.slot("check_width_px")] = np.float32(2.7)  # a float32 widened as NumPy widens it
    assert record["t_ns"][0] == 2**62 + 3 and record["predict"][0] == 1 and record["measure"][0] == 0
    assert record["last_sweep_px"][0] == 0.1 and record["check_width_px"][0] == np.float64(np.float32(2.7))
    out = np.zeros(1, K.STEADY_OUT)
    out["swap"], out["confidence"], out["placed"] = 1, 0.75, -1
    read = RecordCells(out)
    assert read.ints[read.slot("swap")] == 1 and read.floats[read.slot("confidence")] == 0.75
    assert read.ints[read.slot("placed")] == -1
    with pytest.raises(ValueError, match="8-byte fields"):
        RecordCells(np.zeros(1, K.STEADY_CONSTANTS))  # float32 and int32 fields
    with pytest.raises(ValueError, match="one C-contiguous record"):
        RecordCells(np.zeros(2, K.STEADY_OUT))


def test_frame_slot_reads_numpys_array_layout() -> None:
    """The kernels read the frame's address, dimensions and strides from its `PyArrayObject` (`FrameSlot`)."""
    assert array_layout_known()
    slot = FrameSlot(4, 6)
    address, one, height, width = slot.row()
    assert (one, height, width) == (1, 4, 6) and address != 0


def test_steady_frame_records_are_named_as_the_stages_read_them() -> None:
    """The constants and results travel as one record each, by name (`STEADY_CONSTANTS`, `STEADY_OUT`)."""
    names = K.STEADY_CONSTANTS.names
    assert {"low", "high", "min_pixels", "length0_px", "broken_outline"} <= set(names)
    assert K.STEADY_OUT.names == (
        "motion_px", "points", "status", "revisits", "swap", "confidence", "stretch_begin", "stretch_end", "check",
        "placed",
    )  # fmt: skip
    values = {name: float(k + 1) for k, name in enumerate(names)}
    values["low"] = 6.4712345  # stored as the float32 `detect_and_trace` takes
    record = steady_constants(**values)
    assert record.dtype == K.STEADY_CONSTANTS and record.shape == (1,) and not record.flags.writeable
    assert record.base is not None and record.base.flags.writeable  # a view of writable memory: in the table
    assert record["low"][0] == np.float32(6.4712345) and record["broken_outline"][0] == values["broken_outline"]
    with pytest.raises(ValueError, match=r"missing: \['broken_outline'\]"):
        steady_constants(**{k: v for k, v in values.items() if k != "broken_outline"})


def test_buffer_table_holds_addresses_and_shapes_by_name() -> None:
    buffers = _table_buffers()
    points = buffers["prev_points"] = np.zeros((5, 2), np.float32)
    table = buffer_table(buffers, K.STEADY_BUFFERS)
    assert table.shape == (len(K.STEADY_BUFFERS), 4) and table.dtype == np.int64
    assert table[K.STEADY_ROW.prev_points].tolist() == [points.ctypes.data, 5, 2, 0]
    slot = buffers["frame_slot"]
    assert isinstance(slot, FrameSlot) and table[K.STEADY_ROW.frame_slot].tolist() == list(slot.row())
    assert table[K.STEADY_ROW.sides, 1:].tolist() == [3, 3, 3]
    assert [name for name, _, _ in K.STEADY_BUFFERS] == list(K.STEADY_ROW._fields)
    assert list(K.STEADY_ROW) == list(range(len(K.STEADY_BUFFERS)))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda b: b.update(prev_points=np.zeros((5, 2), np.float64)), "buffer 'prev_points' is a float64 array of 2"),
        (lambda b: b.update(fixed=np.zeros((2, 2), np.float32)), "buffer 'fixed' is a float32 array of 2 dim"),
        (lambda b: b.update(prev_points=np.zeros((5, 4), np.float32)[:, ::2]), "'prev_points' must be C-contiguous"),
        (lambda b: b.update(fixed=[0.0, 0.0]), "buffer 'fixed' is a <class 'list'>"),
        (lambda b: b.pop("lo"), "buffers missing: ['lo']; not in the table: none"),
        (lambda b: b.update(spare=np.zeros(3)), "buffers missing: none; not in the table: ['spare']"),
    ],
)
def test_buffer_table_refuses_wrong_buffers(change, message: str) -> None:
    buffers = _table_buffers()
    change(buffers)
    with pytest.raises((TypeError, ValueError), match=message.replace("(", r"\(").replace("[", r"\[")):
        buffer_table(buffers, K.STEADY_BUFFERS)


def test_buffer_table_refuses_read_only_memory() -> None:
    buffers = _table_buffers()
    frozen = np.zeros(3, np.float32)
    frozen.flags.writeable = False  # memory of its own, read-only (a mapped file): a kernel write would crash
    buffers["fixed"] = frozen
    with pytest.raises(TypeError, match="'fixed' must be C-contiguous in writable memory"):
        buffer_table(buffers, K.STEADY_BUFFERS)
    view = np.zeros(3, np.float32).view()
    view.flags.writeable = False  # a read-only view of writable memory is taken
    buffers["fixed"] = view
    assert buffer_table(buffers, K.STEADY_BUFFERS)[K.STEADY_ROW.fixed, 0] == view.ctypes.data


def test_a_pipeline_cannot_be_copied_or_pickled() -> None:
    """A copy would share the raw addresses of the steady frame's table: it is refused, with a message."""
    pipeline = Pipeline(PipelineConfig(), (32, 24))
    for copy_it in (copy.copy, copy.deepcopy, pickle.dumps):
        with pytest.raises(TypeError, match="a Pipeline cannot be copied or pickled"):
            copy_it(pipeline)


def test_the_table_buffers_cannot_be_replaced() -> None:
    """The buffers `steady_frame`'s table points at belong to the frozen workspace: neither the workspace's
    groups nor the stages' attributes for them can be rebound (the table would point at the old memory)."""
    pipeline = Pipeline(PipelineConfig(), (32, 24))
    ws = pipeline.workspace
    with pytest.raises(dataclasses.FrozenInstanceError):
        ws.edges.gx = np.zeros_like(ws.edges.gx)  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        ws.split = ws.split  # type: ignore[misc]
    for stage, name in ((pipeline.edges, "gx"), (pipeline.tracer, "points"), (pipeline.splitter, "sides"),
                        (pipeline.tracker, "work"), (pipeline._motion, "profile"), (pipeline._time_order, "state"),
                        (pipeline, "lo")):  # fmt: skip
        with pytest.raises(AttributeError):
            setattr(stage, name, getattr(stage, name).copy())
    # Every buffer of the table is one of the workspace's (or of the rope width's tables, which the pipeline
    # keeps with the table).
    assert pipeline.edges.gx is ws.edges.gx and pipeline.tracker.work is ws.track.work


@pytest.mark.jit_only  # a dozen frames of a pipeline
def test_the_one_call_gives_track_frame_the_rope_width_the_steps_give_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """`track_frame` tests for crossing shapes against the rope's width (`uncross_shapes`). The step-by-step path
    gives it the edge model's width for the edge spacing (`SplitOutcome.width_px`); the one call bound the edge
    spacing instead until session 17 (the late swing's crossing frames 30 and 53: centreline 0.62 and 0.53 px in
    one call, 0.32 and 0.22 step by step)."""
    made: list[dict] = []
    real = steady_module.steady_constants

    def recorded(**values: float):
        made.append(values)
        return real(**values)

    monkeypatch.setattr(steady_module, "steady_constants", recorded)
    frames = _frames(46)[:24]  # (to the jump at frame 24)
    pipeline = Pipeline(PipelineConfig(), (frames[0][0].shape[1], frames[0][0].shape[0]))
    for image, index, t_ns, exposure_us in frames:
        pipeline.process(image, index, t_ns, exposure_us)
    assert made, "no steady frame was bound"
    steps_width = float(pipeline.splitter.frame_call.width_px)
    assert made[-1]["rope_width_px"] == steps_width
    assert abs(steps_width - float(pipeline.splitter.width)) > 0.1  # the scene tells the two widths apart


@pytest.mark.jit_only  # 2 x 32 frames of a pipeline
def test_steady_frames_on_a_dusty_plate_are_the_calls_one_by_one(
    monkeypatch: pytest.MonkeyPatch, swinging_rope: SyntheticRope, dusty_frames: list[tuple[object, np.ndarray]]
) -> None:
    """On a dusty plate the learned mask reaches every free tip (`tip_masked`) and the frame disproves it: the one
    call withdraws the verdict itself (`steady_frame`), the steps in `SelfChecks.check`; the same results frame for
    frame (review of session 17)."""
    rope = swinging_rope
    frames = [(image, f.index, f.t_ns, float(rope.exposure_us)) for f, image in dusty_frames]  # type: ignore[attr-defined]
    config = PipelineConfig(static_frames=6)
    rows: dict[bool, list[dict]] = {}
    stops: list[int] = []
    real = K.steady_frame

    def counted(*args):
        stops.append(int(real(*args)))
        return stops[-1]

    with monkeypatch.context() as patch:
        patch.setattr(K, "steady_frame", counted)
        for fused in (True, False):
            pipeline = Pipeline(config, (rope.width, rope.height))
            pipeline.one_call = fused
            rows[fused] = []
            for frame in frames:
                result = pipeline.process(*frame)
                rows[fused].append(
                    {
                        f.name: _copy(getattr(result, f.name))
                        for f in dataclasses.fields(result)
                        if f.name != "pipeline_us"
                    }
                )
    assert stops.count(K.STEADY_DONE) >= 5  # the one call measured whole frames
    blind = Pipeline(config, (rope.width, rope.height))
    blind._finisher.static_mask = blind._steady.static_mask = None
    assert sum(blind.process(*frame).reason == "tip_masked" for frame in frames) >= 5  # verdicts to withdraw
    assert {row["status"] for row in rows[True]} == {FrameStatus.OK}
    _assert_identical(rows[True], rows[False])
