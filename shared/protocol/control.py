"""The device's side of the control channel: verify, apply, acknowledge, count.

Only Control messages addressed to this device (or to BROADCAST_DEVICE_ID), with a valid tag and a fresh counter,
reach the `apply` callback; its outcome goes back as a ControlAck. Refused messages get no answer (an answer would
help an attacker probe the key) but are counted in `ControlEndpoint.stats` and `Verifier.stats`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

from ropecam.shared.protocol.auth import Verdict, Verifier
from ropecam.shared.protocol.records import AckResult, Control, ControlAck
from ropecam.shared.protocol.wire import Message, MessageType

__all__ = ["BROADCAST_DEVICE_ID", "ControlEndpoint", "EndpointStats"]

BROADCAST_DEVICE_ID: Final = 0xFFFF
_log = logging.getLogger(__name__)

ApplyFunction = Callable[[Control], tuple[AckResult, str]]


@dataclass(slots=True)
class EndpointStats:
    """Messages the endpoint saw, by outcome (refusals by reason are in the verifier's stats)."""

    applied: int = 0
    failed: int = 0
    refused: int = 0
    other_device: int = 0
    not_control: int = 0


class ControlEndpoint:
    """Turn incoming control messages into calls of `apply` and acknowledgements.

    Parameters
    ----------
    device_id
        This device's id; messages for other ids are ignored (counted).
    verifier
        Checks tags and counters; a verifier without key refuses everything (control off).
    apply
        Called with each accepted Control; returns (result, detail) for the ack. A `ValueError` it raises becomes
        ``AckResult.INVALID`` with the message as detail.
    """

    def __init__(self, device_id: int, verifier: Verifier, apply: ApplyFunction) -> None:
        self.device_id = device_id
        self.verifier = verifier
        self._apply = apply
        self.stats = EndpointStats()

    def handle(self, message: Message) -> ControlAck | None:
        """Process one decoded message; return the ack to send, or None when nothing is to be sent."""
        if message.header.type is not MessageType.CONTROL or not isinstance(message.record, Control):
            self.stats.not_control += 1
            return None
        if message.header.device_id not in (self.device_id, BROADCAST_DEVICE_ID):
            self.stats.other_device += 1
            return None
        verdict = self.verifier.verify(message)
        if verdict is not Verdict.ACCEPTED:
            self.stats.refused += 1
            _log.debug("refused control message seq %d: %s", message.header.sequence, verdict.value)
            return None
        control = message.record
        try:
            result, detail = self._apply(control)
        except ValueError as exc:
            result, detail = AckResult.INVALID, str(exc)[:200]
        if result is AckResult.APPLIED:
            self.stats.applied += 1
        else:
            self.stats.failed += 1
        return ControlAck(message.header.sequence, control.command, result, detail)
