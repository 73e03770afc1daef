"""The sender's byte budget (`ropecam.shared.protocol.budget`): a frame over it goes with looser shapes, or without
shapes and material points, within the budget, and the decoded record says so; a frame within it is untouched."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol import FrameResult, FrameStatus, ShapeHint, decode_message, encode_message, frame
from ropecam.shared.protocol.budget import BUDGET_TOLERANCES_PX, MIN_BUDGET_BYTES, encode_within_budget
from ropecam.shared.protocol.framing import framed_bytes_bound
from ropecam.shared.protocol.quality import RECORD_KEYS, WIRE_TOLERANCE_KEY, Reason
from ropecam.shared.protocol.shapes import ShapeCodecConfig
from ropecam.shared.protocol.wire import MessageType

_SENDER = ShapeCodecConfig(tolerance_px=0.2)
_DROPPED = len(BUDGET_TOLERANCES_PX) + 1


def _record(wobble_px: float, points: int = 400, seed: int = 0, index: int = 5) -> FrameResult:
    """A frame whose two shapes are a smooth arc with uniform noise of +-`wobble_px` (rough shapes cost bytes)."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, points)
    arc = np.stack([500.0 + 300.0 * np.sin(1.2 * s), 80.0 + 300.0 * (1.0 - np.cos(1.2 * s))], axis=1)
    begin = arc + rng.uniform(-wobble_px, wobble_px, arc.shape)
    end = arc + np.array([3.0, -2.0]) + rng.uniform(-wobble_px, wobble_px, arc.shape)
    material = [0.1, 0.2, 0.3, 0.411]
    rows = np.linspace(100, points - 1, 4).astype(int)
    return FrameResult(
        frame_index=index,
        exposure_start_t_ns=1_000_000,
        exposure_end_t_ns=5_000_000,
        status=FrameStatus.IMPLAUSIBLE,
        order_confidence=0.8,
        begin_px=begin,
        end_px=end,
        begin_tip_px=tuple(begin[-1]),
        end_tip_px=tuple(end[-1]),
        fixed_end_px=(500.0, 80.0),
        material_s_m=tuple(material),
        material_begin_px=begin[rows],
        material_end_px=end[rows],
        stretch_begin=1.01,
        stretch_end=0.99,
        pipeline_us=3100,
        reason=Reason.TIP_MOTION,
        quality={"length_ratio": 1.01, "tip_motion_px": 14.2, "tip_motion_limit_px": 6.0},
    )


def _encode(record: FrameResult, budget: int, hint: ShapeHint | None = None, **options) -> tuple[bytes, int]:
    return encode_within_budget(
        record, budget, device_id=3, sequence=9, t_ns=7_000_000, shape_config=_SENDER, hint=hint, **options
    )


def test_a_frame_within_the_budget_is_sent_as_measured() -> None:
    record = _record(0.02)
    hint, reference_hint = ShapeHint(), ShapeHint()
    message, cut = _encode(record, 774, hint)
    expected = encode_message(
        record, device_id=3, sequence=9, t_ns=7_000_000,
        pack_options={"shape_config": _SENDER, "hint": reference_hint},
    )  # fmt: skip
    assert cut == 0 and message == expected
    assert hint == reference_hint
    assert WIRE_TOLERANCE_KEY not in decode_message(message).record.quality
    assert _encode(record, 0)[0] == expected  # no budget: the same bytes


