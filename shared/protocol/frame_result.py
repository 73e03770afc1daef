"""FrameResult: what the device measured in one frame (the record streamed at camera rate).

Wire resolution (what survives `unpack(pack(r))`): times exactly; pixel points (fixed end, tips, material points) to
1/64 px; shapes within the shape codec's tolerance (`shapes`, 0.05 px by default); order confidence to 1/65535;
stretch ratios to 1e-5; material arc lengths to 0.1 mm. Coordinates are chained (each coded relative to a nearby
point both sides already know) so a typical frame costs ~100-150 bytes with header and CRC.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum, IntFlag
from typing import ClassVar, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol._kernels import points_within, rows_on_wire
from ropecam.shared.protocol.bytecodec import ByteReader, ByteWriter, check_int
from ropecam.shared.protocol.quality import QUALITY_KEYS, Reason, check_quality, pack_quality, unpack_quality
from ropecam.shared.protocol.shapes import (
    MAX_SHAPE_POINTS,
    POLYLINE_LIMIT_PX,
    EncodedShape,
    ShapeCodecConfig,
    _encode_checked,
    check_polyline,
    decode_shape,
    encode_shape,
)
from ropecam.shared.protocol.wire import PROTOCOL_VERSION, MessageType, register_record

__all__ = [
    "QUALITY_KEYS",
    "FrameResult",
    "FrameStatus",
    "FrameSummary",
    "Method",
    "Reason",
    "ShapeHint",
    "peek_frame_summary",
]

POINT_SHIFT: Final = 6
"""Pixel points are coded in units of 1/64 px."""
_POINT_SCALE: Final = float(1 << POINT_SHIFT)
_POINT_LIMIT: Final = 65536 * (1 << POINT_SHIFT)
_PX_LIMIT: Final = 65537.0
"""Beyond this a pixel is refused before it is scaled (a huge finite value would overflow `round`)."""
_S_SCALE: Final = 1e4  # material arc lengths in units of 0.1 mm
_S_LIMIT: Final = 4_000_000  # 400 m in units of 0.1 mm
_STRETCH_SCALE: Final = 1e5
_CONFIDENCE_SCALE: Final = 65535
MAX_MATERIAL_POINTS: Final = 64
_U32: Final = 0xFFFF_FFFF
_DEFAULT_SHAPES: Final = ShapeCodecConfig()
_PointQ = tuple[int, int]
"""A point in 1/64 px units."""


class FrameStatus(IntEnum):
    """Outcome of a frame (uint8 on the wire; add members at the end, never renumber)."""

    OK = 0
    NO_ROPE = 1
    BAD_FRAME = 2
    LOST_TRACK = 3
    PARTIAL = 4
    """Some of the rope was measured (a shape or the tips are missing)."""
    OVERRUN = 5
    """The pipeline ran out of time and skipped work on this frame."""
    ROPE_CLIPPED = 6
    """The rope's free part touches the image border: it is leaving the field of view."""
    IMPLAUSIBLE = 7
    """A self-check failed (the record's `reason` says which): the shapes are given but not trusted."""
    NO_BLUR = 8
    """A split was found where nothing can have moved (no exposure time): the shapes are the static centreline."""


class Method(IntEnum):
    """How the device turned the blurred frame into begin and end shapes (uint8 on the wire)."""

    BLUR_SPLIT = 0
    PAPER = 1
    CENTERLINE = 2
    STATIC_FALLBACK = 3


class _Flags(IntFlag):
    FIXED_END = 1
    BEGIN_TIP = 2
    END_TIP = 4
    STRETCH_BEGIN = 8
    STRETCH_END = 16


_FIXED_END: Final = int(_Flags.FIXED_END)
_BEGIN_TIP: Final = int(_Flags.BEGIN_TIP)
_END_TIP: Final = int(_Flags.END_TIP)
_STRETCH_BEGIN: Final = int(_Flags.STRETCH_BEGIN)
_STRETCH_END: Final = int(_Flags.STRETCH_END)


