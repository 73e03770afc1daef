"""Transports chosen by URL (``loop://``, ``udp://host:port``, ``serial:///dev/ttyX?baud=921600``) and sequence
accounting on the receiving side.

    from ropecam.shared.transport import open_transport

    with open_transport("udp://192.168.1.10:5005") as link:
        link.send(message_bytes)            # never blocks; False when dropped (counted in link.stats)
"""

from ropecam.shared.transport.base import Transport, TransportStats, open_transport
from ropecam.shared.transport.loop import LoopTransport
from ropecam.shared.transport.sequence import Arrival, SequenceStats, SequenceTracker

__all__ = [
    "Arrival",
    "LoopTransport",
    "SequenceStats",
    "SequenceTracker",
    "Transport",
    "TransportStats",
    "open_transport",
]
