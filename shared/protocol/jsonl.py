"""The JSON-lines form of a FrameResult: one object per frame, written by ``ropecam-device extract`` and by
``ropecam replay --export-jsonl``, read by ``ropecam compare`` (`ropecam.host.compare.measurement.read_extract_jsonl`).

Both writers go through `frame_result_json`, so the two files cannot drift apart. Points are ``[u, v]`` distorted
pixels (OpenCV convention), shapes fixed end first; unmeasured values are ``null``. ``extract`` adds the fields only
the device knows (`DEVICE_ONLY_FIELDS`).
"""

from __future__ import annotations

import math
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from ropecam.shared.protocol.frame_result import FrameResult

__all__ = ["DEVICE_ONLY_FIELDS", "frame_result_json"]

DEVICE_ONLY_FIELDS: Final = ("segmentation_points", "rope_width_px", "roi", "message")
"""Fields of the extract output that the wire record does not carry (absent from a replay export)."""


def _number(value: float, digits: int | None) -> float | None:
    value = float(value)
    if math.isnan(value):
        return None
    return value if digits is None else round(value, digits)


def _point(point: tuple[float, float] | NDArray[np.float64] | None, digits: int | None) -> list | None:
    if point is None:
        return None
    u, v = (_number(c, digits) for c in point)
    return None if u is None or v is None else [u, v]


def _points(points: NDArray[np.float64] | None, digits: int | None) -> list | None:
    if points is None:
        return None
    return [_point(p, digits) for p in np.asarray(points, dtype=np.float64).reshape(-1, 2)]


def frame_result_json(record: FrameResult, digits: int | None = None) -> dict[str, Any]:
    """Return the JSON object of one FrameResult.

    Parameters
    ----------
    record
        The wire record (on the device: ``to_wire(result)``).
    digits
        Round pixel coordinates to this many decimals (None: exact, as decoded).

    Returns
    -------
    dict
        ``frame``, ``t_ns``, ``t_end_ns``, ``status``, ``method`` (null when the frame has no shape),
        ``order_confidence``, ``begin``, ``end`` (``[[u, v], ...]`` or null), ``tips`` (``{"begin", "end"}``, each
        ``[u, v]`` or null; null when neither is known), ``fixed_end``, ``material_points`` (``{"s_m", "begin",
        "end"}``, rows null where unmeasured; null without material points), ``stretch`` (``{"begin", "end"}``
        or null when neither is known), ``pipeline_us``, ``reason`` (``""`` or the failed self-check: `Reason`),
        ``quality`` (the self-checks' measures by name, `QUALITY_KEYS`; ``{}`` from a version 1 device), ``readout_ns``
        (rolling-shutter readout, 0 = global shutter or a version 1 device).
    """
    measured = record.begin_px is not None or record.end_px is not None
    tips = None
    if record.begin_tip_px is not None or record.end_tip_px is not None:
        tips = {"begin": _point(record.begin_tip_px, digits), "end": _point(record.end_tip_px, digits)}
    material = None
    if len(record.material_s_m):
        material = {
            "s_m": [float(s) for s in record.material_s_m],
            "begin": _points(record.material_begin_px, digits),
            "end": _points(record.material_end_px, digits),
        }
    stretch = {"begin": _number(record.stretch_begin, 6), "end": _number(record.stretch_end, 6)}
    return {
        "frame": int(record.frame_index),
        "t_ns": int(record.exposure_start_t_ns),
        "t_end_ns": int(record.exposure_end_t_ns),
        "status": record.status.name,
        "method": record.method.name if measured else None,
        # At the wire's resolution (1/65535) first: extract (never packed) and replay (decoded) write the same digits.
        "order_confidence": round(round(float(record.order_confidence) * 65535) / 65535, 4),
        "begin": _points(record.begin_px, digits),
        "end": _points(record.end_px, digits),
        "tips": tips,
        "fixed_end": _point(record.fixed_end_px, digits),
        "material_points": material,
        "stretch": None if stretch["begin"] is None and stretch["end"] is None else stretch,
        "pipeline_us": int(record.pipeline_us),
        "reason": record.reason.text,
        "quality": {key: round(value, 4) for key, value in record.quality.items()},
        "readout_ns": int(record.readout_ns),
    }
