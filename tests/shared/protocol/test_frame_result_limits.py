"""FrameResult and Status at their limits: what the constructor accepts, the wire carries and decodes."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol import Command, Control, FrameResult, Status, decode_message, encode_message
from ropecam.shared.protocol.frame_result import MAX_MATERIAL_POINTS, Reason
from ropecam.shared.protocol.records import COMMAND_VALUES
from ropecam.shared.protocol.wire import CRC, HEADER_BYTES


def _trip(record: object) -> object:
    return decode_message(encode_message(record, device_id=1, sequence=0, t_ns=0)).record  # type: ignore[arg-type]


def _material_frame(count: int, seed: int = 0) -> FrameResult:
    rng = np.random.default_rng(seed)
    s_m = tuple(0.01 * (k + 1) for k in range(count))
    begin = np.column_stack([np.arange(count) * 2.0 + 10, np.arange(count) * 3.0 + 10])
    end = begin + 0.5
    # Every combination of measured / not measured shows up: each bit of the mask matters.
    begin[rng.random(count) < 0.3] = np.nan
    end[rng.random(count) < 0.3] = np.nan
    return FrameResult(
        frame_index=1,
        exposure_start_t_ns=0,
        exposure_end_t_ns=10,
        material_s_m=s_m,
        material_begin_px=begin,
        material_end_px=end,
    )


@pytest.mark.parametrize("count", [0, 1, 3, 4, 5, 31, 32, 33, 40, 63, MAX_MATERIAL_POINTS])
def test_material_points_round_trip_up_to_the_maximum(count: int) -> None:
    record = _material_frame(count, seed=count)
    decoded = _trip(record)
    assert decoded.material_s_m == pytest.approx(record.material_s_m, abs=0.5e-4)
    for name in ("material_begin_px", "material_end_px"):
        original, back = getattr(record, name), getattr(decoded, name)
        np.testing.assert_array_equal(np.isnan(back), np.isnan(original))
        np.testing.assert_allclose(back[~np.isnan(back)], original[~np.isnan(original)], atol=1 / 128)


def test_the_device_accepts_as_many_material_points_as_a_frame_result_carries() -> None:
    assert COMMAND_VALUES[Command.SET_MATERIAL_POINTS] == (1, MAX_MATERIAL_POINTS)
    Control(Command.SET_MATERIAL_POINTS, tuple(0.01 * k for k in range(MAX_MATERIAL_POINTS)))
    with pytest.raises(ValueError, match="material_s_m"):
        _material_frame(MAX_MATERIAL_POINTS + 1)


def test_material_mask_padding_bits_are_refused() -> None:
    # The mask of 3 points is one byte whose two top bits are padding; with no point measured it ends the payload.
    record = FrameResult(
        frame_index=1, exposure_start_t_ns=0, exposure_end_t_ns=10, material_s_m=(0.1, 0.2, 0.3),
        material_begin_px=np.full((3, 2), np.nan), material_end_px=np.full((3, 2), np.nan),
    )  # fmt: skip
    data = bytearray(encode_message(record, device_id=1, sequence=0, t_ns=0, version=1))
    payload_end = len(data) - 4
    assert data[payload_end - 1] == 0  # no point measured: the mask is the last payload byte of version 1
    data[payload_end - 1] = 0x40  # bit 6: a 4th point that does not exist
    data[payload_end:] = CRC.pack(zlib.crc32(bytes(data[:payload_end])))
    with pytest.raises(ProtocolError, match="beyond its 3 points"):
        decode_message(bytes(data))


@pytest.mark.parametrize(
    ("last_bytes", "fragment"),
    [
        (bytes([max(Reason) + 1, 0, 0]), f"unknown reason code {max(Reason) + 1}"),  # the first code not defined
        (b"\x00\x00\x80\x02", "quality keys"),  # bit 8: the first measure not defined (RECORD_KEYS has 8)
    ],
    ids=["reason", "quality key"],
)
def test_unknown_quality_codes_are_refused(last_bytes: bytes, fragment: str) -> None:
    # Version 2 ends with the quality record: reason, readout_ns, the present measures (none here: 3 bytes).
    record = FrameResult(frame_index=1, exposure_start_t_ns=0, exposure_end_t_ns=10)
    data = bytearray(encode_message(record, device_id=1, sequence=0, t_ns=0))
    assert data[-7:-4] == b"\x00\x00\x00"
    payload = bytes(data[HEADER_BYTES:-7]) + last_bytes
    with pytest.raises(ProtocolError, match=fragment):
        FrameResult.unpack(payload)


def test_a_version_1_frame_decodes_without_quality() -> None:
    record = FrameResult(frame_index=1, exposure_start_t_ns=0, exposure_end_t_ns=10, reason=Reason.LENGTH,
                         readout_ns=5000, quality={"length_ratio": 1.4})  # fmt: skip
    v1 = decode_message(encode_message(record, device_id=1, sequence=0, t_ns=0, version=1))
    assert v1.header.version == 1
    assert (v1.record.reason, v1.record.readout_ns, v1.record.quality) == (Reason.NONE, 0, {})
    v2 = decode_message(encode_message(record, device_id=1, sequence=0, t_ns=0))
    assert (v2.record.reason, v2.record.readout_ns) == (Reason.LENGTH, 5000)
    assert v2.record.quality == {"length_ratio": pytest.approx(1.4, abs=5e-4)}  # coded to 1e-3
    with pytest.raises(ValueError, match="quality key 'stretch'"):
        FrameResult(frame_index=1, exposure_start_t_ns=0, exposure_end_t_ns=10, quality={"stretch": 1.0})


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("material_s_m", (399.99996,)),  # rounds to 400.0 m at 0.1 mm
        ("fixed_end_px", (65535.999, 0.0)),  # rounds to 65536 px at 1/64 px
        ("begin_tip_px", (0.0, -65535.995)),
        ("begin_px", [[0.0, 0.0], [32768.0, 1.0]]),  # beyond the shape codec's +-32768 px
        ("end_px", np.zeros((8193, 2))),  # more points than a shape may have on the wire
    ],
)
def test_the_constructor_refuses_what_the_wire_cannot_carry(field: str, value: object) -> None:
    kwargs: dict[str, object] = {field: value}
    if field == "material_s_m":
        kwargs |= {"material_begin_px": [[1.0, 1.0]], "material_end_px": [[1.0, 1.0]]}
    with pytest.raises(ValueError, match=field):
        FrameResult(frame_index=1, exposure_start_t_ns=0, exposure_end_t_ns=10, **kwargs)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("material_s_m", (399.9999,)),
        ("fixed_end_px", (65535.99, -65535.99)),
        ("begin_px", [[0.0, 0.0], [32767.9, -32767.9]]),
    ],
)
def test_values_just_inside_the_limits_round_trip(field: str, value: object) -> None:
    kwargs: dict[str, object] = {field: value}
    if field == "material_s_m":
        kwargs |= {"material_begin_px": [[1.0, 1.0]], "material_end_px": [[math.nan, math.nan]]}
    record = FrameResult(frame_index=1, exposure_start_t_ns=0, exposure_end_t_ns=10, **kwargs)
    decoded = _trip(record)
    np.testing.assert_allclose(np.asarray(getattr(decoded, field)), np.asarray(getattr(record, field)), atol=0.05)


def _status(**overrides: float) -> Status:
    values: dict[str, float] = dict(
        frame_rate_hz=119.0, frames_captured=1, frames_dropped=0, messages_dropped=0, exposure_us=100, gain=0.0,
        uptime_ns=1,
    )  # fmt: skip
    return Status(**(values | overrides))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("frame_rate_hz", 3.5e38),  # beyond float32
        ("gain", -1e39),
        ("temperature_c", 1e300),
        ("cpu_load", 1.5),
        ("cpu_load", -0.1),
        ("frame_rate_hz", math.nan),
        ("gain", math.inf),
    ],
)
def test_status_refuses_values_the_wire_cannot_carry(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        _status(**{field: value})


def test_status_float32_limits_round_trip() -> None:
    record = _status(frame_rate_hz=3.4e38, gain=-3.4e38, cpu_load=1.0, temperature_c=-273.15)
    decoded = _trip(record)
    assert decoded.frame_rate_hz == pytest.approx(3.4e38, rel=1e-6)
    assert decoded.cpu_load == 1.0
