"""Rebuild an MCAP file cut short by a crash: keep every complete record up to the cut, write a proper file.

A recording killed while running ends in the middle of a record (or right after a flushed chunk) and has no summary
or footer, so indexed readers refuse it. `recover_mcap` reads it sequentially, takes every complete record (schemas,
channels, metadata, attachments and the messages of every chunk that reads and decompresses), stops at the first
damaged one, and writes all of it into a new, complete file.
"""

from __future__ import annotations

import argparse
import contextlib
import struct
import sys
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from ropecam.shared.cli import EXIT_OK, EXIT_RUNTIME, declare_outputs
from ropecam.shared.errors import DataError, UsageError

__all__ = ["RecoveryReport", "recover_mcap", "register"]


@dataclass(frozen=True, slots=True)
class RecoveryReport:
    """What `recover_mcap` found."""

    messages: int
    chunks: int
    last_log_time_ns: int | None
    complete: bool
    """True when the input was already a complete file (it had its footer)."""
    stopped_at: str | None
    """Why reading stopped before the end, or None."""


def recover_mcap(source: Path, destination: Path, overwrite: bool = False) -> RecoveryReport:
    """Copy every complete record of `source` (possibly truncated) into a new, complete MCAP file `destination`.

    Raises
    ------
    DataError
        `source` cannot be read or is not an MCAP file; `destination` exists (and `overwrite` is False) or cannot
        be written (an I/O error or a full disk on the way: the incomplete `destination` is removed).
    """
    source, destination = Path(source), Path(destination)
    if source.resolve() == destination.resolve():
        raise UsageError(f"--out must differ from the input file {source}")
    try:
        handle = open(source, "rb")  # noqa: SIM115
    except OSError as exc:
        raise DataError(f"cannot read {source}: {exc.strerror or exc}") from exc
    try:
        out = open(destination, "wb" if overwrite else "xb")  # noqa: SIM115
    except FileExistsError as exc:
        handle.close()
        raise UsageError(f"{destination} exists; choose another --out or pass --force") from exc
    except OSError as exc:
        handle.close()
        raise DataError(f"cannot write {destination}: {exc.strerror or exc}") from exc
    try:
        with handle:
            report = _copy(source, handle, out)
        out.close()  # the last buffered bytes: may still fail on a full disk
        return report
    except DataError:
        _discard(out, destination)
        raise
    except OSError as exc:  # reading the input or writing the output failed (I/O error, disk full, ...)
        _discard(out, destination)
        raise DataError(
            f"recovering {source} into {destination} failed: {exc.strerror or exc}; the incomplete {destination} "
            f"was removed, {source} is unchanged"
        ) from exc


def _discard(out: BinaryIO, destination: Path) -> None:
    """Close and delete a half-written output file (its buffered tail may fail again: that is expected)."""
    with contextlib.suppress(OSError):
        out.close()
    with contextlib.suppress(OSError):
        destination.unlink()


def _copy(source: Path, handle: BinaryIO, out: BinaryIO) -> RecoveryReport:
    from mcap.exceptions import McapError
    from mcap.records import Attachment, Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk
    from mcap.writer import CompressionType, Writer
    from zstandard import ZstdError

    writer = Writer(out, compression=CompressionType.ZSTD)
    schemas: dict[int, int] = {}
    channels: dict[int, int] = {}
    pending_channels: dict[int, Channel] = {}
    messages = chunks = 0
    last_log_time: int | None = None
    complete = False
    stopped_at = None
    profile = ""

    def add_channel(channel: Channel) -> None:
        if channel.id in channels:
            return
        if channel.schema_id and channel.schema_id not in schemas:
            pending_channels[channel.id] = channel
            return
        channels[channel.id] = writer.register_channel(
            channel.topic, channel.message_encoding, schemas.get(channel.schema_id, 0), dict(channel.metadata)
        )

    def handle_record(record: object) -> None:
        nonlocal messages, last_log_time
        if isinstance(record, Schema):
            if record.id not in schemas:
                schemas[record.id] = writer.register_schema(record.name, record.encoding, record.data)
                for channel in [c for c in pending_channels.values() if c.schema_id == record.id]:
                    del pending_channels[channel.id]
                    add_channel(channel)
        elif isinstance(record, Channel):
            add_channel(record)
        elif isinstance(record, Message) and record.channel_id in channels:
            writer.add_message(
                channels[record.channel_id], record.log_time, record.data, record.publish_time, record.sequence
            )
            messages += 1
            last_log_time = record.log_time if last_log_time is None else max(last_log_time, record.log_time)
        elif isinstance(record, Metadata):
            writer.add_metadata(record.name, dict(record.metadata))
        elif isinstance(record, Attachment):
            writer.add_attachment(record.create_time, record.log_time, record.name, record.media_type, record.data)

    started = False
    try:
        reader = StreamReader(handle, emit_chunks=True, record_size_limit=1 << 30)
        for record in reader.records:
            if not started:
                started = True
                profile = getattr(record, "profile", "")
                writer.start(profile=profile, library="ropecam recover")
            if isinstance(record, Chunk):
                # A chunk is all or nothing: decompress and check it before copying any of its messages.
                inner = breakup_chunk(record, validate_crc=True)
                chunks += 1
                for item in inner:
                    handle_record(item)
            elif isinstance(record, DataEnd | Footer):
                complete = True  # the data section ended properly; the summary only repeats what was read
                break
            else:
                handle_record(record)
    except (McapError, EOFError, struct.error, zlib.error, ValueError, MemoryError) as exc:
        stopped_at = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    except ZstdError as exc:
        stopped_at = f"damaged chunk: {exc}"
    if not messages and not chunks and stopped_at and "magic" in stopped_at.lower():
        raise DataError(f"{source} is not an MCAP file ({stopped_at})")
    if not started:
        writer.start(profile=profile, library="ropecam recover")
    writer.finish()
    return RecoveryReport(messages, chunks, last_log_time, complete and stopped_at is None, stopped_at)


def _run(args: argparse.Namespace) -> int:
    report = recover_mcap(Path(args.input), Path(args.out), args.force)
    if report.messages == 0:
        Path(args.out).unlink(missing_ok=True)  # a valid file with nothing in it would only hide the failure
        reason = report.stopped_at or "the file holds no message"
        print(f"{args.input}: recovered nothing ({reason}); wrote no file", file=sys.stderr)
        return EXIT_RUNTIME
    last = "none" if report.last_log_time_ns is None else f"{report.last_log_time_ns / 1e9:.3f} s since the epoch"
    state = "was already complete" if report.complete else f"was cut ({report.stopped_at or 'no footer'})"
    print(
        f"{args.input} {state}: wrote {report.messages} messages from {report.chunks} chunks to {args.out} "
        f"(last message logged at {last})"
    )
    return EXIT_OK


HELP = """\
Rebuild a recording cut short by a crash (power loss, kill -9, full disk): every message up to the recorder's
last flush (at most 1 s before the cut) is copied into a new, complete MCAP file that any MCAP reader and Foxglove
open. The input file is not modified.

When not a single message can be recovered, no file is written and the exit status is 1.

example:
  ropecam recover run.mcap --out run-fixed.mcap
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `recover` sub-command."""
    parser = subparsers.add_parser(
        "recover",
        help="rebuild a crashed MCAP recording",
        description=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("input", help="the damaged .mcap file")
    parser.add_argument("--out", required=True, help="the complete .mcap file to write")
    declare_outputs(parser, "out")
    parser.set_defaults(func=_run)
