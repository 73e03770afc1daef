"""`ropecam keygen`: write a new pre-shared control key (hex) for the device and the host."""

from __future__ import annotations

import argparse
import os
import secrets
from pathlib import Path

from ropecam.shared.cli import declare_outputs
from ropecam.shared.errors import ConfigError, UsageError

__all__ = ["register", "write_key"]

HELP = """\
Write a random pre-shared key for the authenticated control channel, as hex digits, to PATH (mode 0600).
Copy the same file to the device and point both configurations at it (key_file = "PATH").
Without a key the device refuses every control message: control is off, not open.
"""


def write_key(path: Path, key_bytes: int = 32, force: bool = False) -> Path:
    """Write a new random key of `key_bytes` bytes as hex to `path` (created with mode 0600).

    Raises
    ------
    UsageError
        `path` exists and `force` is False.
    ConfigError
        The size is below 16 bytes, or the file cannot be written.
    """
    if key_bytes < 16:
        raise ConfigError(f"--bytes must be at least 16, got {key_bytes}")
    flags = os.O_WRONLY | os.O_CREAT | (os.O_TRUNC if force else os.O_EXCL)
    try:
        descriptor = os.open(path, flags, 0o600)
    except FileExistsError as exc:
        raise UsageError(f"{path} exists; use --force to replace the key (both ends then need the new one)") from exc
    except OSError as exc:
        raise ConfigError(f"{path}: cannot write key file: {exc.strerror}") from exc
    with os.fdopen(descriptor, "w", encoding="ascii") as handle:
        handle.write(secrets.token_hex(key_bytes) + "\n")
    os.chmod(path, 0o600)
    return path


def _run(args: argparse.Namespace) -> int:
    path = write_key(Path(args.path), args.bytes, args.force)
    print(f"wrote a {args.bytes}-byte control key to {path} (mode 0600)")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `keygen` sub-command."""
    parser = subparsers.add_parser(
        "keygen", help="write a new control key", description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("path", help="key file to create, e.g. ~/.config/ropecam/control.key")
    parser.add_argument("--bytes", type=int, default=32, help="key length in bytes (default 32, at least 16)")
    declare_outputs(parser, "path")
    parser.set_defaults(func=_run)
