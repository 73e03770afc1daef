"""Acceptance 5: forged, replayed and unauthenticated control packets are all rejected and counted; valid ones
are applied and acknowledged. No key configured means control is off."""

from __future__ import annotations

import random

import pytest

from ropecam.shared.errors import ConfigError
from ropecam.shared.protocol import (
    AckResult,
    AuthConfig,
    Command,
    Control,
    ControlAck,
    ControlEndpoint,
    Signer,
    Verdict,
    Verifier,
    decode_message,
    encode_message,
    load_key,
)
from ropecam.shared.protocol.wire import CRC, CRC_BYTES
from ropecam.shared.transport import LoopTransport

KEY = bytes.fromhex("00112233445566778899aabbccddeeff" * 2)
DEVICE = 7


class Device:
    """A device-side settings holder the endpoint applies commands to."""

    def __init__(self) -> None:
        self.applied: list[Control] = []
        self.exposure_us = 8000

    def apply(self, control: Control) -> tuple[AckResult, str]:
        if control.command is Command.SET_EXPOSURE:
            if not 10 <= control.values[0] <= 100_000:
                raise ValueError(f"exposure_us {control.values[0]} outside [10, 100000]")
            self.exposure_us = int(control.values[0])
        self.applied.append(control)
        return AckResult.APPLIED, ""


def _recrc(data: bytes) -> bytes:
    """Fix the CRC after tampering, as an attacker would (the CRC is no protection, the tag is)."""
    import zlib

    body = data[:-CRC_BYTES]
    return body + CRC.pack(zlib.crc32(body))


def test_acceptance_forged_replayed_unauthenticated_rejected_valid_applied() -> None:
    host_end, device_end = LoopTransport.pair()
    device = Device()
    endpoint = ControlEndpoint(DEVICE, Verifier(KEY), device.apply)
    signer = Signer(KEY)
    wrong_signer = Signer(bytes(32))
    rng = random.Random(0)
    sent_valid, sent_bad, captured = [], 0, []
    for sequence in range(600):
        control = Control(Command.SET_EXPOSURE, (float(rng.randint(100, 9000)),))
        kind = rng.choice(["valid", "unauthenticated", "wrong_key", "bit_flip", "replay", "counter_edit"])
        if kind == "replay" and not captured:
            kind = "valid"
        if kind == "valid":
            data = encode_message(control, device_id=DEVICE, sequence=sequence, t_ns=sequence, signer=signer)
            captured.append(data)
            sent_valid.append((sequence, control))
        elif kind == "unauthenticated":
            data = encode_message(control, device_id=DEVICE, sequence=sequence, t_ns=sequence)
        elif kind == "wrong_key":
            data = encode_message(control, device_id=DEVICE, sequence=sequence, t_ns=sequence, signer=wrong_signer)
        elif kind == "bit_flip":  # change the exposure value in a valid message and fix the CRC
            good = bytearray(encode_message(control, device_id=DEVICE, sequence=sequence, t_ns=0, signer=signer))
            good[24] ^= 0x40
            data = _recrc(bytes(good))
        elif kind == "counter_edit":  # push the counter forward without the key
            good = bytearray(encode_message(control, device_id=DEVICE, sequence=sequence, t_ns=0, signer=signer))
            good[-CRC_BYTES - 17] ^= 0x01
            data = _recrc(bytes(good))
        else:
            data = rng.choice(captured)
        if kind != "valid":
            sent_bad += 1
        host_end.send(data)
    acks = []
    while (data := device_end.receive()) is not None:
        ack = endpoint.handle(decode_message(data))
        if ack is not None:
            device_end.send(encode_message(ack, device_id=DEVICE, sequence=len(acks), t_ns=0))
            acks.append(ack)
    stats = endpoint.verifier.stats
    assert stats.accepted == len(sent_valid) == len(device.applied)
    assert stats.rejected == sent_bad == endpoint.stats.refused
    assert stats.unauthenticated > 0 and stats.bad_tag > 0 and stats.replayed + stats.stale > 0
    assert device.applied == [control for _, control in sent_valid]
    received_acks = []
    while (data := host_end.receive()) is not None:
        received_acks.append(decode_message(data).record)
    assert [a.acked_sequence for a in received_acks] == [s for s, _ in sent_valid]
    assert all(isinstance(a, ControlAck) and a.result is AckResult.APPLIED for a in received_acks)