@dataclass(slots=True)
class ShapeHint:
    """Mutable per-stream memory of the shape encoder, to speed up the next frame.

    The encoder reuses last frame's numbers of control points and searches for fewer bytes only every
    `explore_every` frames (the bound holds on every frame regardless; only the size can be a few bytes off).
    """

    begin_control_points: int | None = None
    end_control_points: int | None = None
    begin_corrections: int = 0
    end_corrections: int = 0
    explore_every: int = 8
    frames: int = 0
    shapes_coded: int = 0
    """Running totals of the stream: shapes sent as splines and the corrections they carried (a rough shape costs
    3-4 bytes per correction; see docs/protocol.md)."""
    corrections_sent: int = 0


def _polyline(value: ArrayLike | None, name: str) -> NDArray[np.float64] | None:
    if value is None:
        return None
    array = np.array(value, dtype=np.float64, order="C")  # the record's own copy
    if array.ndim != 2 or array.shape[1:] != (2,) or len(array) < 2:
        raise ValueError(f"{name} must be None or an (n >= 2, 2) array of (u, v) pixels, got shape {array.shape}")
    # One kernel pass on the per-frame path; `check_polyline` names what is wrong when it is not accepted.
    if len(array) > MAX_SHAPE_POINTS or not points_within(array, POLYLINE_LIMIT_PX):
        check_polyline(array, name)  # the shape codec's limits: what is accepted here can be packed
    array.flags.writeable = False
    return array


def _on_wire(array: NDArray[np.float64]) -> bool:
    """True when every (finite) coordinate still lies within +-65536 px after quantisation to 1/64 px."""
    return bool(np.all(np.abs(np.rint(array * _POINT_SCALE)) < _POINT_LIMIT))


def _on_wire_px(value: float) -> bool:
    """`_on_wire` of one plain coordinate (False for nan and infinities too)."""
    return abs(value) < _PX_LIMIT and abs(round(value * _POINT_SCALE)) < _POINT_LIMIT


def _point(value: ArrayLike | None, name: str) -> tuple[float, float] | None:
    if value is None:
        return None
    if (
        type(value) is tuple
        and len(value) == 2
        and isinstance(value[0], float | int)
        and isinstance(value[1], float | int)
    ):
        # The per-frame case (plain numbers): the same rule without NumPy calls (round() rounds half to even).
        u, v = float(value[0]), float(value[1])
        if _on_wire_px(u) and _on_wire_px(v):
            return u, v
    array = np.asarray(value, dtype=np.float64).ravel()
    if array.shape != (2,) or not np.all(np.isfinite(array)) or not _on_wire(array):
        raise ValueError(f"{name} must be None or a finite (u, v) pixel within +-65536 (at 1/64 px), got {value!r}")
    return float(array[0]), float(array[1])


def _material(value: ArrayLike | None, count: int, name: str) -> NDArray[np.float64]:
    if isinstance(value, np.ndarray) and value.shape == (count, 2):
        # The per-frame case: one copy and one kernel pass; anything it does not accept takes the path below.
        array = np.array(value, dtype=np.float64, order="C")
        if rows_on_wire(array, _POINT_SCALE, float(_POINT_LIMIT)):
            array.flags.writeable = False
            return array
    if value is None:
        array = np.full((count, 2), np.nan)
    else:
        array = np.array(value, dtype=np.float64).reshape(-1, 2) if np.size(value) else np.zeros((0, 2))
    if array.shape != (count, 2):
        raise ValueError(f"{name} must have shape ({count}, 2) (one row per material_s_m), got {array.shape}")
    partial = np.isnan(array).any(axis=1) & ~np.isnan(array).all(axis=1)
    if np.any(partial) or np.any(np.isinf(array)) or not _on_wire(array[~np.isnan(array)]):
        raise ValueError(
            f"{name} rows must be finite (u, v) pixels within +-65536 (at 1/64 px) or (nan, nan) when not measured"
        )
    array.flags.writeable = False
    return array


