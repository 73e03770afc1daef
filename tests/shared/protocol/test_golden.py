"""Golden byte files: one per message type and protocol version, decoded and compared on every run.

Regenerate (only after an intentional format change, bumping PROTOCOL_VERSION and adding a new folder):
``ROPECAM_REGENERATE_GOLDEN=1 pytest tests/shared/protocol/test_golden.py``.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import pytest

from ropecam.shared.protocol import (
    SUPPORTED_VERSIONS,
    MessageType,
    Signer,
    Verdict,
    Verifier,
    decode_message,
    encode_message,
)
from ropecam.shared.protocol.examples import example_records
from ropecam.shared.protocol.quality import WIRE_TOLERANCE_KEY
from ropecam.shared.protocol.shapes import ShapeCodecConfig, polyline_distances_px

GOLDEN_DIR = Path(__file__).resolve().parents[2] / "data" / "golden"
REGENERATE = os.environ.get("ROPECAM_REGENERATE_GOLDEN") == "1"
DEVICE_ID = 3
SEQUENCE = 4_000_000_000
T_NS = 1_700_000_000_010_000_000
KEY = bytes(range(32))
COUNTER = 1_700_000_000_123_456_789


def _path(version: int, name: str) -> Path:
    return GOLDEN_DIR / f"v{version}" / f"{name}.bin"


def _example(message_type: MessageType, version: int):
    """The example record as a device of `version` sends it (version 1 has no quality record)."""
    record = example_records()[message_type]
    if version == 1 and message_type is MessageType.FRAME_RESULT:
        record = dataclasses.replace(record, readout_ns=0, quality={})
    return record


def _encode(message_type: MessageType, signed: bool, version: int) -> bytes:
    signer = Signer(KEY, clock_ns=lambda: COUNTER) if signed else None
    record = _example(message_type, version)
    return encode_message(record, device_id=DEVICE_ID, sequence=SEQUENCE, t_ns=T_NS, signer=signer, version=version)


CASES = [(t, False, v) for v in sorted(SUPPORTED_VERSIONS) for t in MessageType] + [
    (MessageType.CONTROL, True, v) for v in sorted(SUPPORTED_VERSIONS)
]


def _name(message_type: MessageType, signed: bool) -> str:
    return message_type.name.lower() + ("_authenticated" if signed else "")


@pytest.mark.parametrize(("message_type", "signed", "version"), CASES, ids=[f"v{c[2]}-{_name(*c[:2])}" for c in CASES])
def test_golden_file_decodes_to_the_example(
    message_type: MessageType,
    signed: bool,
    version: int,
    frames_match,
) -> None:
    path = _path(version, _name(message_type, signed))
    if REGENERATE and not path.is_file():  # an existing version's files are never rewritten
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(_encode(message_type, signed, version))
    assert path.is_file(), f"{path} is missing: run with ROPECAM_REGENERATE_GOLDEN=1 once"
    data = path.read_bytes()
    message = decode_message(data)
    assert message.header.version == version
    assert (message.header.type, message.header.device_id) == (message_type, DEVICE_ID)
    assert (message.header.sequence, message.header.t_ns) == (SEQUENCE, T_NS)
    expected = _example(message_type, version)
    if message_type is MessageType.FRAME_RESULT:
        frames_match(expected, message.record)
    else:
        assert message.record == expected
        # The small records have one encoding: today's encoder must still produce the file byte for byte.
        assert _encode(message_type, signed, version) == data
    if signed:
        assert message.counter == COUNTER
        assert Verifier(KEY).verify(message) is Verdict.ACCEPTED


def test_every_supported_version_has_a_complete_golden_set() -> None:
    for version in SUPPORTED_VERSIONS:
        names = {p.stem for p in _path(version, "x").parent.glob("*.bin")}
        assert {_name(*c[:2]) for c in CASES} <= names, version


def test_a_frame_the_byte_budget_cut_has_its_own_golden_file(frames_match) -> None:
    """Version 2's quality record gained ``wire_tolerance_px`` (bit 7) without a layout change: a frame the sender's
    byte budget cut (its shapes coded at 1 px) is kept as bytes, so the key's bit and value stay readable."""
    version = 2
    record = _example(MessageType.FRAME_RESULT, version)
    record = dataclasses.replace(record, quality={**record.quality, WIRE_TOLERANCE_KEY: 1.0})
    path = _path(version, "frame_result_budget_cut")
    if REGENERATE and not path.is_file():
        loose = {"shape_config": ShapeCodecConfig(tolerance_px=1.0)}
        data = encode_message(
            record, device_id=DEVICE_ID, sequence=SEQUENCE, t_ns=T_NS, version=version, pack_options=loose
        )
        path.write_bytes(data)
    assert path.is_file(), f"{path} is missing: run with ROPECAM_REGENERATE_GOLDEN=1 once"
    message = decode_message(path.read_bytes())
    assert message.header.version == version
    assert message.record.quality[WIRE_TOLERANCE_KEY] == 1.0
    assert {k: v for k, v in message.record.quality.items() if k != WIRE_TOLERANCE_KEY} == pytest.approx(
        _example(MessageType.FRAME_RESULT, version).quality, abs=1e-4
    )
    assert polyline_distances_px(record.begin_px, message.record.begin_px).max() <= 1.0 + 1e-6
    assert polyline_distances_px(record.end_px, message.record.end_px).max() <= 1.0 + 1e-6
