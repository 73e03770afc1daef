"""Compact, error-bounded coding of rope centrelines (dense subpixel polylines) for the wire.

Why a spline: a device polyline has about one point per pixel (200-600 points) with ~0.02 px noise, so a lossless
fixed-point code costs several bits per point and coordinate (hundreds of bytes per shape) while the serial budget is
~200 bytes for a whole frame. The rope is smooth, so a clamped cubic B-spline with a handful of control points, fitted
by least squares over the normalised arc length, carries the curve in 15-30 bytes.

The bound is guaranteed by construction. The decoded shape is the polyline through the spline sampled at the device's
point count, at equally spaced parameters. The encoder builds exactly that polyline from the quantised control points
(same kernel, same arithmetic as the decoder) and measures the distance of every device point to it (the nearest
segment is searched in a window around the point's position along the rope, which can only overestimate). Where a
smooth curve cannot reach a point (noise outliers, a kink) it adds a correction: the decoded sample nearest the point
is moved onto it (an offset at the coding quantum). Corrections are iterated until every device point and both end
points are within ``tolerance_px``. The number of control points is chosen to minimise the bytes (spline points
versus corrections), starting from the previous frame's.

Wire format of one shape (integers are varints, coordinates in units of ``2**-shift`` px)::

    byte   kind | shift << 4        kind: 0 absent, 1 spline, 2 raw points, 3 spline relative to another shape
    uvar   point_count              points the decoder returns (the device's count), >= 2
    uvar   control_count            spline kinds: 2..MAX_CONTROL_POINTS
    svar   u, v of item 0           relative to the caller's origin (kinds 1, 2) or to the reference's (kind 3)
    svar   u, v of item 1 - item 0  (kind 3: of the offsets from the reference's control points)
    svar   u, v second differences of items 2..count-1
    uvar   correction_count         spline kinds only
    uvar   index gap, svar du, dv   per correction: index - previous index - 1, offset from the spline sample
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from enum import IntEnum
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ropecam.shared.config import check_range
from ropecam.shared.errors import ConfigError, ProtocolError
from ropecam.shared.jit import KernelStatus
from ropecam.shared.protocol._kernels import (
    apply_corrections,
    bspline_sample_table,
    chain_bytes,
    decode_spline,
    distances_to_polyline,
    fit_spline_with_corrections,
    fit_work_size,
    ints_within,
    read_chain,
    relative_positions,
    sample_with_table,
    write_spline_body,
)
from ropecam.shared.protocol.bytecodec import ByteReader, ByteWriter

__all__ = [
    "MAX_CONTROL_POINTS",
    "MAX_SHAPE_POINTS",
    "POLYLINE_LIMIT_PX",
    "EncodedShape",
    "ShapeCodecConfig",
    "ShapeKind",
    "check_polyline",
    "decode_shape",
    "encode_shape",
    "polyline_distances_px",
]

MAX_SHAPE_POINTS: Final = 8192
"""Most points a shape may have on the wire (no rope in a 1024 x 544 image is longer)."""
MAX_CONTROL_POINTS: Final = 64
_MIN_CONTROL_POINTS: Final = 4
_COORD_LIMIT_PX: Final = 65536.0
"""Coordinates beyond +-this are refused (keeps integers on the wire bounded)."""
POLYLINE_LIMIT_PX: Final = _COORD_LIMIT_PX / 2
"""Polyline points to encode must lie within +-this (their second differences then stay in range)."""
_DEGREE: Final = 3
_SEARCH_HALF_WINDOW: Final = 6
_ENCODER_HALF_WINDOW: Final = 3
"""The encoder checks each point against the decoded segments within this many of its own index: samples and
points both follow the arc length, so the nearest is at most a step away; a point whose nearest segment lies
outside gets an overestimated distance, which can only add a correction."""
_MAX_CORRECTION_ROUNDS: Final = 8
_FIRST_GUESS: Final = 8
_PATIENCE: Final = 2
_UPWARD_GAIN: Final = 2
_ACCEPT_MORE_CORRECTIONS: Final = 2


class ShapeKind(IntEnum):
    """How a shape is coded (low nibble of its first byte)."""

    ABSENT = 0
    SPLINE = 1
    RAW = 2
    SPLINE_RELATIVE = 3


@dataclass(frozen=True, slots=True)
class ShapeCodecConfig:
    """Settings of the shape encoder.

    Parameters
    ----------
    tolerance_px
        Largest allowed distance between a device point and the decoded polyline, pixels.
    quantum_shift
        Coordinates are coded in units of ``2**-quantum_shift`` px (6 = 1/64 px, the default).
    """

    tolerance_px: float = 0.05
    quantum_shift: int = 6

    def __post_init__(self) -> None:
        check_range("tolerance_px", self.tolerance_px, 1e-4, 10.0)
        if isinstance(self.quantum_shift, bool) or not isinstance(self.quantum_shift, int):
            raise ConfigError(f"quantum_shift must be an integer, got {self.quantum_shift!r}")
        check_range("quantum_shift", self.quantum_shift, 0, 12)
        if 2.0**-self.quantum_shift > self.tolerance_px:
            raise ConfigError(
                f"quantum 2**-{self.quantum_shift} px is coarser than tolerance_px={self.tolerance_px}: "
                "raise quantum_shift"
            )


@dataclass(frozen=True, slots=True)
class EncodedShape:
    """What `encode_shape` produced: the bytes and what the decoder will see (for chaining and statistics)."""

    data: bytes
    kind: ShapeKind
    control_q: NDArray[np.int64] | None
    """Quantised control points (spline kinds), shape (m, 2); None otherwise."""
    corrections: int
    max_error_px: float


_SampleTable = tuple[NDArray[np.int64], NDArray[np.float64]]
_SAMPLE_TABLES: dict[tuple[int, int], _SampleTable] = {}
_CACHED_TABLES: Final = 64
_CACHED_TABLE_POINTS: Final = 2048


def _sample_table(point_count: int, control_count: int) -> _SampleTable:
    """The B-spline basis at `point_count` equally spaced parameters for `control_count` control points.

    It depends only on the two counts, which repeat from frame to frame: cached (a few dozen tables of a few kB),
    it saves most of the sampling on both sides. Tables are never written after they are built (shared by threads).
    """
    key = (point_count, control_count)
    table = _SAMPLE_TABLES.get(key)
    if table is None:
        first = np.empty(point_count, dtype=np.int64)
        basis = np.empty((point_count, 4))
        if bspline_sample_table(control_count, first, basis) != point_count:
            raise AssertionError(f"bspline_sample_table refused ({point_count}, {control_count})")
        table = (first, basis)
        if point_count <= _CACHED_TABLE_POINTS:
            if len(_SAMPLE_TABLES) >= _CACHED_TABLES:
                _SAMPLE_TABLES.clear()
            _SAMPLE_TABLES[key] = table
    return table


def _spline_samples(control_q: NDArray[np.int64], point_count: int, shift: int) -> NDArray[np.float64]:
    """The decoder's polyline before corrections; the encoder's check runs the very same arithmetic."""
    out = np.empty((point_count, 2))
    first, basis = _sample_table(point_count, len(control_q))
    sample_with_table(control_q / float(1 << shift), first, basis, out)  # a new C-contiguous array
    return out


def _relative_position(points: NDArray[np.float64]) -> NDArray[np.float64]:
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    if arc[-1] <= 0.0:
        return np.linspace(0.0, 1.0, len(points))
    return arc / arc[-1]


def polyline_distances_px(points_px: ArrayLike, curve_px: ArrayLike) -> NDArray[np.float64]:
    """Return the distance of each of `points_px` (n, 2) to the polyline `curve_px` (m, 2), pixels.

    Both are ordered along the rope (fixed end first); the nearest segment is searched near the point's relative
    position along the rope, so the cost is linear. Use it to check a decoded shape against the device polyline
    (together with the distance between the end points).
    """
    points = np.ascontiguousarray(points_px, dtype=np.float64)
    curve = np.ascontiguousarray(curve_px, dtype=np.float64)
    if points.ndim != 2 or points.shape[1:] != (2,) or curve.ndim != 2 or curve.shape[1:] != (2,):
        raise ValueError(f"points_px and curve_px must have shape (n, 2), got {points.shape} and {curve.shape}")
    if len(points) < 1 or len(curve) < 2:
        raise ValueError(f"need >= 1 point and >= 2 curve points, got {len(points)} and {len(curve)}")
    out = np.empty(len(points))
    half_window = max(_SEARCH_HALF_WINDOW, 2 * int(np.ceil(len(curve) / len(points))) * _SEARCH_HALF_WINDOW)
    distances_to_polyline(points, _relative_position(points), curve, half_window, out)
    return out


def check_polyline(points_px: ArrayLike, name: str) -> NDArray[np.float64]:
    """Return `points_px` as a C-contiguous (n, 2) float64 array the shape codec can encode, else raise ValueError.

    The codec takes 2..MAX_SHAPE_POINTS finite points within +-POLYLINE_LIMIT_PX.
    """
    points = np.ascontiguousarray(points_px, dtype=np.float64)
    if points.ndim != 2 or points.shape[1:] != (2,):
        raise ValueError(f"{name} must have shape (n, 2), got {points.shape}")
    if not 2 <= len(points) <= MAX_SHAPE_POINTS:
        raise ValueError(f"{name} must have 2..{MAX_SHAPE_POINTS} points, got {len(points)}")
    if not np.all(np.isfinite(points)) or np.any(np.abs(points) >= POLYLINE_LIMIT_PX):
        raise ValueError(f"{name} must hold finite pixel coordinates within +-{POLYLINE_LIMIT_PX:g}")
    return points


def _origin_q(origin_px: tuple[float, float] | NDArray[np.float64] | None, shift: int) -> NDArray[np.int64]:
    """Quantise the coding origin; an absent (None or non-finite) origin is (0, 0) on both sides."""
    if origin_px is None:
        return np.zeros(2, dtype=np.int64)
    if isinstance(origin_px, tuple) and len(origin_px) == 2:
        u, v = float(origin_px[0]), float(origin_px[1])
    else:
        origin = np.asarray(origin_px, dtype=np.float64).reshape(2)
        u, v = float(origin[0]), float(origin[1])
    if not (math.isfinite(u) and math.isfinite(v)) or abs(u) >= _COORD_LIMIT_PX or abs(v) >= _COORD_LIMIT_PX:
        return np.zeros(2, dtype=np.int64)
    scale = float(1 << shift)
    return np.array([round(u * scale), round(v * scale)], dtype=np.int64)


def _write_chain(writer: ByteWriter, items: NDArray[np.int64]) -> None:
    """Write item 0, the first difference and the second differences (rows (u, v))."""
    writer.svarint(int(items[0, 0]))
    writer.svarint(int(items[0, 1]))
    if len(items) > 1:
        writer.svarint(int(items[1, 0] - items[0, 0]))
        writer.svarint(int(items[1, 1] - items[0, 1]))
    for du, dv in np.diff(items, n=2, axis=0).tolist():
        writer.svarint(du)
        writer.svarint(dv)


def _read_chain(reader: ByteReader, count: int, limit: int, what: str) -> NDArray[np.int64]:
    """Read `count` items written by `_write_chain` (in one kernel call: RAW shapes have thousands)."""
    values = np.empty((count, 2), dtype=np.int64)
    data, position = reader.buffer()
    position = read_chain(data, position, limit, values)
    if position == KernelStatus.FULL:
        raise ProtocolError(f"truncated payload: {what} ends inside its {count} coordinates")
    if position < 0:
        raise ProtocolError(f"{what}: over-long varint or coordinate beyond +-{_COORD_LIMIT_PX:g} px")
    reader.seek(position, what)
    return values


@dataclass(slots=True)
class _Candidate:
    control_q: NDArray[np.int64]
    index: NDArray[np.int64]
    offset_q: NDArray[np.int64]
    max_error_px: float
    size: int
    """Bytes of the control chain (relative to the origin) and the corrections: the rank of candidates."""


_LOCAL = threading.local()
_UNTRIED: Final = object()
_NO_INDEX: Final = np.zeros(0, dtype=np.int64)
_NO_OFFSETS: Final = np.zeros((0, 2), dtype=np.int64)
_NO_INDEX.flags.writeable = False  # shared by candidates without corrections
_NO_OFFSETS.flags.writeable = False


def _workspace(n: int) -> tuple[NDArray, ...]:
    """Work buffers of the encoder for a polyline of `n` points, reused by the calls of one thread (a shape's
    buffers are free again once it is encoded; allocating them per shape costs more than its fits' setup).

    Leading slices of C-contiguous buffers: C-contiguous, as the kernels require.
    """
    buffers = getattr(_LOCAL, "buffers", None)
    if buffers is None or buffers[0] < n:
        capacity = max(n, 512)
        buffers = (
            capacity,
            np.empty(capacity),  # t
            np.empty(fit_work_size(capacity, MAX_CONTROL_POINTS)),  # the fit's float work
            np.empty(capacity, dtype=np.int64),  # index
            np.empty((capacity, 2), dtype=np.int64),  # offsets
            np.zeros(capacity + 1, dtype=np.int64),  # moved samples per round
            np.empty(2),  # stats
        )
        _LOCAL.buffers = buffers
    _, t, work, index, offset_q, changed, stats = buffers
    return t[:n], work, index[:n], offset_q[:n], changed[: n + 1], stats


class _Fitter:
    """Work buffers of one `encode_shape` call and the candidates tried (one per control-point count)."""

    def __init__(self, points: NDArray[np.float64], config: ShapeCodecConfig, origin_q: NDArray[np.int64]) -> None:
        n = len(points)
        self.n = n
        self.points = points
        self.config = config
        self.shift = config.quantum_shift
        self.tolerance_px = config.tolerance_px
        self.origin_q = origin_q
        self.t, self.work, self.index, self.offset_q, self.changed, self.stats = _workspace(n)
        relative_positions(points, self.t)
        self.tried: dict[int, _Candidate | None] = {}

    def attempt(self, m: int) -> _Candidate | None:
        """The candidate with `m` control points (None: singular fit or no convergence), computed once."""
        candidate = self.tried.get(m, _UNTRIED)
        if candidate is not _UNTRIED:
            return candidate  # type: ignore[return-value]
        control_q = np.empty((m, 2), dtype=np.int64)
        first, basis = _sample_table(self.n, m)
        count = fit_spline_with_corrections(
            self.points, self.t, self.shift, _MAX_CORRECTION_ROUNDS, self.tolerance_px, _ENCODER_HALF_WINDOW,
            self.origin_q, first, basis, self.work, self.changed, control_q, self.index, self.offset_q, self.stats,
        )  # fmt: skip
        if count < 0:
            candidate = None
        else:
            max_error_px, size = self.stats.tolist()
            if count == 0:  # the usual end shape: no corrections to copy out
                candidate = _Candidate(control_q, _NO_INDEX, _NO_OFFSETS, max_error_px, int(size))
            else:
                index, offset_q = self.index[:count].copy(), self.offset_q[:count].copy()
                candidate = _Candidate(control_q, index, offset_q, max_error_px, int(size))
        self.tried[m] = candidate
        return candidate

    def size(self, m: int) -> float:
        candidate = self.attempt(m)
        return float("inf") if candidate is None else candidate.size


def encode_shape(
    points_px: ArrayLike | None,
    config: ShapeCodecConfig,
    origin_px: tuple[float, float] | NDArray[np.float64] | None = None,
    reference: EncodedShape | None = None,
    control_hint: int | None = None,
    explore: bool = True,
    hint_corrections: int = 0,
) -> EncodedShape:
    """Encode one polyline (fixed end first) so that every point lies within ``config.tolerance_px`` of the decoded one.

    Parameters
    ----------
    points_px
        Polyline (n, 2), float (u, v) distorted pixels, 2 <= n <= MAX_SHAPE_POINTS; None for an absent shape.
    config
        Tolerance and quantum.
    origin_px
        Point the first coordinate is coded relative to (for example the fixed-end pixel); the decoder must be given
        the same value. None or non-finite means (0, 0).
    reference
        A shape encoded before it in the same message (the begin shape, for the end shape). When its spline has a
        count of control points that suits this polyline too, the control points are coded as offsets from it,
        which costs about half.
    control_hint
        Number of control points to try first (what the previous frame needed; consecutive frames are alike).
    explore
        Also look for fewer bytes below `control_hint`. With False a `control_hint` that needs at most
        ``hint_corrections + 2`` corrections is taken as it is (one fit; the stream explores every few frames, see
        `ShapeHint`); one that needs more starts a search upwards.
    hint_corrections
        Corrections `control_hint` needed on the previous frame (noise no smooth curve follows needs some on
        every frame; searching for a count without them would be wasted).

    Returns
    -------
    EncodedShape

    Raises
    ------
    ValueError
        `points_px` has the wrong shape, too few or too many points, or non-finite or huge coordinates.
    """
    if points_px is None:
        return EncodedShape(bytes([ShapeKind.ABSENT]), ShapeKind.ABSENT, None, 0, 0.0)
    points = check_polyline(points_px, "points_px")
    return _encode_checked(points, config, origin_px, reference, control_hint, explore, hint_corrections)


def _encode_checked(
    points: NDArray[np.float64],
    config: ShapeCodecConfig,
    origin_px: tuple[float, float] | NDArray[np.float64] | None,
    reference: EncodedShape | None,
    control_hint: int | None,
    explore: bool,
    hint_corrections: int,
) -> EncodedShape:
    """`encode_shape` of a polyline `check_polyline` accepted (C-contiguous float64 (n, 2) within the limits)."""
    n = len(points)
    most = min(MAX_CONTROL_POINTS, n // 2)
    if most < _MIN_CONTROL_POINTS:
        return _encode_raw(points, config, origin_px)
    fitter = _Fitter(points, config, _origin_q(origin_px, config.quantum_shift))
    ref_count = None if reference is None or reference.control_q is None else len(reference.control_q)
    if ref_count is not None and _MIN_CONTROL_POINTS <= ref_count <= most:
        relative_candidate = fitter.attempt(ref_count)
        if relative_candidate is not None and len(relative_candidate.index) == 0:
            # The usual case for the end shape: the begin shape's count fits without corrections, and offsets from
            # the begin shape are the cheapest code there is.
            return _write_spline(relative_candidate, n, config, fitter.origin_q, reference)
    start = int(min(max(control_hint or ref_count or _FIRST_GUESS, _MIN_CONTROL_POINTS), most))
    accept = _ACCEPT_MORE_CORRECTIONS + max(0, int(hint_corrections)) if control_hint is not None else 0
    best = _search(fitter, start, most, explore or control_hint is None, accept)
    chosen = fitter.attempt(best)
    if chosen is None:
        return _encode_raw(points, config, origin_px)
    relative = False
    if ref_count is not None and reference is not None and reference.control_q is not None:
        # Offsets from the reference cost about half the control chain: the reference's count may win with them.
        candidate = fitter.tried.get(ref_count)
        if candidate is not None:
            gain = _chain_size(candidate.control_q - fitter.origin_q) - _chain_size(
                candidate.control_q - reference.control_q
            )
            if candidate.size - gain < chosen.size:
                chosen, relative = candidate, True
    return _write_spline(chosen, n, config, fitter.origin_q, reference if relative else None)


def _chain_size(items: NDArray[np.int64]) -> int:
    return int(chain_bytes(np.ascontiguousarray(items)))


def _search(fitter: _Fitter, start: int, most: int, explore: bool, accept: int) -> int:
    """Return the control-point count of fewest bytes found near `start`.

    Bytes against the count are noisy but roughly valley-shaped: corrections fall as control points are added,
    until none are left and each further point only costs. Upwards (from a count that needs corrections) the
    search stops at the first count that needs none, or `_PATIENCE` counts after the last gain of at least
    `_UPWARD_GAIN` bytes (with noise that no smooth curve follows, corrections never vanish, and small gains are
    noise: without the margin the count would creep up frame after frame). Downwards (when exploring) it goes on
    while counts cost no more, up to `_PATIENCE` counts past the last gain. Without exploring, a start that needs
    at most `accept` corrections is taken at once.
    """
    best = start
    first = fitter.attempt(start)
    if not explore and first is not None and len(first.index) <= accept:
        return start
    if first is None or len(first.index) > 0:
        m, since = start, 0
        while m < most and since < _PATIENCE:
            m += 1
            candidate = fitter.attempt(m)
            if fitter.size(m) < math.inf and fitter.size(m) <= fitter.size(best) - _UPWARD_GAIN:
                best, since = m, 0
            else:
                since += 1
            if candidate is not None and len(candidate.index) == 0:
                break  # more control points than this only cost bytes
    if not explore and first is not None:
        return best
    m, since = best, 0
    while m - 1 >= _MIN_CONTROL_POINTS and since < _PATIENCE:
        m -= 1
        if fitter.size(m) <= fitter.size(best) and fitter.size(m) < math.inf:
            best, since = m, 0
        else:
            since += 1  # also when no count down here converges: never a walk through every count
    return best


def _write_spline(
    candidate: _Candidate,
    n: int,
    config: ShapeCodecConfig,
    origin_q: NDArray[np.int64],
    reference: EncodedShape | None,
) -> EncodedShape:
    kind = ShapeKind.SPLINE if reference is None else ShapeKind.SPLINE_RELATIVE
    m = len(candidate.control_q)
    writer = ByteWriter()
    writer.raw(bytes((int(kind) | (config.quantum_shift << 4),)))
    writer.uvarint(n)
    writer.uvarint(m)
    base = reference.control_q if reference is not None and reference.control_q is not None else origin_q.reshape(1, 2)
    # Each value takes at most 10 bytes: a buffer that cannot overflow.
    body = np.empty(10 * (2 * m + 3 * len(candidate.index) + 1), dtype=np.uint8)
    base = np.ascontiguousarray(base, dtype=np.int64)  # a no-op for the encoder's own arrays
    count = write_spline_body(candidate.control_q, base, candidate.index, candidate.offset_q, body)
    if count < 0:
        raise AssertionError(f"write_spline_body returned status {count}")
    writer.raw(body[:count].tobytes())
    return EncodedShape(writer.getvalue(), kind, candidate.control_q, len(candidate.index), candidate.max_error_px)


def _encode_raw(
    points: NDArray[np.float64], config: ShapeCodecConfig, origin_px: tuple[float, float] | NDArray | None
) -> EncodedShape:
    scale = float(1 << config.quantum_shift)
    points_q = np.rint(points * scale).astype(np.int64)
    writer = ByteWriter()
    writer.raw(bytes([ShapeKind.RAW | (config.quantum_shift << 4)]))
    writer.uvarint(len(points))
    _write_chain(writer, points_q - _origin_q(origin_px, config.quantum_shift))
    error = float(np.max(np.hypot(*(points - points_q / scale).T)))
    return EncodedShape(writer.getvalue(), ShapeKind.RAW, None, 0, error)


def decode_shape(
    reader: ByteReader,
    origin_px: tuple[float, float] | NDArray[np.float64] | None = None,
    reference_control_q: NDArray[np.int64] | None = None,
    what: str = "shape",
) -> tuple[NDArray[np.float64] | None, NDArray[np.int64] | None]:
    """Read one shape written by `encode_shape`.

    Parameters
    ----------
    reader
        Positioned at the shape's first byte.
    origin_px
        The origin the encoder was given.
    reference_control_q
        Quantised control points of the reference shape (second return value of decoding it), for kind 3.
    what
        Name used in error messages.

    Returns
    -------
    points, control_q
        The decoded polyline (n, 2) float64, or None when absent; the quantised control points (for a later
        relative shape) or None.

    Raises
    ------
    ProtocolError
        Unknown kind, counts out of range, truncated data, coordinates out of range, a relative shape without a
        matching reference.
    """
    head = reader.raw(1, f"{what} kind")[0]
    try:
        kind = ShapeKind(head & 0x0F)
    except ValueError as exc:
        raise ProtocolError(f"{what}: unknown shape kind {head & 0x0F}") from exc
    shift = head >> 4
    if kind is ShapeKind.ABSENT:
        if shift:
            raise ProtocolError(f"{what}: absent shape with nonzero quantum bits {shift}")
        return None, None
    if shift > 12:
        raise ProtocolError(f"{what}: quantum shift {shift} > 12")
    scale = float(1 << shift)
    limit = int(_COORD_LIMIT_PX * scale)
    n = reader.uvarint(f"{what} point count", MAX_SHAPE_POINTS)
    if n < 2:
        raise ProtocolError(f"{what}: point count {n} < 2")
    if kind is ShapeKind.RAW:
        return (_read_chain(reader, n, limit, what) + _origin_q(origin_px, shift)) / scale, None
    m = reader.uvarint(f"{what} control count", MAX_CONTROL_POINTS)
    if not 2 <= m <= n:
        raise ProtocolError(f"{what}: control count {m} not in [2, point count {n}]")
    if kind is ShapeKind.SPLINE:
        base: NDArray[np.int64] | None = _origin_q(origin_px, shift).reshape(1, 2)
    elif isinstance(reference_control_q, np.ndarray) and reference_control_q.shape == (m, 2):
        base = reference_control_q if reference_control_q.dtype == np.int64 else None
    else:
        base = None  # no usable reference: the step-by-step path below says so, after the chain as always
    if base is not None:
        # The whole body in one kernel call; anything it does not accept is parsed again step by step below, which
        # names the fault (or decodes what the kernel's stricter limits refused: a 10-byte varint).
        data, start = reader.buffer()
        control_q = np.empty((m, 2), dtype=np.int64)
        points = np.empty((n, 2))
        first, basis = _sample_table(n, m)
        end = decode_spline(
            data, start, limit, shift, np.ascontiguousarray(base), first, basis, control_q, np.empty((m, 2)), points
        )
        if end >= 0:
            reader.seek(end, what)
            return points, control_q
    chain = _read_chain(reader, m, limit, what)
    if kind is ShapeKind.SPLINE_RELATIVE:
        if reference_control_q is None or len(reference_control_q) != m:
            raise ProtocolError(f"{what}: relative shape without a reference spline of {m} control points")
        control_q = chain + reference_control_q
    else:
        control_q = chain + _origin_q(origin_px, shift)
    if not ints_within(control_q, limit):
        raise ProtocolError(f"{what}: control point beyond +-{_COORD_LIMIT_PX:g} px")
    corrections = reader.uvarint(f"{what} correction count", n)
    points = _spline_samples(control_q, n, shift)
    data, position = reader.buffer()
    position = apply_corrections(data, position, corrections, limit, shift, points)
    if position == KernelStatus.FULL:
        raise ProtocolError(f"truncated payload: {what} ends inside its {corrections} corrections")
    if position < 0:
        raise ProtocolError(
            f"{what}: a correction has an over-long varint, an index beyond point count {n} or an offset beyond "
            f"+-{_COORD_LIMIT_PX:g} px"
        )
    reader.seek(position, what)
    return points, control_q