@dataclass(frozen=True, slots=True)
class FrameSummary:
    """The fixed-size fields at the start of a FrameResult payload (read without decoding the shapes).

    `status` and `method` are the raw codes (a newer device may send codes this side does not know).
    """

    frame_index: int
    exposure_start_t_ns: int
    exposure_end_t_ns: int
    status: int
    method: int
    order_confidence: float
    pipeline_us: int


def _read_summary(r: ByteReader, t_ns_ref: int) -> FrameSummary:
    """Read the leading fields `FrameResult.pack` writes first (the one parser of that layout)."""
    frame_index = r.uvarint("frame_index", _U32)
    start = t_ns_ref + r.svarint("exposure start", 2**63)
    end = start + r.uvarint("exposure duration", 2**40 - 1)
    if not (start >= -(2**63) and end < 2**63):
        raise ProtocolError(f"exposure times out of int64 range: {start}, {end}")
    status_code, method_code = r.raw(2, "status and method")
    confidence = r.fixed("H", "order confidence") / _CONFIDENCE_SCALE
    pipeline_us = r.uvarint("pipeline_us", _U32)
    return FrameSummary(frame_index, start, end, status_code, method_code, confidence, pipeline_us)


def peek_frame_summary(payload: bytes | memoryview, t_ns_ref: int = 0) -> FrameSummary:
    """Read only the leading fields of a FrameResult payload (a few microseconds; the shapes stay undecoded).

    Parameters
    ----------
    payload
        The payload bytes (after the header).
    t_ns_ref
        The header's t_ns (the exposure start is coded relative to it).

    Raises
    ------
    ProtocolError
        The payload is too short or a field is out of range.
    """
    return _read_summary(ByteReader(payload), t_ns_ref)


