"""The quality record of a FrameResult (protocol version 2): why a frame is not OK and its self-check measures.

Wire layout (appended to the version 1 payload; all varints as `bytecodec`)::

    reason        uint8     `Reason` code (0 = none)
    readout_ns    uvarint   rolling-shutter readout time of the frame (0 = global shutter)
    present       uvarint   bit k set: measure RECORD_KEYS[k] follows
    values        svarint   each present measure, in units of its scale (`QUALITY_SCALES`; 0.01 px for the
                            sender's ``wire_tolerance_px``), in key order

The measures are coded coarsely (ratios to 1e-3, pixels to 0.1 px): they say how plausible a frame was, they are
not measurements. A value that is not finite is not present; a value beyond +-QUALITY_LIMIT units is clipped to it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from enum import IntEnum
from typing import Final

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol.bytecodec import ByteReader, ByteWriter

__all__ = [
    "QUALITY_KEYS",
    "QUALITY_SCALES",
    "RECORD_KEYS",
    "WIRE_TOLERANCE_KEY",
    "Reason",
    "check_quality",
    "pack_quality",
    "unpack_quality",
]


class Reason(IntEnum):
    """Why a frame's status is not OK (uint8 on the wire; add members at the end, never renumber).

    The lower-case name is the reason string of the JSONL (``"length"``, ``"tip_motion"``, ...; ``""`` for NONE).
    """

    NONE = 0
    LENGTH = 1
    WIDTH = 2
    FIXED_END = 3
    TIP_MOTION = 4
    ORDER = 5
    NO_BLUR = 6
    TIP_MASKED = 7
    FALLBACK_SWEEP = 8
    TIP_KINK = 9
    TIP_AT_FIXED_END = 10
    TIP_CORNER = 11
    TIP_SHORT = 12
    FIXED_END_GUESS = 13

    @property
    def text(self) -> str:
        """The reason string (``""`` for NONE)."""
        return "" if self is Reason.NONE else self.name.lower()

    @classmethod
    def from_text(cls, text: str) -> Reason:
        """Return the member of reason string `text` (``""``: NONE); ValueError naming the known ones."""
        if text == "":
            return cls.NONE
        try:
            return cls[text.upper()]
        except KeyError:
            known = ", ".join(m.text for m in cls if m is not cls.NONE)
            raise ValueError(f"reason must be '' or one of {known}, got {text!r}") from None


QUALITY_KEYS: Final = (
    "length_ratio",
    "width_ratio",
    "fixed_end_px",
    "tip_separation_px",
    "tip_motion_px",
    "tip_motion_limit_px",
    "blur_evidence",
)
"""The per-frame measures of the self-checks (`ropecam.device.pipeline.checks`), in wire order."""
QUALITY_SCALES: Final = (1e-3, 1e-3, 0.1, 0.1, 0.1, 0.1, 1e-2)
"""The unit of each key on the wire."""
WIRE_TOLERANCE_KEY: Final = "wire_tolerance_px"
"""The sender's measure (`budget`): present only on a frame the serial budget cut, the tolerance its shapes were
coded with (px), 0 when its shapes and material points were left out."""
RECORD_KEYS: Final = (*QUALITY_KEYS, WIRE_TOLERANCE_KEY)
"""Every measure a quality record may carry, in wire order: the self-checks' and then the sender's."""
_SCALES: Final = (*QUALITY_SCALES, 1e-2)
QUALITY_LIMIT: Final = 2**31 - 1
_INDEX: Final = {key: k for k, key in enumerate(RECORD_KEYS)}


def check_quality(quality: Mapping[str, float]) -> dict[str, float]:
    """Return a checked copy of `quality` (keys from RECORD_KEYS, float values; non-finite ones dropped).

    Raises
    ------
    ValueError
        An unknown key or a value that is not a number.
    """
    checked = {}
    for key, value in quality.items():
        if key not in _INDEX:
            raise ValueError(f"quality key {key!r} is not one of {RECORD_KEYS}")
        number = float(value)
        if math.isfinite(number):
            checked[key] = number
    return checked


def pack_quality(w: ByteWriter, reason: Reason, readout_ns: int, quality: Mapping[str, float]) -> None:
    """Write the quality record (`quality` checked by `check_quality`)."""
    w.raw(bytes([reason]))
    w.uvarint(readout_ns)
    present = 0
    for key in quality:
        present |= 1 << _INDEX[key]
    w.uvarint(present)
    for k, key in enumerate(RECORD_KEYS):
        if present >> k & 1:
            w.svarint(round(max(-QUALITY_LIMIT, min(QUALITY_LIMIT, quality[key] / _SCALES[k]))))


def unpack_quality(r: ByteReader) -> tuple[Reason, int, dict[str, float]]:
    """Read the quality record; raise `ProtocolError` on an unknown reason or measure."""
    code = r.raw(1, "reason")[0]
    try:
        reason = Reason(code)
    except ValueError as exc:
        raise ProtocolError(f"FrameResult: unknown reason code {code} (a newer device?)") from exc
    readout_ns = r.uvarint("readout_ns", 2**40 - 1)
    present = r.uvarint("quality keys", (1 << len(RECORD_KEYS)) - 1)
    quality = {}
    for k, key in enumerate(RECORD_KEYS):
        if present >> k & 1:
            quality[key] = r.svarint(key, QUALITY_LIMIT) * _SCALES[k]
    return reason, readout_ns, quality
