"""MCAP recorder: zstd chunks closed at least every `flush_s`, files rolled by size or time, failures contained.

Durability: the mcap writer keeps the open chunk in memory; `Recorder.tick` closes it and flushes the file every
`flush_s` (0.5 s by default), so a host killed by SIGKILL loses at most that much: `ropecam recover` rebuilds the
rest (`recover.recover_mcap`). A write that fails (disk full, file system gone read-only) stops the recording with a
clear message, cuts the file back to the end of the last complete flush (so it is a clean, recoverable prefix, and
the space of the broken chunk is freed) and lets the caller go on monitoring: nothing flushed before is lost.
"""

from __future__ import annotations

import logging
import os
import re
import time
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Final

from mcap.writer import CompressionType, Writer

from ropecam.host.recording.schemas import schema_record
from ropecam.shared.config import check_positive
from ropecam.shared.errors import ConfigError

__all__ = ["PART_METADATA", "PROFILE", "Recorder", "RecordingConfig", "later_parts", "part_path", "read_part_id"]

PROFILE: Final = "ropecam"
PART_METADATA: Final = "recording"
"""Metadata record in every part: ``id`` (shared by all parts of one recording) and ``part`` (0, 1, ...)."""
log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class RecordingConfig:
    """How to record.

    Parameters
    ----------
    path
        The first file; later parts of a rolled recording are ``<stem>_001<suffix>``, ``<stem>_002<suffix>``, ...
    flush_s
        Longest time a message stays in memory before it is in the file (chunk closed and flushed).
    roll_bytes
        Start a new file when the current one exceeds this size (0: never).
    roll_s
        Start a new file after this many seconds (0: never).
    chunk_bytes
        Uncompressed chunk size at which a chunk is closed early (before the flush timer).
    overwrite
        Replace existing files instead of refusing to start.
    fsync
        Also ask the OS to write each flush to the disk (survives power loss, costs a disk sync per flush).
    """

    path: Path
    flush_s: float = 0.5
    roll_bytes: int = 0
    roll_s: float = 0.0
    chunk_bytes: int = 4 << 20
    overwrite: bool = False
    fsync: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", Path(self.path))
        check_positive("flush_s", self.flush_s)
        check_positive("chunk_bytes", self.chunk_bytes)
        if self.flush_s > 1.0:
            raise ConfigError(f"flush_s must be at most 1.0 s (at most 1 s may be lost in a crash), got {self.flush_s}")
        if self.roll_bytes < 0 or self.roll_s < 0:
            raise ConfigError(
                f"roll_bytes and roll_s must be >= 0 (0: no rolling), got {self.roll_bytes}, {self.roll_s}"
            )


def part_path(path: Path, index: int) -> Path:
    """Return the file name of part `index` of a recording that starts at `path` (part 0 is `path` itself)."""
    return path if index == 0 else path.with_name(f"{path.stem}_{index:03d}{path.suffix}")


def later_parts(path: Path) -> list[Path]:
    """Return the files next to `path` named like later parts of a recording starting there (``<stem>_NNN``)."""
    pattern = re.compile(re.escape(path.stem) + r"_\d{3,}" + re.escape(path.suffix) + "$")
    try:
        names = sorted(p for p in path.parent.iterdir() if pattern.fullmatch(p.name))
    except OSError:
        return []  # no such directory: creating the first part reports it
    return names


def read_part_id(path: Path) -> tuple[str, int] | None:
    """Return (recording id, part index) from a part's `PART_METADATA`, or None (older file, or none readable).

    Reads only the records before the first chunk, so it works on files cut by a crash as well.
    """
    from mcap.exceptions import McapError
    from mcap.records import Chunk, DataEnd, Message, Metadata
    from mcap.stream_reader import StreamReader

    try:
        with open(path, "rb") as handle:
            for record in StreamReader(handle).records:
                if isinstance(record, Metadata) and record.name == PART_METADATA:
                    return str(record.metadata["id"]), int(record.metadata["part"])
                if isinstance(record, (Chunk, Message, DataEnd)):
                    return None
    except (McapError, OSError, EOFError, KeyError, ValueError):
        return None  # an unreadable file has no id; reading its messages later names the problem
    return None


Opener = Callable[[Path, bool], IO[bytes]]


def _open_file(path: Path, overwrite: bool) -> IO[bytes]:
    return open(path, "wb" if overwrite else "xb")  # closed by Recorder


