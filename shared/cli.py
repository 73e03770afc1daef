"""The command-line runner both programs share: sub-command discovery, error reporting and exit codes.

Each sub-command lives in its own module that defines ``register(subparsers)``; the module adds its parser and sets
``func`` (``args -> int`` exit code) with ``parser.set_defaults(func=...)``. Errors ropecam raises on purpose become
one line on stderr and exit code 2; Ctrl-C exits 130.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence
from importlib.metadata import PackageNotFoundError, version

from ropecam.shared.errors import RopecamError

__all__ = ["EXIT_ERROR", "EXIT_INTERRUPTED", "build_parser", "ropecam_version", "run"]

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130


def ropecam_version() -> str:
    """Return the installed ropecam version (``"unknown"`` when the package is not installed)."""
    try:
        return version("ropecam")
    except PackageNotFoundError:
        return "unknown"


def build_parser(prog: str, description: str, command_modules: Sequence[str]) -> argparse.ArgumentParser:
    """Build the top-level parser and let each module in `command_modules` register its sub-command."""
    parser = argparse.ArgumentParser(
        prog=prog, description=description, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {ropecam_version()}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    subparsers = parser.add_subparsers(title="commands", metavar="COMMAND")
    for name in command_modules:
        importlib.import_module(name).register(subparsers)
    return parser


def run(prog: str, description: str, command_modules: Sequence[str], argv: Sequence[str] | None = None) -> int:
    """Parse `argv`, run the chosen sub-command and return its exit code."""
    parser = build_parser(prog, description, command_modules)
    args = parser.parse_args(argv)
    if not hasattr(args, "func"):
        parser.print_help(sys.stderr)
        return EXIT_ERROR
    logging.basicConfig(
        level=(logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)],
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args) or 0)
    except RopecamError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