@register_record
@dataclass(frozen=True, eq=False)
class FrameResult:
    """The measurement of one frame.

    Parameters
    ----------
    frame_index
        Camera frame counter, uint32.
    exposure_start_t_ns, exposure_end_t_ns
        Device clock at the start and end of the exposure, int64 ns (end >= start).
    status, method
        Outcome and segmentation method.
    order_confidence
        Confidence in [0, 1] that begin and end are not swapped.
    begin_px, end_px
        Rope centrelines at the start and end of the exposure: (n, 2) float (u, v) distorted pixels, fixed end
        first, or None when not measured.
    begin_tip_px, end_tip_px, fixed_end_px
        (u, v) pixels or None.
    material_s_m
        Arc lengths (metres of unstretched rope from the fixed end) of the configured material points, >= 0.
    material_begin_px, material_end_px
        (len(material_s_m), 2) pixels on the begin and end shapes; rows of nan where not measured.
    stretch_begin, stretch_end
        Lc / Lc0 of each shape; nan when not measured.
    pipeline_us
        Device processing time of the frame, microseconds.
    reason
        Why the status is not OK when a self-check failed (`Reason`; version 2 only, NONE in version 1).
    readout_ns
        Rolling-shutter readout time (ns, 0 = global shutter): a shape point on image row r was seen at
        ``exposure_start_t_ns + r / height * readout_ns`` (begin) and ``exposure_end_t_ns + ...`` (end)
        (version 2 only, 0 in version 1).
    quality
        The self-checks' measures by name (`QUALITY_KEYS`; version 2 only, empty in version 1).
    """

    TYPE: ClassVar[MessageType] = MessageType.FRAME_RESULT
    VERSIONED: ClassVar[bool] = True
    """`pack` and `unpack` take the protocol version (the payload grew in version 2)."""

    frame_index: int
    exposure_start_t_ns: int
    exposure_end_t_ns: int
    status: FrameStatus = FrameStatus.OK
    method: Method = Method.BLUR_SPLIT
    order_confidence: float = 1.0
    begin_px: NDArray[np.float64] | None = None
    end_px: NDArray[np.float64] | None = None
    begin_tip_px: tuple[float, float] | None = None
    end_tip_px: tuple[float, float] | None = None
    fixed_end_px: tuple[float, float] | None = None
    material_s_m: tuple[float, ...] = ()
    material_begin_px: NDArray[np.float64] = field(default=None)  # type: ignore[assignment]
    material_end_px: NDArray[np.float64] = field(default=None)  # type: ignore[assignment]
    stretch_begin: float = math.nan
    stretch_end: float = math.nan
    pipeline_us: int = 0
    reason: Reason = Reason.NONE
    readout_ns: int = 0
    quality: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # `frozen` guards setattr, not the instance dict: the checked values are stored there directly (this runs
        # once per frame on the device and once per message on the host).
        values = self.__dict__
        for name in ("frame_index", "pipeline_us"):
            values[name] = check_int(name, values[name], high=_U32)
        for name in ("exposure_start_t_ns", "exposure_end_t_ns"):
            values[name] = check_int(name, values[name], low=-(2**63), high=2**63 - 1)
        if not 0 <= self.exposure_end_t_ns - self.exposure_start_t_ns < 2**40:
            raise ValueError(
                f"exposure_end_t_ns ({self.exposure_end_t_ns}) must be >= exposure_start_t_ns "
                f"({self.exposure_start_t_ns}) and less than 2**40 ns later"
            )
        status, method = values["status"], values["method"]
        values["status"] = status if type(status) is FrameStatus else FrameStatus(status)
        values["method"] = method if type(method) is Method else Method(method)
        confidence = float(values["order_confidence"])
        if not 0.0 <= confidence <= 1.0:
            raise ValueError(f"order_confidence must be in [0, 1], got {self.order_confidence!r}")
        values["order_confidence"] = confidence
        values["begin_px"] = _polyline(values["begin_px"], "begin_px")
        values["end_px"] = _polyline(values["end_px"], "end_px")
        for name in ("begin_tip_px", "end_tip_px", "fixed_end_px"):
            values[name] = _point(values[name], name)
        s_m = tuple(float(s) for s in self.material_s_m)
        # Checked after quantisation to 0.1 mm: 399.99996 m would be sent as 400.0 m, which the decoder refuses.
        if len(s_m) > MAX_MATERIAL_POINTS or not all(s >= 0.0 and round(s * _S_SCALE) < _S_LIMIT for s in s_m):
            raise ValueError(
                f"material_s_m must hold <= {MAX_MATERIAL_POINTS} arc lengths in [0, 400) m (at 0.1 mm), got {s_m}"
            )
        values["material_s_m"] = s_m
        values["material_begin_px"] = _material(values["material_begin_px"], len(s_m), "material_begin_px")
        values["material_end_px"] = _material(values["material_end_px"], len(s_m), "material_end_px")
        for name in ("stretch_begin", "stretch_end"):
            value = float(values[name])
            if not (math.isnan(value) or 0.0 <= value < 50.0):
                raise ValueError(f"{name} must be nan or in [0, 50), got {value!r}")
            values[name] = value
        reason = values["reason"]
        values["reason"] = reason if type(reason) is Reason else Reason(reason)
        values["readout_ns"] = check_int("readout_ns", values["readout_ns"], high=2**40 - 1)
        values["quality"] = check_quality(values["quality"])

    def __repr__(self) -> str:
        def shape(value: NDArray[np.float64] | None) -> str:
            return "None" if value is None else f"<{len(value)} points>"

        return (
            f"FrameResult(frame_index={self.frame_index}, exposure_start_t_ns={self.exposure_start_t_ns}, "
            f"exposure_end_t_ns={self.exposure_end_t_ns}, status={self.status.name}, method={self.method.name}, "
            f"order_confidence={self.order_confidence:.4f}, begin_px={shape(self.begin_px)}, "
            f"end_px={shape(self.end_px)}, begin_tip_px={self.begin_tip_px}, end_tip_px={self.end_tip_px}, "
            f"fixed_end_px={self.fixed_end_px}, material_s_m={self.material_s_m}, stretch_begin={self.stretch_begin}, "
            f"stretch_end={self.stretch_end}, pipeline_us={self.pipeline_us}, reason={self.reason.name}, "
            f"readout_ns={self.readout_ns}, quality={self.quality})"
        )

    def pack(
        self,
        t_ns_ref: int = 0,
        shape_config: ShapeCodecConfig | None = None,
        hint: ShapeHint | None = None,
        version: int = PROTOCOL_VERSION,
    ) -> bytes:
        """Return the payload bytes.

        Parameters
        ----------
        t_ns_ref
            The header's t_ns; the exposure start is coded relative to it.
        shape_config
            Tolerance and quantum of the shape codec (default 0.05 px at 1/64 px).
        hint
            Per-stream encoder memory, updated in place (saves most of the shape search on consecutive frames).
        version
            Protocol version of the payload: 2 appends the quality record (`quality`), 1 leaves it out.
        """
        config = shape_config or _DEFAULT_SHAPES
        w = ByteWriter()
        w.uvarint(self.frame_index)
        offset = self.exposure_start_t_ns - t_ns_ref
        if not -(2**63) <= offset < 2**63:  # two int64 times may lie farther apart than a zigzag varint holds
            raise ValueError(
                f"exposure_start_t_ns ({self.exposure_start_t_ns}) lies {offset} ns from the message's t_ns "
                f"({t_ns_ref}): the exposure start is coded relative to it, within [-2**63, 2**63) ns"
            )
        w.svarint(offset)
        w.uvarint(self.exposure_end_t_ns - self.exposure_start_t_ns)
        w.raw(bytes([self.status, self.method]))
        w.fixed("H", round(self.order_confidence * _CONFIDENCE_SCALE))
        w.uvarint(self.pipeline_us)
        # Plain ints: IntFlag arithmetic is slow on this per-frame path.
        flags = (
            (_FIXED_END if self.fixed_end_px is not None else 0)
            | (_BEGIN_TIP if self.begin_tip_px is not None else 0)
            | (_END_TIP if self.end_tip_px is not None else 0)
            | (0 if math.isnan(self.stretch_begin) else _STRETCH_BEGIN)
            | (0 if math.isnan(self.stretch_end) else _STRETCH_END)
        )
        w.raw(bytes([flags]))
        origin: _PointQ = (0, 0)
        if self.fixed_end_px is not None:
            origin = _write_point(w, self.fixed_end_px, origin)
        origin_px = (origin[0] / _POINT_SCALE, origin[1] / _POINT_SCALE)
        hint = hint if hint is not None else ShapeHint()
        explore = hint.frames % max(1, hint.explore_every) == 0
        hint.frames += 1
        # The constructor checked the polylines (`_polyline`): no second validation on this per-frame path.
        begin = _encode_shape(
            self.begin_px, config, origin_px, None, hint.begin_control_points, explore, hint.begin_corrections
        )
        end = _encode_shape(
            self.end_px, config, origin_px, begin, hint.end_control_points, explore, hint.end_corrections
        )
        for encoded, side in ((begin, "begin"), (end, "end")):
            if encoded.control_q is not None:
                setattr(hint, f"{side}_control_points", len(encoded.control_q))
                setattr(hint, f"{side}_corrections", encoded.corrections)
                hint.shapes_coded += 1
                hint.corrections_sent += encoded.corrections
        w.raw(begin.data)
        w.raw(end.data)
        tip = origin
        if self.begin_tip_px is not None:
            tip = _write_point(w, self.begin_tip_px, tip)
        if self.end_tip_px is not None:
            _write_point(w, self.end_tip_px, tip)
        for present, value in ((_STRETCH_BEGIN, self.stretch_begin), (_STRETCH_END, self.stretch_end)):
            if flags & present:
                w.svarint(round((value - 1.0) * _STRETCH_SCALE))
        self._pack_material(w, origin)
        if version >= 2:
            pack_quality(w, self.reason, self.readout_ns, self.quality)
        return w.getvalue()

    def _pack_material(self, w: ByteWriter, origin: _PointQ) -> None:
        w.uvarint(len(self.material_s_m))
        previous_s = 0
        for s in self.material_s_m:
            s_q = round(s * _S_SCALE)
            w.svarint(s_q - previous_s)
            previous_s = s_q
        # Plain lists: indexing them per point costs far less than NumPy scalars (a row is all nan or none).
        begin_rows = self.material_begin_px.tolist()
        end_rows = self.material_end_px.tolist()
        begin_ok = [row[0] == row[0] for row in begin_rows]
        end_ok = [row[0] == row[0] for row in end_rows]
        w.raw(_pack_mask(begin_ok, end_ok))
        previous = origin
        for k in range(len(self.material_s_m)):
            begin_q = None
            if begin_ok[k]:
                begin_q = previous = _write_point(w, begin_rows[k], previous)
            if end_ok[k]:
                end_q = _write_point(w, end_rows[k], begin_q if begin_q is not None else previous)
                if begin_q is None:
                    previous = end_q

    @classmethod
    def unpack(cls, payload: bytes, t_ns_ref: int = 0, version: int = PROTOCOL_VERSION) -> FrameResult:
        """Parse a payload written by `pack` in protocol `version`; raise `ProtocolError` on anything malformed."""
        r = ByteReader(payload)
        summary = _read_summary(r, t_ns_ref)
        frame_index, start, end = summary.frame_index, summary.exposure_start_t_ns, summary.exposure_end_t_ns
        try:
            status, method = FrameStatus(summary.status), Method(summary.method)
        except ValueError as exc:
            raise ProtocolError(f"FrameResult: {exc} (a newer device?)") from exc
        confidence, pipeline_us = summary.order_confidence, summary.pipeline_us
        flags_byte = r.raw(1, "flags")[0]
        if flags_byte & ~0x1F:
            raise ProtocolError(f"FrameResult: unknown flag bits 0x{flags_byte:02x}")
        flags = flags_byte
        origin: _PointQ = (0, 0)
        fixed_end = None
        if flags & _FIXED_END:
            origin = _read_point(r, origin, "fixed end")
            fixed_end = _as_px(origin)
        origin_px = (origin[0] / _POINT_SCALE, origin[1] / _POINT_SCALE)
        begin_px, begin_q = decode_shape(r, origin_px, what="begin shape")
        end_px, _ = decode_shape(r, origin_px, begin_q, what="end shape")
        tip = origin
        begin_tip = end_tip = None
        if flags & _BEGIN_TIP:
            tip = _read_point(r, tip, "begin tip")
            begin_tip = _as_px(tip)
        if flags & _END_TIP:
            end_tip = _as_px(_read_point(r, tip, "end tip"))
        stretch = [math.nan, math.nan]
        for i, bit in enumerate((_STRETCH_BEGIN, _STRETCH_END)):
            if flags & bit:
                stretch[i] = 1.0 + r.svarint("stretch ratio", 4_900_000) / _STRETCH_SCALE
        s_m, material_begin, material_end = _unpack_material(r, origin)
        reason, readout_ns, quality = unpack_quality(r) if version >= 2 else (Reason.NONE, 0, {})
        r.finish("FrameResult")
        return cls(
            frame_index=frame_index,
            exposure_start_t_ns=start,
            exposure_end_t_ns=end,
            status=status,
            method=method,
            order_confidence=confidence,
            begin_px=begin_px,
            end_px=end_px,
            begin_tip_px=begin_tip,
            end_tip_px=end_tip,
            fixed_end_px=fixed_end,
            material_s_m=s_m,
            material_begin_px=material_begin,
            material_end_px=material_end,
            stretch_begin=stretch[0],
            stretch_end=stretch[1],
            pipeline_us=pipeline_us,
            reason=reason,
            readout_ns=readout_ns,
            quality=quality,
        )