class Recorder:
    """Write messages into (rolled) MCAP files.

    Parameters
    ----------
    config
        Paths, flush and roll settings.
    metadata
        Named metadata records written into every part (e.g. ``{"rig": {...}, "calibration": {...}}``).
    attachments
        (name, media type, bytes) written into every part (e.g. calibration files).
    opener
        ``(path, overwrite) -> binary file``; tests inject failing files here.

    Every part carries a `PART_METADATA` record (recording id, part index), so replay can tell the parts of this
    recording from leftovers of an older one.

    Raises
    ------
    ConfigError
        The first file or a later part (``<stem>_NNN<suffix>``, left by an earlier rolled recording) exists and
        `overwrite` is False, or a file cannot be created or (with `overwrite`) a stale part cannot be removed.
    """

    def __init__(
        self,
        config: RecordingConfig,
        metadata: Mapping[str, Mapping[str, str]] | None = None,
        attachments: Sequence[tuple[str, str, bytes]] = (),
        opener: Opener = _open_file,
    ) -> None:
        self.config = config
        self._metadata = {name: dict(values) for name, values in (metadata or {}).items()}
        self._attachments = list(attachments)
        self._opener = opener
        self.parts: list[Path] = []
        self.error: str | None = None
        self.messages = 0
        self.flushed_messages = 0
        """Messages known to be in the files (written before the last completed flush)."""
        self.unrecorded = 0
        self._writer: Writer | None = None
        self._stream: IO[bytes] | None = None
        self._channels: dict[str, int] = {}
        self._schemas: dict[tuple[str, str], int] = {}
        self._good_offset = 0
        self._last_flush = time.monotonic()
        self._part_started = self._last_flush
        self._next_part: int | None = None  # rolled: the next part opens with its first message (no empty files)
        self.recording_id = uuid.uuid4().hex
        self._remove_stale_parts()
        self._open_part(0, fatal=True)

    def _remove_stale_parts(self) -> None:
        """Refuse (or with `overwrite` delete) later parts of an earlier recording: they would mix with this one."""
        stale = later_parts(self.config.path)
        if not stale:
            return
        if not self.config.overwrite:
            more = f" (and {len(stale) - 1} more)" if len(stale) > 1 else ""
            raise ConfigError(
                f"{stale[0]}{more} exists: a part of an earlier rolled recording to {self.config.path}; choose "
                "another --record file, move those files away, or pass --force to delete them"
            )
        for path in stale:
            try:
                path.unlink()
            except OSError as exc:
                raise ConfigError(f"cannot remove {path} of an earlier recording: {exc.strerror or exc}") from exc
            log.info("removed %s of an earlier recording (--force)", path)

    @property
    def active(self) -> bool:
        """True while messages are being written (False after a failure or `close`)."""
        return self._writer is not None or self._next_part is not None

    @property
    def path(self) -> Path | None:
        """The file being written now."""
        return self.parts[-1] if self.parts else None

    def _open_part(self, index: int, fatal: bool = False) -> None:
        path = part_path(self.config.path, index)
        try:
            stream = self._opener(path, self.config.overwrite)
        except FileExistsError as exc:
            message = f"{path} exists; choose another --record file or pass --force"
            if fatal:
                raise ConfigError(message) from exc
            self._fail(message)
            return
        except OSError as exc:
            message = f"cannot create recording file {path}: {exc.strerror or exc}"
            if fatal:
                raise ConfigError(message) from exc
            self._fail(message)
            return
        self._stream = stream
        self._good_offset = 0
        self.parts.append(path)
        self._channels.clear()
        self._schemas.clear()
        try:
            writer = Writer(stream, chunk_size=self.config.chunk_bytes, compression=CompressionType.ZSTD)
            writer.start(profile=PROFILE, library="ropecam")
            writer.add_metadata(PART_METADATA, {"id": self.recording_id, "part": str(index)})
            for name, values in self._metadata.items():
                writer.add_metadata(name, values)
            now_ns = time.time_ns()
            for name, media_type, data in self._attachments:
                writer.add_attachment(now_ns, now_ns, name, media_type, data)
            self._writer = writer
            self._flush()
        except OSError as exc:
            self._fail(f"writing {path} failed: {exc.strerror or exc}")
            if fatal:
                path.unlink(missing_ok=True)  # created just now and holds nothing
                raise ConfigError(f"cannot write recording file {path}: {exc.strerror or exc}") from exc
            return
        self._part_started = time.monotonic()

    def _channel(self, topic: str, schema_name: str | None, message_encoding: str) -> int:
        channel_id = self._channels.get(topic)
        if channel_id is None:
            assert self._writer is not None
            schema_id = 0
            if schema_name is not None:
                schema_id = self._schemas.get((schema_name, message_encoding), 0)
                if not schema_id:
                    schema_encoding, data = schema_record(schema_name, message_encoding)
                    schema_id = self._writer.register_schema(schema_name, schema_encoding, data)
                    self._schemas[schema_name, message_encoding] = schema_id
            channel_id = self._writer.register_channel(topic, message_encoding, schema_id)
            self._channels[topic] = channel_id
        return channel_id

    def write(
        self,
        topic: str,
        data: bytes,
        log_time_ns: int,
        schema_name: str | None = None,
        message_encoding: str = "json",
        sequence: int = 0,
        publish_time_ns: int | None = None,
    ) -> bool:
        """Add one message; False (counted in `unrecorded`) when the recording has stopped.

        Parameters
        ----------
        topic
            Channel topic, registered on first use in each file.
        data
            Message bytes.
        log_time_ns
            Time of the message (ns since the epoch, host clock): for a frame, its exposure.
        schema_name
            A name known to `ropecam.host.recording.schemas.schema_bytes`, or None for a schemaless channel.
        message_encoding
            ``"json"`` (schema stored as JSON Schema) or ``"protobuf"`` (schema stored as a FileDescriptorSet).
        sequence
            The wire sequence number (uint32), for tools that look at it.
        publish_time_ns
            Host receive time (default: `log_time_ns`).
        """
        if self._writer is None and self._next_part is not None:
            index, self._next_part = self._next_part, None
            self._open_part(index)
        if self._writer is None:
            self.unrecorded += 1
            return False
        try:
            channel_id = self._channel(topic, schema_name, message_encoding)
            publish = log_time_ns if publish_time_ns is None else publish_time_ns
            self._writer.add_message(channel_id, log_time_ns, data, publish, sequence)
        except OSError as exc:
            self._fail(f"writing {self.path} failed: {exc.strerror or exc}")
            self.unrecorded += 1
            return False
        self.messages += 1
        return True

    def _flush(self) -> None:
        assert self._writer is not None and self._stream is not None
        self._writer.flush()
        if self.config.fsync:
            os.fsync(self._stream.fileno())
        self._good_offset = self._stream.tell()
        self.flushed_messages = self.messages
        self._last_flush = time.monotonic()

    def tick(self) -> None:
        """Flush when `flush_s` has passed and roll when the part is big or old enough; call it often (>= 10 Hz)."""
        if self._writer is None:
            return
        now = time.monotonic()
        try:
            if now - self._last_flush >= self.config.flush_s:
                self._flush()
            roll = (self.config.roll_bytes and self._good_offset >= self.config.roll_bytes) or (
                self.config.roll_s and now - self._part_started >= self.config.roll_s
            )
        except OSError as exc:
            self._fail(f"writing {self.path} failed: {exc.strerror or exc}")
            return
        if roll and self._finish():
            self._next_part = len(self.parts)

    def _finish(self) -> bool:
        writer, stream = self._writer, self._stream
        if writer is None or stream is None:
            return False
        try:
            writer.finish()
            stream.flush()
            if self.config.fsync:
                os.fsync(stream.fileno())
        except OSError as exc:
            self._fail(f"closing {self.path} failed: {exc.strerror or exc}")
            return False
        self._writer = None
        self._stream = None
        try:
            stream.close()
        except OSError as exc:
            self.error = f"closing {self.path} failed: {exc.strerror or exc}"
            log.error("%s", self.error)
            return False
        return True

    def _fail(self, message: str) -> None:
        """Stop recording after an I/O error, keeping the file's last complete flush."""
        stream, self._writer, self._stream = self._stream, None, None
        kept = f"; {self.path} keeps everything up to its last flush" if self.parts else ""
        self.error = message + kept
        if stream is not None:
            self.error += f" (run `ropecam recover {self.path} --out FIXED.mcap` to make it a complete file)"
            try:
                stream.close()  # its buffered tail fails again; the file is cut back below anyway
            except (OSError, ValueError) as exc:
                log.debug("closing %s after the failure: %s", self.path, exc)
            try:
                if self.path is not None:
                    os.truncate(self.path, self._good_offset)
            except OSError as exc:
                log.warning("could not cut %s back to its last flush: %s", self.path, exc)
        log.error("recording stopped: %s", self.error)

    def close(self) -> None:
        """Finish the current file (summary and index written) and stop."""
        self._next_part = None
        self._finish()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()