def test_no_key_means_control_is_off() -> None:
    device = Device()
    endpoint = ControlEndpoint(DEVICE, Verifier(load_key(AuthConfig())), device.apply)
    for signer in (None, Signer(KEY)):
        data = encode_message(Control(Command.START), device_id=DEVICE, sequence=1, t_ns=0, signer=signer)
        assert endpoint.handle(decode_message(data)) is None
    assert device.applied == []
    assert endpoint.verifier.stats.disabled == 2 and not endpoint.verifier.enabled


def test_invalid_values_are_acked_as_invalid_and_other_devices_ignored() -> None:
    device = Device()
    endpoint = ControlEndpoint(DEVICE, Verifier(KEY), device.apply)
    signer = Signer(KEY)
    bad = Control(Command.SET_EXPOSURE, (5.0,))
    ack = endpoint.handle(decode_message(encode_message(bad, device_id=DEVICE, sequence=3, t_ns=0, signer=signer)))
    assert ack is not None and ack.result is AckResult.INVALID and "exposure_us" in ack.detail
    other = encode_message(Control(Command.STOP), device_id=DEVICE + 1, sequence=4, t_ns=0, signer=signer)
    assert endpoint.handle(decode_message(other)) is None
    assert endpoint.stats.other_device == 1


def test_signer_counter_strictly_increases_even_if_the_clock_steps_back() -> None:
    times = iter([100, 100, 50, 200, 10])
    signer = Signer(KEY, clock_ns=lambda: next(times))
    counters = [signer.next_counter() for _ in range(5)]
    assert counters == [100, 101, 102, 200, 201]
    verifier = Verifier(KEY, last_counter=150)  # a daemon restored its last counter
    old = encode_message(Control(Command.START), device_id=1, sequence=1, t_ns=0, signer=Signer(KEY, lambda: 120))
    assert verifier.verify(decode_message(old)) is Verdict.STALE


def test_keys_come_from_hex_or_a_file(tmp_path) -> None:
    path = tmp_path / "control.key"
    path.write_text(KEY.hex() + "\n")
    assert load_key(AuthConfig(key_file=path)) == KEY
    assert load_key(AuthConfig(key_hex=KEY.hex())) == KEY
    assert "<set>" in repr(AuthConfig(key_hex=KEY.hex())) and KEY.hex() not in repr(AuthConfig(key_hex=KEY.hex()))
    with pytest.raises(ConfigError, match="at least 16"):
        AuthConfig(key_hex="abcd")
    with pytest.raises(ConfigError, match="hexadecimal"):
        AuthConfig(key_hex="zz" * 16)
    with pytest.raises(ConfigError, match="not found"):
        load_key(AuthConfig(key_file=tmp_path / "missing.key"))
    with pytest.raises(ConfigError, match="not both"):
        AuthConfig(key_hex=KEY.hex(), key_file=path)


def test_the_data_stream_can_be_authenticated_too() -> None:
    from ropecam.shared.protocol.examples import example_records
    from ropecam.shared.protocol.wire import MessageType

    data_key = bytes(range(100, 132))
    record = example_records()[MessageType.FRAME_RESULT]
    signer = Signer(data_key)
    verifier = Verifier(data_key)
    messages = [encode_message(record, device_id=1, sequence=i, t_ns=0, signer=signer) for i in range(3)]
    assert [verifier.verify(decode_message(m)) for m in messages] == [Verdict.ACCEPTED] * 3
    assert verifier.verify(decode_message(messages[1])) is Verdict.REPLAYED
    plain = encode_message(record, device_id=1, sequence=9, t_ns=0)
    assert verifier.verify(decode_message(plain)) is Verdict.UNAUTHENTICATED


def test_auth_config_loads_from_toml_and_refuses_unknown_keys(tmp_path) -> None:
    from ropecam.shared.config import load_toml

    key_path = tmp_path / "control.key"
    key_path.write_text(KEY.hex())
    config_path = tmp_path / "device.toml"
    config_path.write_text(f'[control]\nkey_file = "{key_path}"\n')
    assert load_key(load_toml(config_path, AuthConfig, "control")) == KEY
    config_path.write_text('[control]\nkey = "00"\n')
    with pytest.raises(ConfigError, match=r"device.toml \[control\]: unknown key 'key' \(allowed: key_file, key_hex\)"):
        load_toml(config_path, AuthConfig, "control")
    config_path.write_text("")
    assert load_key(load_toml(config_path, AuthConfig, "control")) is None  # no key: control off
