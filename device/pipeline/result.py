"""The per-frame result of the pipeline and its JSON form (the record the wire protocol carries)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.shared.protocol.frame_result import FrameResult, FrameStatus, Method, Reason
from ropecam.shared.protocol.jsonl import frame_result_json

# FrameStatus and Method are the wire protocol's: one definition of what happened to a frame, on both sides.
__all__ = ["FrameStatus", "Method", "PipelineResult", "SplitOutcome", "exposure_in_ns", "frame_problem", "to_wire"]


def _uv(points: NDArray[np.float32] | None, digits: int = 3) -> list[list[float]] | None:
    """(row, col) points to a JSON list of [u, v] = [col, row]."""
    if points is None:
        return None
    return [[round(float(p[1]), digits), round(float(p[0]), digits)] for p in points]


@dataclass(slots=True)
class PipelineResult:
    """The measurement of one frame, as `Pipeline.process` returns it (the wire's record of it is
    `ropecam.shared.protocol.FrameResult`, made by `to_wire`). Arrays are (row, col) float32 views into the
    pipeline's buffers, valid until its next call; `to_json` copies them out as (u, v) = (col, row) lists.

    ``begin``/``end`` are the centrelines at the start and end of the exposure, fixed end first; ``None`` when not
    measured. ``order_confidence`` (0-1) says how sure the pipeline is that ``begin`` really is the earlier shape.
    ``readout_ns`` is the rolling shutter's readout time (0: global shutter): a point of ``begin`` on image row r
    (its v) was seen at ``t_ns + r / height * readout_ns``, a point of ``end`` at ``t_end_ns + r / height *
    readout_ns`` (height: the image's rows); material points likewise.
    """

    frame: int
    t_ns: int
    t_end_ns: int
    status: FrameStatus
    method: Method | None = None
    order_confidence: float = 0.0
    begin: NDArray[np.float32] | None = None
    end: NDArray[np.float32] | None = None
    fixed_end: NDArray[np.float32] | None = None
    segmentation_points: NDArray[np.float32] | None = None
    material_arc_m: tuple[float, ...] = ()
    material_begin: NDArray[np.float32] | None = None
    material_end: NDArray[np.float32] | None = None
    stretch_begin: float | None = None
    stretch_end: float | None = None
    rope_width_px: float | None = None
    full_frame: bool = True
    pipeline_us: float = 0.0
    message: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    reason: str = ""
    """Why the status is not OK when a self-check failed (`Reason`'s text: ``"length"``, ``"no_blur"``, ...)."""
    quality: dict[str, float] = field(default_factory=dict)
    """The self-checks' measures (`QUALITY_KEYS`; the pipeline's dict, valid until its next call)."""
    readout_ns: int = 0
    """Rolling-shutter readout time of the frame (ns, 0 = global shutter)."""

    def reset(self, frame: int, t_ns: int, t_end_ns: int, status: FrameStatus, quality: dict[str, float]) -> None:
        """Make this record the new record of frame `frame` exposed from `t_ns` to `t_end_ns` with `status`: every
        other field to its default, ``extra`` emptied and ``quality`` set to `quality` (an empty dict its owner
        keeps, so that a reused record allocates nothing; see `Pipeline.process`'s `out`)."""
        self.frame, self.t_ns, self.t_end_ns, self.status = frame, t_ns, t_end_ns, status
        self.method = self.begin = self.end = self.fixed_end = self.segmentation_points = None
        self.material_begin = self.material_end = self.stretch_begin = self.stretch_end = self.rope_width_px = None
        self.order_confidence = 0.0
        self.material_arc_m = ()
        self.full_frame = True
        self.pipeline_us = 0.0
        self.message = self.reason = ""
        if self.extra:
            self.extra.clear()
        self.quality = quality
        self.readout_ns = 0

    @property
    def tips(self) -> tuple[NDArray[np.float32], NDArray[np.float32]] | None:
        """The free tips (row, col) at the start and end of the exposure."""
        if self.begin is None or self.end is None:
            return None
        return self.begin[-1], self.end[-1]

    def to_json(self) -> dict[str, Any]:
        """Return the JSON object of this frame: the wire record's (`ropecam.shared.protocol.jsonl`, pixels to
        1/1000 px) plus the fields only the device knows (``DEVICE_ONLY_FIELDS`` there)."""
        record = frame_result_json(to_wire(self), digits=3)
        record.update(
            segmentation_points=_uv(self.segmentation_points),
            rope_width_px=None if self.rope_width_px is None else round(float(self.rope_width_px), 3),
            roi=not self.full_frame,
            message=self.message,
        )
        return record


@dataclass(slots=True)
class SplitOutcome:
    """The shapes the split found in one contour (views into the splitter's buffers, valid until its next call).

    `shape_a` and `shape_b` run from the fixed end to the tip; for single-shape methods they are the same array.
    They are not yet in time order: the pipeline decides which one is the start of the exposure.
    """

    method: Method
    shape_a: NDArray[np.float32]
    shape_b: NDArray[np.float32]
    segmentation_points: NDArray[np.float32] | None
    width_px: float
    sweep_px: float


def _wire_uv(points: NDArray[np.float32] | None) -> NDArray[np.float32] | None:
    """(row, col) -> (u, v): a reversed view (the wire record copies it to float64 when it checks it)."""
    if points is None:
        return None
    return points[:, ::-1]


def _tip(points: NDArray[np.float32] | None) -> tuple[float, float] | None:
    if points is None or len(points) == 0:
        return None
    row, col = points[-1].tolist()
    return col, row


def to_wire(result: PipelineResult) -> FrameResult:
    """Build the FrameResult message record of one pipeline result (shapes fixed end first, (u, v) pixels)."""
    begin, end = _wire_uv(result.begin), _wire_uv(result.end)
    material_s = tuple(float(s) for s in result.material_arc_m) if result.material_begin is not None else ()
    material_begin = _wire_uv(result.material_begin) if material_s else np.zeros((0, 2))
    material_end = _wire_uv(result.material_end) if material_s and result.material_end is not None else material_begin
    fixed = None if result.fixed_end is None else (float(result.fixed_end[1]), float(result.fixed_end[0]))
    return FrameResult(
        frame_index=int(result.frame),
        exposure_start_t_ns=int(result.t_ns),
        exposure_end_t_ns=int(result.t_end_ns),
        status=FrameStatus(result.status),
        method=Method.BLUR_SPLIT if result.method is None else Method(result.method),
        order_confidence=min(max(float(result.order_confidence), 0.0), 1.0),
        begin_px=begin,
        end_px=end,
        begin_tip_px=_tip(result.begin),
        end_tip_px=_tip(result.end),
        fixed_end_px=fixed,
        material_s_m=material_s,
        material_begin_px=material_begin,
        material_end_px=material_end,
        stretch_begin=np.nan if result.stretch_begin is None else float(result.stretch_begin),
        stretch_end=np.nan if result.stretch_end is None else float(result.stretch_end),
        pipeline_us=round(float(result.pipeline_us)),
        reason=Reason.from_text(result.reason),
        readout_ns=int(result.readout_ns),
        quality=result.quality,
    )


def frame_problem(frame: object, shape: tuple[int, int]) -> str:
    """Return why `frame` is not a (height, width) = `shape` uint8 image ('' when it is one)."""
    if not isinstance(frame, np.ndarray):
        return f"frame is a {type(frame).__name__}, expected a numpy array"
    if frame.dtype != np.uint8:
        return f"frame dtype is {frame.dtype}, expected uint8"
    if frame.ndim != 2:
        return f"frame has shape {frame.shape}, expected 2-D {shape}"
    if frame.shape != shape:
        return f"frame shape is {frame.shape}, expected {shape}"
    return ""


def exposure_in_ns(exposure_us: object) -> tuple[int, str]:
    """Return a frame's exposure `exposure_us` (microseconds; None or 0: unknown) in integer ns (0 = unknown) and
    a problem message ('' when fine)."""
    if exposure_us is None:
        return 0, ""
    try:
        value = float(exposure_us)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return 0, f"exposure_us is {exposure_us!r}, expected a number of microseconds (0 = unknown)"
    if not math.isfinite(value) or value < 0:
        return 0, f"exposure_us is {value}, expected a finite number of microseconds >= 0 (0 = unknown)"
    return round(value * 1000.0), ""
