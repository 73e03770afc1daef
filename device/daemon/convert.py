"""Turn the pipeline's per-frame result into the wire record (copies: the pipeline's arrays are reused)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline.result import FrameResult as PipelineResult
from ropecam.shared.protocol import FrameResult, FrameStatus, Method

__all__ = ["to_wire"]


def _uv(points: NDArray[np.float32] | None) -> NDArray[np.float64] | None:
    """(row, col) float32 -> (u, v) float64, a copy."""
    if points is None:
        return None
    return np.ascontiguousarray(np.asarray(points, dtype=np.float64)[:, ::-1])


def _tip(points: NDArray[np.float32] | None) -> tuple[float, float] | None:
    if points is None or len(points) == 0:
        return None
    return float(points[-1][1]), float(points[-1][0])


def to_wire(result: PipelineResult) -> FrameResult:
    """Build the FrameResult message record of one pipeline result (shapes fixed end first, (u, v) pixels)."""
    begin, end = _uv(result.begin), _uv(result.end)
    material_s = tuple(float(s) for s in result.material_arc_m) if result.material_begin is not None else ()
    material_begin = _uv(result.material_begin) if material_s else np.zeros((0, 2))
    material_end = _uv(result.material_end) if material_s and result.material_end is not None else material_begin
    fixed = None if result.fixed_end is None else (float(result.fixed_end[1]), float(result.fixed_end[0]))
    return FrameResult(
        frame_index=int(result.frame),
        exposure_start_t_ns=int(result.t_ns),
        exposure_end_t_ns=int(result.t_end_ns),
        status=FrameStatus(result.status),
        method=Method.BLUR_SPLIT if result.method is None else Method(result.method),
        order_confidence=float(np.clip(result.order_confidence, 0.0, 1.0)),
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
    )
