"""A byte budget per FrameResult: a frame whose message would be over it is sent with looser shapes, or without them.

A serial line carries ``baud / 10 / fps`` bytes per frame (8N1): 774 B at 921600 baud and 119 FPS. A message over
that delays the next frames (the transport then drops whole messages), so the sender keeps every FrameResult within
the budget, whatever the pipeline measured: it encodes the record as configured, and when the COBS-framed message
would be over the budget it encodes it again with the shapes at each tolerance of `BUDGET_TOLERANCES_PX` in turn,
and at last without shapes and material points (which always fits: the rest of a FrameResult is < 160 B, checked).

What the host receives says so: the quality record's ``wire_tolerance_px`` is present on such a frame only, with the
tolerance the decoded shapes are within (px), or 0 when the shapes and material points were left out. Everything
else (status, reason, tips, fixed end, times, stretch, the other measures) is sent as measured.

The frames that need it are rough or folded shapes the pipeline itself doubts (lab-hard's runaway contours, a
fresh device's first frame of a swinging rope): see docs/protocol.md, "The serial budget".
"""

from __future__ import annotations

import dataclasses
from typing import Any, Final

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.frame_result import FrameResult, ShapeHint
from ropecam.shared.protocol.framing import framed_bytes_bound
from ropecam.shared.protocol.quality import WIRE_TOLERANCE_KEY
from ropecam.shared.protocol.shapes import ShapeCodecConfig
from ropecam.shared.protocol.wire import PROTOCOL_VERSION, encode_message

__all__ = ["BUDGET_TOLERANCES_PX", "MIN_BUDGET_BYTES", "encode_within_budget"]

BUDGET_TOLERANCES_PX: Final = (0.5, 1.0, 2.0)
"""Shape tolerances tried, in order, for a frame over the budget (looser than any configured sender tolerance
would be: the frames that need them are the rough ones)."""
MIN_BUDGET_BYTES: Final = 256
"""The smallest budget accepted: a FrameResult without shapes and material points (header, times, status, tips,
fixed end, stretch, a full quality record, the authentication trailer) always fits in it."""


def encode_within_budget(
    record: FrameResult,
    budget_bytes: int,
    *,
    device_id: int,
    sequence: int,
    t_ns: int,
    shape_config: ShapeCodecConfig | None = None,
    hint: ShapeHint | None = None,
    signer: Any = None,
    version: int = PROTOCOL_VERSION,
) -> tuple[bytes, int]:
    """Encode `record` as `encode_message` does, within `budget_bytes` framed bytes; return the message and the cut.

    Parameters
    ----------
    record
        The FrameResult as measured.
    budget_bytes
        Largest framed size (`framing.framed_bytes_bound`) of the message; 0 means no budget.
    device_id, sequence, t_ns, signer, version
        As `encode_message`.
    shape_config
        The stream's shape codec settings (its tolerance is tried first).
    hint
        The stream's `ShapeHint`: updated by the first encoding only (a cut frame's loose shapes would mislead
        the next frame's search).

    Returns
    -------
    message, cut
        The bytes to send; 0 when the record went as measured, k >= 1 when its shapes were coded at
        ``BUDGET_TOLERANCES_PX[k - 1]``, ``len(BUDGET_TOLERANCES_PX) + 1`` when they were left out.

    Raises
    ------
    ValueError
        `budget_bytes` is neither 0 nor >= MIN_BUDGET_BYTES, or `record` cannot be encoded (as `encode_message`).
    ProtocolError
        Not even the record without shapes and material points fits (not with a budget >= MIN_BUDGET_BYTES): the
        sender counts it as a frame it cannot encode and goes on (an AssertionError ended its thread).
    """
    if budget_bytes != 0 and budget_bytes < MIN_BUDGET_BYTES:
        raise ValueError(f"budget_bytes must be 0 (no budget) or >= {MIN_BUDGET_BYTES}, got {budget_bytes!r}")
    config = shape_config or ShapeCodecConfig()
    options: dict[str, Any] = {"shape_config": config, "hint": hint if hint is not None else ShapeHint()}
    message = encode_message(
        record, device_id=device_id, sequence=sequence, t_ns=t_ns, signer=signer, pack_options=options,
        version=version,
    )  # fmt: skip
    if budget_bytes == 0 or framed_bytes_bound(len(message)) <= budget_bytes:
        return message, 0
    for cut, tolerance_px in enumerate(BUDGET_TOLERANCES_PX, start=1):
        if tolerance_px <= config.tolerance_px:
            continue
        loose = ShapeCodecConfig(tolerance_px=tolerance_px, quantum_shift=config.quantum_shift)
        marked = _marked(record, tolerance_px)
        message = encode_message(
            marked, device_id=device_id, sequence=sequence, t_ns=t_ns, signer=signer,
            pack_options={"shape_config": loose, "hint": ShapeHint()}, version=version,
        )  # fmt: skip
        if framed_bytes_bound(len(message)) <= budget_bytes:
            return message, cut
    bare = dataclasses.replace(
        _marked(record, 0.0), begin_px=None, end_px=None, material_s_m=(), material_begin_px=None,
        material_end_px=None,
    )  # fmt: skip
    message = encode_message(bare, device_id=device_id, sequence=sequence, t_ns=t_ns, signer=signer, version=version)
    if framed_bytes_bound(len(message)) > budget_bytes:
        raise ProtocolError(
            f"frame {record.frame_index}: without shapes and material points the FrameResult still takes "
            f"{framed_bytes_bound(len(message))} framed bytes, over budget_bytes={budget_bytes}"
        )
    return message, len(BUDGET_TOLERANCES_PX) + 1


def _marked(record: FrameResult, tolerance_px: float) -> FrameResult:
    """`record` with the quality record's ``wire_tolerance_px`` set (version 1 carries no quality record)."""
    return dataclasses.replace(record, quality={**record.quality, WIRE_TOLERANCE_KEY: tolerance_px})
