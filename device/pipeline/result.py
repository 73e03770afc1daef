"""The per-frame result of the pipeline and its JSON form (the record the wire protocol carries)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.shared.protocol.frame_result import FrameStatus, Method

# FrameStatus and Method are the wire protocol's: one definition of what happened to a frame, on both sides.
__all__ = ["FrameResult", "FrameStatus", "Method"]


def _uv(points: NDArray[np.float32] | None, digits: int = 3) -> list[list[float]] | None:
    """(row, col) points to a JSON list of [u, v] = [col, row]."""
    if points is None:
        return None
    return [[round(float(p[1]), digits), round(float(p[0]), digits)] for p in points]


@dataclass(slots=True)
class FrameResult:
    """The measurement of one frame. Arrays are (row, col) float32 views into the pipeline's buffers, valid until
    its next call; `to_json` copies them out as (u, v) = (col, row) lists.

    ``begin``/``end`` are the centrelines at the start and end of the exposure, fixed end first; ``None`` when not
    measured. ``order_confidence`` (0-1) says how sure the pipeline is that ``begin`` really is the earlier shape.
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

    @property
    def tips(self) -> tuple[NDArray[np.float32], NDArray[np.float32]] | None:
        """The free tips (row, col) at the start and end of the exposure."""
        if self.begin is None or self.end is None:
            return None
        return self.begin[-1], self.end[-1]

    def to_json(self) -> dict[str, Any]:
        """Return the JSON object of this frame (points as [u, v] pixels, OpenCV convention)."""
        tips = self.tips
        material = None
        if self.material_begin is not None and self.material_end is not None:
            material = {
                "s_m": list(self.material_arc_m),
                "begin": _uv(self.material_begin),
                "end": _uv(self.material_end),
            }
        return {
            "frame": self.frame,
            "t_ns": self.t_ns,
            "t_end_ns": self.t_end_ns,
            "status": self.status.name,
            "method": None if self.method is None else self.method.name,
            "order_confidence": round(float(self.order_confidence), 4),
            "begin": _uv(self.begin),
            "end": _uv(self.end),
            "tips": None if tips is None else {"begin": _uv(tips[0][None])[0], "end": _uv(tips[1][None])[0]},
            "fixed_end": None if self.fixed_end is None else _uv(self.fixed_end[None])[0],
            "segmentation_points": _uv(self.segmentation_points),
            "material_points": material,
            "stretch": None
            if self.stretch_begin is None
            else {"begin": round(self.stretch_begin, 6), "end": round(float(self.stretch_end or 0.0), 6)},
            "rope_width_px": None if self.rope_width_px is None else round(self.rope_width_px, 3),
            "roi": not self.full_frame,
            "pipeline_us": round(self.pipeline_us, 1),
            "message": self.message,
        }