def _encode_shape(
    points: NDArray[np.float64] | None,
    config: ShapeCodecConfig,
    origin_px: tuple[float, float],
    reference: EncodedShape | None,
    control_hint: int | None,
    explore: bool,
    hint_corrections: int,
) -> EncodedShape:
    if points is None:
        return encode_shape(None, config)
    return _encode_checked(points, config, origin_px, reference, control_hint, explore, hint_corrections)


def _write_point(w: ByteWriter, point: ArrayLike, reference_q: _PointQ) -> _PointQ:
    # Python's round() rounds half to even like np.rint; plain ints keep this per-point path free of NumPy calls.
    u = round(float(point[0]) * _POINT_SCALE)  # type: ignore[index]
    v = round(float(point[1]) * _POINT_SCALE)  # type: ignore[index]
    w.svarint_pair(u - reference_q[0], v - reference_q[1])
    return u, v


def _read_point(r: ByteReader, reference_q: _PointQ, what: str) -> _PointQ:
    du, dv = r.svarint_pair(what, 2 * _POINT_LIMIT)
    u = reference_q[0] + du
    v = reference_q[1] + dv
    if abs(u) >= _POINT_LIMIT or abs(v) >= _POINT_LIMIT:
        raise ProtocolError(f"{what} beyond +-65536 px")
    return u, v