@pytest.mark.parametrize(("wobble_px", "expected_cut"), [(0.3, 1), (1.0, 2), (1.5, 3)])
def test_a_rough_frame_goes_with_looser_shapes_within_the_budget(
    wobble_px: float, expected_cut: int, shape_error
) -> None:
    record = _record(wobble_px)
    plain = encode_message(record, device_id=3, sequence=9, t_ns=7_000_000, pack_options={"shape_config": _SENDER})
    assert len(frame(plain)) > 774  # the noise no smooth curve follows costs corrections at 0.2 px
    hint = ShapeHint()
    message, cut = _encode(record, 774, hint)
    assert cut == expected_cut  # the first tolerance that fits
    assert len(frame(message)) <= framed_bytes_bound(len(message)) <= 774
    decoded = decode_message(message).record
    tolerance = BUDGET_TOLERANCES_PX[cut - 1]
    assert decoded.quality[WIRE_TOLERANCE_KEY] == pytest.approx(tolerance)
    for name in ("begin_px", "end_px"):
        assert shape_error(getattr(record, name), getattr(decoded, name)) <= tolerance + 1e-9, name
    # Everything else as measured: status, reason, tips, material points, the self-checks' measures.
    assert (decoded.status, decoded.reason, decoded.frame_index) == (record.status, record.reason, 5)
    assert np.allclose(decoded.begin_tip_px, record.begin_tip_px, atol=1 / 128)
    assert np.allclose(decoded.material_end_px, record.material_end_px, atol=1 / 128)
    assert decoded.quality["tip_motion_px"] == pytest.approx(14.2)
    # The stream's hint saw the frame once, at the stream's tolerance: the cut's loose fits do not steer the next.
    assert hint.frames == 1


def test_shapes_no_tolerance_carries_are_left_out_and_the_frame_says_so() -> None:
    record = _record(8.0, points=2000, seed=1)  # a folded, noisy contour: over the budget at every tolerance
    for version in (2, 1):
        message, cut = _encode(record, MIN_BUDGET_BYTES, version=version)
        assert cut == _DROPPED and len(frame(message)) <= MIN_BUDGET_BYTES
        decoded = decode_message(message)
        assert decoded.header.version == version and decoded.header.type is MessageType.FRAME_RESULT
        result = decoded.record
        assert result.begin_px is None and result.end_px is None and result.material_s_m == ()
        assert np.allclose(result.end_tip_px, record.end_tip_px, atol=1 / 128)
        assert result.stretch_begin == pytest.approx(1.01)
        if version == 2:  # version 1 has no quality record: the missing shapes are all it shows
            assert result.quality[WIRE_TOLERANCE_KEY] == 0.0 and result.reason is Reason.TIP_MOTION


def test_the_smallest_budget_holds_the_largest_frame_without_shapes() -> None:
    """MIN_BUDGET_BYTES holds whatever is left once shapes and material points are out: the widest times and
    counters, far coordinates, every measure of the quality record, and the authentication trailer."""
    from ropecam.shared.protocol import Signer

    record = dataclasses.replace(
        _record(8.0, points=2000, seed=2, index=2**32 - 1),
        exposure_start_t_ns=-(2**62), exposure_end_t_ns=-(2**62) + 2**40 - 1, pipeline_us=2**32 - 1,
        fixed_end_px=(-30000.0, 30000.0), begin_tip_px=(30000.0, -30000.0), end_tip_px=(-30000.0, 30000.0),
        readout_ns=2**40 - 1, quality={key: -1e9 for key in RECORD_KEYS},
    )  # fmt: skip
    message, cut = _encode(record, MIN_BUDGET_BYTES, signer=Signer(b"k" * 16))
    assert cut == _DROPPED and framed_bytes_bound(len(message)) <= MIN_BUDGET_BYTES


def test_a_budget_below_the_smallest_is_refused() -> None:
    with pytest.raises(ValueError, match=r"budget_bytes must be 0 .* >= 256, got 200"):
        _encode(_record(0.02), 200)


def test_a_host_that_knows_no_wire_tolerance_refuses_the_frame_whole() -> None:
    """The measure is a new bit of the quality record's key mask: a host older than it refuses a cut frame with a
    ProtocolError (upgrade hosts before devices, as with new reasons) instead of misreading it."""
    from ropecam.shared.protocol import quality

    message, cut = _encode(_record(0.6), 774)
    assert cut >= 1
    old_keys = quality.RECORD_KEYS[:-1]
    saved = quality.RECORD_KEYS
    try:
        quality.RECORD_KEYS = old_keys  # the mask limit of a host that knows the self-checks' seven measures
        with pytest.raises(ProtocolError, match="quality keys"):
            decode_message(message)
    finally:
        quality.RECORD_KEYS = saved
    assert math.isfinite(decode_message(message).record.quality[WIRE_TOLERANCE_KEY])
