"""Bounds-checked little-endian byte writer and reader with LEB128 varints and zigzag signed varints.

Every read past the end, every over-long varint and every value out of its declared range raises `ProtocolError`, so a
decoder built on `ByteReader` cannot raise anything else on hostile input.
"""

from __future__ import annotations

import struct
from typing import Final

import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import ProtocolError

__all__ = ["ByteReader", "ByteWriter", "check_int", "unzigzag", "zigzag"]

_MAX_VARINT_BYTES: Final = 10  # 64-bit values
_U64_MAX: Final = (1 << 64) - 1
_STRUCTS: Final = {code: struct.Struct("<" + code) for code in "bBhHiIqQfd"}


def check_int(name: str, value: object, *, low: int = 0, high: int) -> int:
    """Return `value` as a Python int if it is an integer (not a bool) in [low, high]; else raise ValueError.

    NumPy integers are accepted (and converted); the message names the field, the range and the value.
    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not low <= value <= high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def zigzag(value: int) -> int:
    """Map a signed integer to an unsigned one (0, -1, 1, -2, ... -> 0, 1, 2, 3, ...)."""
    return (value << 1) if value >= 0 else ((-value) << 1) - 1


def unzigzag(value: int) -> int:
    """Inverse of `zigzag`."""
    return (value >> 1) if not value & 1 else -((value + 1) >> 1)


class ByteWriter:
    """Append fixed-width little-endian values and varints to a growing buffer."""

    __slots__ = ("_buffer",)

    def __init__(self) -> None:
        self._buffer = bytearray()

    def __len__(self) -> int:
        return len(self._buffer)

    def getvalue(self) -> bytes:
        """Return the bytes written so far."""
        return bytes(self._buffer)

    def fixed(self, code: str, value: float) -> None:
        """Write one value in `struct` format `code` (one of ``bBhHiIqQfd``), little-endian."""
        try:
            self._buffer += _STRUCTS[code].pack(value)
        except (struct.error, OverflowError) as exc:
            raise ValueError(f"value {value!r} does not fit struct format {code!r}: {exc}") from exc

    def uvarint(self, value: int) -> None:
        """Write an unsigned LEB128 varint (0 <= value < 2**64)."""
        if 0 <= value < 0x80:
            self._buffer.append(value)
            return
        if not 0 <= value <= _U64_MAX:
            raise ValueError(f"uvarint value must be in [0, 2**64), got {value}")
        while value >= 0x80:
            self._buffer.append((value & 0x7F) | 0x80)
            value >>= 7
        self._buffer.append(value)

    def svarint(self, value: int) -> None:
        """Write a signed integer as a zigzag varint."""
        # Most values on the per-frame path are small deltas: one byte, no further calls.
        unsigned = (value << 1) if value >= 0 else ((-value) << 1) - 1
        if unsigned > _U64_MAX:
            self.uvarint(unsigned)  # raises, naming the value
        buffer = self._buffer
        while unsigned >= 0x80:
            buffer.append((unsigned & 0x7F) | 0x80)
            unsigned >>= 7
        buffer.append(unsigned)

    def svarint_pair(self, u: int, v: int) -> None:
        """Write two signed integers as zigzag varints (a point's deltas: one call instead of two)."""
        buffer = self._buffer
        for value in (u, v):
            unsigned = (value << 1) if value >= 0 else ((-value) << 1) - 1
            if unsigned > _U64_MAX:
                self.uvarint(unsigned)  # raises, naming the value
            while unsigned >= 0x80:
                buffer.append((unsigned & 0x7F) | 0x80)
                unsigned >>= 7
            buffer.append(unsigned)

    def raw(self, data: bytes | bytearray | memoryview) -> None:
        """Write bytes as they are."""
        self._buffer += data

    def blob(self, data: bytes | bytearray | memoryview) -> None:
        """Write a varint length followed by the bytes."""
        self.uvarint(len(data))
        self._buffer += data


def _short_varint(data: memoryview, position: int, end: int) -> tuple[int, int]:
    """(value, next position) of a varint of one or two bytes at `position`, else (0, 0): the common case of the
    decoders' hot path (pixel deltas at 1/64 px take two bytes), read without a loop."""
    if position < end:
        first = data[position]
        if first < 0x80:
            return first, position + 1
        if position + 1 < end:
            second = data[position + 1]
            if second < 0x80:
                return (first & 0x7F) | (second << 7), position + 2
    return 0, 0


class ByteReader:
    """Read what `ByteWriter` wrote; any inconsistency raises `ProtocolError` naming `what` was being read."""

    __slots__ = ("_data", "_pos")

    def __init__(self, data: bytes | bytearray | memoryview) -> None:
        self._data = memoryview(data).cast("B") if not isinstance(data, bytes) else memoryview(data)
        self._pos = 0

    @property
    def remaining(self) -> int:
        """Number of unread bytes."""
        return len(self._data) - self._pos

    def _take(self, count: int, what: str) -> memoryview:
        if count < 0 or self._pos + count > len(self._data):
            raise ProtocolError(f"truncated payload: {what} needs {count} bytes, {self.remaining} left")
        view = self._data[self._pos : self._pos + count]
        self._pos += count
        return view

    def fixed(self, code: str, what: str) -> int | float:
        """Read one value in `struct` format `code`."""
        layout = _STRUCTS[code]
        return layout.unpack(self._take(layout.size, what))[0]

    def uvarint(self, what: str, maximum: int = _U64_MAX) -> int:
        """Read an unsigned varint and check ``value <= maximum``."""
        # The hot path of every decoder: bytes are read in place, without a view per byte.
        data = self._data
        position = self._pos
        end = len(data)
        value, after = _short_varint(data, position, end)
        if after:
            self._pos = after
            if value > maximum:
                raise ProtocolError(f"{what} = {value} exceeds its maximum {maximum}")
            return value
        value = 0
        for shift in range(0, 7 * _MAX_VARINT_BYTES, 7):
            if position >= end:
                raise ProtocolError(f"truncated payload: {what} needs 1 bytes, 0 left")
            byte = data[position]
            position += 1
            value |= (byte & 0x7F) << shift
            if not byte & 0x80:
                self._pos = position
                if value > maximum:
                    raise ProtocolError(f"{what} = {value} exceeds its maximum {maximum}")
                return value
        raise ProtocolError(f"{what}: varint longer than {_MAX_VARINT_BYTES} bytes")

    def svarint(self, what: str, limit: int = 1 << 62) -> int:
        """Read a zigzag varint and check ``abs(value) <= limit``."""
        unsigned, after = _short_varint(self._data, self._pos, len(self._data))
        if after:
            self._pos = after
        else:
            unsigned = self.uvarint(what)
        value = (unsigned >> 1) if not unsigned & 1 else -((unsigned + 1) >> 1)
        if abs(value) > limit:
            raise ProtocolError(f"{what} = {value} exceeds its limit {limit}")
        return value

    def svarint_pair(self, what: str, limit: int) -> tuple[int, int]:
        """Read two zigzag varints (the u and v of a point: errors name ``what u`` or ``what v``), each checked as
        `svarint` checks it."""
        data = self._data
        end = len(data)
        a, middle = _short_varint(data, self._pos, end)
        if middle:
            b, after = _short_varint(data, middle, end)
            if after:
                u = (a >> 1) if not a & 1 else -((a + 1) >> 1)
                v = (b >> 1) if not b & 1 else -((b + 1) >> 1)
                if abs(u) <= limit and abs(v) <= limit:
                    self._pos = after
                    return u, v
        # Longer varints or an error: the general path (and its messages); names are built only here.
        return self.svarint(f"{what} u", limit), self.svarint(f"{what} v", limit)

    def buffer(self) -> tuple[NDArray[np.uint8], int]:
        """Return the whole input as a uint8 array (no copy) and the read position, for kernels that parse in
        place; move on with `seek`."""
        return np.frombuffer(self._data, dtype=np.uint8), self._pos

    def seek(self, position: int, what: str) -> None:
        """Continue reading at `position` (forward only, within the data)."""
        if not self._pos <= position <= len(self._data):
            raise ProtocolError(f"{what}: position {position} outside [{self._pos}, {len(self._data)}]")
        self._pos = position

    def raw(self, count: int, what: str) -> bytes:
        """Read exactly `count` bytes."""
        return bytes(self._take(count, what))

    def blob(self, what: str, maximum: int) -> bytes:
        """Read a varint length (<= `maximum`) and that many bytes."""
        return self.raw(self.uvarint(f"{what} length", maximum), what)

    def text(self, what: str, maximum: int) -> str:
        """Read a length-prefixed UTF-8 string."""
        data = self.blob(what, maximum)
        try:
            return data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ProtocolError(f"{what} is not valid UTF-8: {exc}") from exc

    def finish(self, what: str) -> None:
        """Raise `ProtocolError` if bytes are left over after `what`."""
        if self.remaining:
            raise ProtocolError(f"{what}: {self.remaining} unexpected trailing bytes")
