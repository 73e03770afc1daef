"""The wire protocol shared by device and host: envelope, records, compact shapes, COBS framing, control auth.

Typical use::

    from ropecam.shared.protocol import FrameResult, decode_message, encode_message

    data = encode_message(result, device_id=1, sequence=seq, t_ns=time.monotonic_ns())
    message = decode_message(data)          # raises ProtocolError on anything malformed
    message.record                          # a FrameResult again

See docs/protocol.md for the byte layouts and the design choices.
"""

from ropecam.shared.protocol.auth import AuthConfig, AuthStats, Signer, Verdict, Verifier, load_key
from ropecam.shared.protocol.control import BROADCAST_DEVICE_ID, ControlEndpoint
from ropecam.shared.protocol.framing import Deframer, cobs_decode, cobs_encode, frame
from ropecam.shared.protocol.rawframe import FrameAssembler, split_frame
from ropecam.shared.protocol.records import (
    AckResult,
    Command,
    Control,
    ControlAck,
    FrameResult,
    FrameStatus,
    Log,
    Method,
    PixelFormat,
    RawFrameChunk,
    ShapeHint,
    Status,
)
from ropecam.shared.protocol.shapes import ShapeCodecConfig, polyline_distances_px
from ropecam.shared.protocol.wire import (
    MAX_MESSAGE_BYTES,
    MAX_PAYLOAD_BYTES,
    PROTOCOL_VERSION,
    SUPPORTED_VERSIONS,
    Header,
    HeaderFlags,
    Message,
    MessageType,
    decode_message,
    encode_message,
)

__all__ = [
    "BROADCAST_DEVICE_ID",
    "MAX_MESSAGE_BYTES",
    "MAX_PAYLOAD_BYTES",
    "PROTOCOL_VERSION",
    "SUPPORTED_VERSIONS",
    "AckResult",
    "AuthConfig",
    "AuthStats",
    "Command",
    "Control",
    "ControlAck",
    "ControlEndpoint",
    "Deframer",
    "FrameAssembler",
    "FrameResult",
    "FrameStatus",
    "Header",
    "HeaderFlags",
    "Log",
    "Message",
    "MessageType",
    "Method",
    "PixelFormat",
    "RawFrameChunk",
    "ShapeCodecConfig",
    "ShapeHint",
    "Signer",
    "Status",
    "Verdict",
    "Verifier",
    "cobs_decode",
    "cobs_encode",
    "decode_message",
    "encode_message",
    "frame",
    "load_key",
    "polyline_distances_px",
    "split_frame",
]
