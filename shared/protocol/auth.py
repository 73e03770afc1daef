"""Authentication of control messages: HMAC-SHA256 tags (truncated to 16 bytes) and a strictly increasing counter.

The tag covers the header (with the authenticated flag and payload length), the payload and the 64-bit counter. The
verifier on the device checks the tag first (a forged message cannot move any state), then the counter, which must
exceed every counter accepted before (replays and stale messages are rejected). The signer on the host starts its
counter at the wall clock in nanoseconds, so a restarted host keeps counting upwards without stored state.

No key configured means control is OFF: every control message is refused and counted, none is applied.
"""

from __future__ import annotations

import hashlib
import hmac
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Final

from ropecam.shared.errors import ConfigError
from ropecam.shared.protocol.wire import TAG_BYTES, Message

__all__ = ["AuthConfig", "AuthStats", "Signer", "Verdict", "Verifier", "load_key"]

MIN_KEY_BYTES: Final = 16
_U64_MAX: Final = (1 << 64) - 1
_RECENT: Final = 256


@dataclass(frozen=True, slots=True)
class AuthConfig:
    """Where the pre-shared key comes from: `key_hex` (hex digits) or `key_file` (a file holding hex digits).

    Neither set means no key: control is off. Both set is an error. Keys are at least 16 bytes (32 hex digits).
    """

    key_hex: str | None = None
    key_file: Path | None = None

    def __post_init__(self) -> None:
        if self.key_hex is not None and self.key_file is not None:
            raise ConfigError("set key_hex or key_file, not both")
        if self.key_hex is not None:
            _parse_hex(self.key_hex, "key_hex")

    def __repr__(self) -> str:  # never print the key
        return f"AuthConfig(key_hex={'<set>' if self.key_hex else None}, key_file={self.key_file!r})"


def _parse_hex(text: str, where: str) -> bytes:
    cleaned = "".join(text.split())
    try:
        key = bytes.fromhex(cleaned)
    except ValueError as exc:
        raise ConfigError(f"{where}: the key must be hexadecimal digits ({exc})") from exc
    if len(key) < MIN_KEY_BYTES:
        raise ConfigError(f"{where}: the key has {len(key)} bytes, at least {MIN_KEY_BYTES} are required")
    return key


def load_key(config: AuthConfig) -> bytes | None:
    """Return the key `config` names, or None when no key is configured (control off).

    Raises
    ------
    ConfigError
        The key file is missing or unreadable, or a key is not hex or too short.
    """
    if config.key_hex is not None:
        return _parse_hex(config.key_hex, "key_hex")
    if config.key_file is None:
        return None
    path = Path(config.key_file)
    try:
        text = path.read_text(encoding="ascii")
    except FileNotFoundError as exc:
        raise ConfigError(f"{path}: key file not found") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read key file: {exc}") from exc
    return _parse_hex(text, str(path))


def _tag(key: bytes, signed: bytes) -> bytes:
    return hmac.new(key, signed, hashlib.sha256).digest()[:TAG_BYTES]


class Signer:
    """Tag messages with a key and a strictly increasing counter (give it to `encode_message`).

    Parameters
    ----------
    key
        The pre-shared key (>= 16 bytes).
    clock_ns
        Source of the counter's starting point (default: the wall clock, so a restarted host stays ahead of the
        counters the device has seen).
    """

    def __init__(self, key: bytes, clock_ns: Callable[[], int] = time.time_ns) -> None:
        if not isinstance(key, bytes) or len(key) < MIN_KEY_BYTES:
            raise ValueError(f"key must be bytes of length >= {MIN_KEY_BYTES}")
        self._key = key
        self._clock_ns = clock_ns
        self._last = 0

    def next_counter(self) -> int:
        """Return a counter larger than every one returned before."""
        self._last = min(max(self._last + 1, self._clock_ns()), _U64_MAX)
        return self._last

    def tag(self, signed: bytes) -> bytes:
        """Return the truncated HMAC-SHA256 of `signed` (header, payload and counter)."""
        return _tag(self._key, signed)


class Verdict(Enum):
    """Outcome of checking one message."""

    ACCEPTED = "accepted"
    DISABLED = "disabled"
    """No key configured: control is off."""
    UNAUTHENTICATED = "unauthenticated"
    BAD_TAG = "bad_tag"
    REPLAYED = "replayed"
    """The counter of a message accepted before."""
    STALE = "stale"
    """A counter not above the last accepted one (and not a recent replay)."""


@dataclass(slots=True)
class AuthStats:
    """How many messages got each verdict."""

    accepted: int = 0
    disabled: int = 0
    unauthenticated: int = 0
    bad_tag: int = 0
    replayed: int = 0
    stale: int = 0

    @property
    def rejected(self) -> int:
        """All messages refused."""
        return self.disabled + self.unauthenticated + self.bad_tag + self.replayed + self.stale

    def as_counters(self, prefix: str = "control_") -> tuple[tuple[str, int], ...]:
        """Return the counts as (name, value) pairs for a Status message."""
        names = ("accepted", "disabled", "unauthenticated", "bad_tag", "replayed", "stale")
        return tuple((prefix + name, getattr(self, name)) for name in names)


class Verifier:
    """Check tags and counters of incoming messages and count every verdict.

    Parameters
    ----------
    key
        The pre-shared key, or None: control off (every message DISABLED).
    last_counter
        The highest counter accepted before (a daemon may persist it across restarts).
    """

    def __init__(self, key: bytes | None, last_counter: int = 0) -> None:
        if key is not None and (not isinstance(key, bytes) or len(key) < MIN_KEY_BYTES):
            raise ValueError(f"key must be None or bytes of length >= {MIN_KEY_BYTES}")
        self._key = key
        self._last = last_counter
        self._recent: deque[int] = deque(maxlen=_RECENT)
        self.stats = AuthStats()

    @property
    def enabled(self) -> bool:
        """True when a key is configured."""
        return self._key is not None

    @property
    def last_counter(self) -> int:
        """The highest counter accepted so far."""
        return self._last

    def verify(self, message: Message) -> Verdict:
        """Return the verdict on a decoded (CRC-checked) `message` and count it; accepting advances the counter."""
        verdict = self._judge(message)
        setattr(self.stats, verdict.value, getattr(self.stats, verdict.value) + 1)
        return verdict

    def _judge(self, message: Message) -> Verdict:
        if self._key is None:
            return Verdict.DISABLED
        if message.tag is None or message.signed_bytes is None or message.counter is None:
            return Verdict.UNAUTHENTICATED
        if not hmac.compare_digest(_tag(self._key, message.signed_bytes), message.tag):
            return Verdict.BAD_TAG
        if message.counter <= self._last:
            return Verdict.REPLAYED if message.counter in self._recent else Verdict.STALE
        self._last = message.counter
        self._recent.append(message.counter)
        return Verdict.ACCEPTED
