"""The control channel on the device: a thread that receives, verifies and queues commands for the main loop.

Commands are validated when they arrive (a bad value is acknowledged as INVALID at once) and applied by the main
loop between two frames, so a frame is never measured with half-changed settings. The main loop acknowledges a
valid command once it has applied it: APPLIED, INVALID (the camera refused the value, e.g. an exposure longer than
the frame period), UNSUPPORTED (the source has no such control) or FAILED (the camera failed while setting it).

A failed receive means the link is broken: the listener sets the shared `link_broken` event and ends; the daemon
opens a new link with a new listener.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
from dataclasses import dataclass
from typing import Final

from ropecam.device.senders.stream import ResultSender
from ropecam.shared.errors import ProtocolError, TransportError
from ropecam.shared.protocol import AckResult, Command, Control, ControlEndpoint, Verifier, decode_message
from ropecam.shared.transport.base import Transport

__all__ = ["ControlListener", "PendingCommand", "validate_command"]

_log = logging.getLogger(__name__)
_EXPOSURE_US: Final = (10, 1_000_000)
_GAIN_UNITS: Final = (-(2**31), 2**31 - 1)  # a V4L2 integer control; the camera checks its own range when applied


@dataclass(frozen=True, slots=True)
class PendingCommand:
    """A verified, validated command waiting for the main loop, and the sequence number its ack refers to."""

    control: Control
    acked_sequence: int


def validate_command(control: Control, rope_length_m: float) -> None:
    """Raise ValueError (the ack's detail) when a command's values are out of range."""
    values = control.values
    if control.command is Command.SET_EXPOSURE:
        low, high = _EXPOSURE_US
        if not (math.isfinite(values[0]) and low <= values[0] <= high):
            raise ValueError(f"exposure must be in [{low}, {high}] us, got {values[0]}")
    elif control.command is Command.SET_GAIN:
        low, high = _GAIN_UNITS
        if not (math.isfinite(values[0]) and values[0] == round(values[0]) and low <= values[0] <= high):
            raise ValueError(
                f"gain must be an integer in the camera's own units (its V4L2 gain control), got {values[0]}"
            )
    elif control.command is Command.SET_THRESHOLDS:
        low, high = values
        if not (0 < low < high <= 1020):
            raise ValueError(f"thresholds must satisfy 0 < low < high <= 1020, got {low}, {high}")
    elif control.command is Command.SET_MATERIAL_POINTS and any(not (0 <= s <= rope_length_m) for s in values):
        raise ValueError(f"material points must lie in [0, {rope_length_m}] m, got {list(values)}")


class ControlListener:
    """Receive messages on `transport`, turn valid control messages into queued commands, send the acks.

    Parameters
    ----------
    transport
        The daemon's link (its receive side belongs to this listener).
    sender
        Where acknowledgements go.
    device_id
        This device's id.
    verifier
        Tag and counter checks; without a key every control message is refused (control off).
    rope_length_m
        For validating material points.
    link_broken
        Set when a receive fails (shared with the sender); a new event by default.
    """

    def __init__(
        self,
        transport: Transport,
        sender: ResultSender,
        device_id: int,
        verifier: Verifier,
        rope_length_m: float,
        link_broken: threading.Event | None = None,
    ) -> None:
        self.transport = transport
        self.sender = sender
        self.link_broken = link_broken if link_broken is not None else threading.Event()
        self.commands: queue.SimpleQueue[PendingCommand] = queue.SimpleQueue()
        self.endpoint = ControlEndpoint(device_id, verifier, self._accept)
        self.bad_messages = 0
        self._rope_length_m = rope_length_m
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ropecam-control", daemon=True)
        self._thread.start()

    def _accept(self, control: Control) -> tuple[AckResult, str]:
        """Validate only: the endpoint's APPLIED here means "valid, queued"; the main loop sends the real ack."""
        validate_command(control, self._rope_length_m)
        return AckResult.APPLIED, ""

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.transport.receive(timeout_s=0.2)
            except TransportError as exc:
                if not (self._stop.is_set() or self.transport.closed):
                    _log.error("control receive failed, the link is broken: %s", exc)
                    self.link_broken.set()
                return
            if data is None:
                continue
            try:
                message = decode_message(data)
            except ProtocolError as exc:
                self.bad_messages += 1
                _log.debug("bad message on the control channel: %s", exc)
                continue
            ack = self.endpoint.handle(message)
            if ack is None:
                continue
            if ack.result is AckResult.APPLIED:
                self.commands.put(PendingCommand(message.record, ack.acked_sequence))  # acked once applied
            else:
                self.sender.submit(ack)

    def close(self) -> None:
        """Stop the thread (within the receive timeout)."""
        self._stop.set()
        self._thread.join(timeout=2.0)
