"""The command-line runner both programs share, and the one policy every sub-command follows.

Each sub-command lives in its own module that defines ``register(subparsers)``; the module adds its parser and sets
``func`` (``args -> int`` exit code) with ``parser.set_defaults(func=...)``. The policy, implemented here once:

* **Outputs are never overwritten silently.** A command declares the arguments that name files or folders it
  writes with `declare_outputs`; that adds ``--force``, and the runner refuses to start when one of them exists
  (a folder: exists and is not empty) unless ``--force`` is given.
* **Exit codes**: 0 ok, 1 runtime error (bad data, a failed fit, a lost device: any `RopecamError` but the two
  below), 2 usage or configuration error (argparse, `ConfigError`, `UsageError`), 130 interrupted. Every
  ``--help`` ends with this list.
* **Logging**: warnings only; ``-v`` adds INFO (also the libraries', e.g. Dask's), ``-vv`` DEBUG. ``-v`` is
  accepted before and after the sub-command.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import shlex
import sys
from collections.abc import Callable, Iterable, Sequence
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from ropecam.shared.errors import ConfigError, RopecamError, UsageError

__all__ = [
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_RUNTIME",
    "EXIT_STATUS_HELP",
    "EXIT_USAGE",
    "CommandParser",
    "build_parser",
    "declare_outputs",
    "existing_outputs",
    "ropecam_version",
    "run",
]

EXIT_OK = 0
EXIT_RUNTIME = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

EXIT_STATUS_HELP = (
    "exit status: 0 ok; 1 runtime error (unreadable or bad data, a failed fit, a lost device);\n"
    "2 usage or configuration error (bad option or config file, an existing output without --force); "
    "130 interrupted."
)

# Libraries that log INFO lines of their own (Dask prints dozens per local cluster): quiet unless -v.
_CHATTY_LOGGERS = ("distributed", "bokeh", "tornado", "asyncio", "matplotlib", "PIL", "numba")

OutputsFunc = Callable[[argparse.Namespace], Iterable[Path | str | None]]


def ropecam_version() -> str:
    """Return the installed ropecam version (``"unknown"`` when the package is not installed)."""
    try:
        return version("ropecam")
    except PackageNotFoundError:
        return "unknown"


class CommandParser(argparse.ArgumentParser):
    """The parser of every sub-command (and of theirs): accepts ``-v`` and ends its help with the exit codes."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        epilog = kwargs.get("epilog")
        kwargs["epilog"] = f"{epilog.rstrip()}\n\n{EXIT_STATUS_HELP}" if epilog else EXIT_STATUS_HELP
        super().__init__(*args, **kwargs)
        # SUPPRESS: without -v here the count given before the sub-command stays.
        self.add_argument(
            "-v", "--verbose", action="count", default=argparse.SUPPRESS, help="more log output (-vv for debug)"
        )


def declare_outputs(parser: argparse.ArgumentParser, *dests: str, derived: OutputsFunc | None = None) -> None:
    """Declare the arguments of `parser` that name outputs, and add ``--force``.

    Parameters
    ----------
    parser
        A sub-command's parser.
    dests
        Destination names of the arguments that hold output paths (None and ``-`` for stdout are skipped).
    derived
        Optional: returns further output paths computed from the arguments (a default report name, the later
        parts of a rolled recording).

    Before the command runs, the runner refuses (exit 2) when an output exists, unless ``--force`` is given; the
    command then replaces it (``args.force`` tells it so).
    """
    parser.add_argument("--force", action="store_true", help="replace existing outputs (default: refuse, exit 2)")
    parser.add_argument("--overwrite", dest="force", action="store_true", help=argparse.SUPPRESS)  # earlier name
    parser.set_defaults(_outputs=dests, _derived_outputs=derived)


def existing_outputs(args: argparse.Namespace) -> list[Path]:
    """Return the declared outputs of the parsed command `args` that exist (folders: exist and are not empty)."""
    paths: list[Any] = [getattr(args, dest, None) for dest in getattr(args, "_outputs", ())]
    derived = getattr(args, "_derived_outputs", None)
    if derived is not None:
        paths.extend(derived(args))
    found = []
    for value in paths:
        if value is None or str(value) == "-":
            continue
        path = Path(value)
        if path.is_dir():
            if any(path.iterdir()):
                found.append(path)
        elif path.exists() or path.is_symlink():
            found.append(path)
    return found


def _refuse_existing_outputs(args: argparse.Namespace) -> None:
    if getattr(args, "force", False):
        return
    found = existing_outputs(args)
    if found:
        kind = "folder is not empty" if found[0].is_dir() else "exists"
        raise UsageError(f"{found[0]}: the output {kind}; pass --force to replace it, or choose another output")


def build_parser(prog: str, description: str, command_modules: Sequence[str]) -> argparse.ArgumentParser:
    """Build the top-level parser and let each module in `command_modules` register its sub-command."""
    parser = argparse.ArgumentParser(
        prog=prog,
        description=description,
        epilog=EXIT_STATUS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {ropecam_version()}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    subparsers = parser.add_subparsers(title="commands", metavar="COMMAND", parser_class=CommandParser)
    for name in command_modules:
        importlib.import_module(name).register(subparsers)
    return parser


def _configure_logging(verbose: int) -> None:
    level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    library_level = logging.WARNING if verbose == 0 else level
    for name in _CHATTY_LOGGERS:
        logging.getLogger(name).setLevel(library_level)
    # Dask sets its loggers' levels from its config when distributed is imported (also in worker processes, which
    # inherit the environment): the config says so too.
    os.environ["DASK_DISTRIBUTED__LOGGING__DISTRIBUTED"] = logging.getLevelName(library_level).lower()


def run(prog: str, description: str, command_modules: Sequence[str], argv: Sequence[str] | None = None) -> int:
    """Parse `argv`, apply the policy (outputs, logging), run the chosen sub-command and return its exit code."""
    parser = build_parser(prog, description, command_modules)
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    args.command_line = shlex.join([prog, *argv])  # for reports that record how they were made
    if not hasattr(args, "func"):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    _configure_logging(args.verbose)
    try:
        _refuse_existing_outputs(args)
        return int(args.func(args) or 0)
    except (ConfigError, UsageError) as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except RopecamError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_RUNTIME
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