def _as_px(point_q: _PointQ) -> tuple[float, float]:
    return point_q[0] / _POINT_SCALE, point_q[1] / _POINT_SCALE


def _mask_bytes(count: int) -> int:
    """Bytes of the material mask of `count` points (2 bits each)."""
    return (2 * count + 7) // 8


def _pack_mask(begin_ok: list[bool], end_ok: list[bool]) -> bytes:
    """Return the material mask: bit 2k = point k measured on the begin shape, bit 2k+1 = on the end shape.

    Little-endian bit order (bit 0 is the lowest bit of the first byte); unused high bits are 0.
    """
    mask = 0
    for k, (begin, end) in enumerate(zip(begin_ok, end_ok, strict=True)):
        mask |= (int(begin) << (2 * k)) | (int(end) << (2 * k + 1))
    return mask.to_bytes(_mask_bytes(len(begin_ok)), "little")


def _unpack_material(
    r: ByteReader, origin: _PointQ
) -> tuple[tuple[float, ...], NDArray[np.float64], NDArray[np.float64]]:
    count = r.uvarint("material point count", MAX_MATERIAL_POINTS)
    s_q = 0
    s_values = []
    for _ in range(count):
        s_q += r.svarint("material s", _S_LIMIT)
        if not 0 <= s_q < _S_LIMIT:
            raise ProtocolError(f"material arc length {s_q / _S_SCALE} m out of [0, 400)")
        s_values.append(s_q / _S_SCALE)
    mask_bytes = r.raw(_mask_bytes(count), "material mask")
    mask = int.from_bytes(mask_bytes, "little")
    if mask >> (2 * count):
        raise ProtocolError(f"material mask {mask_bytes.hex()} has bits set beyond its {count} points")
    absent = (math.nan, math.nan)
    begin = [absent] * count  # rows collected as tuples, made arrays once (cheaper than row assignments)
    end = [absent] * count
    previous = origin
    for k in range(count):
        begin_q = None
        if mask >> (2 * k) & 1:
            begin_q = previous = _read_point(r, previous, f"material begin {k}")
            begin[k] = _as_px(begin_q)
        if mask >> (2 * k + 1) & 1:
            end_q = _read_point(r, begin_q if begin_q is not None else previous, f"material end {k}")
            end[k] = _as_px(end_q)
            if begin_q is None:
                previous = end_q
    return (
        tuple(s_values),
        np.array(begin, dtype=np.float64).reshape(count, 2),
        np.array(end, dtype=np.float64).reshape(count, 2),
    )
