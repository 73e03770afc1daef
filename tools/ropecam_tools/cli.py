"""The entry scripts' dispatcher: ``SCRIPT COMMAND [options]``, one subcommand per module of `ropecam_tools`.

Only the chosen subcommand's module is imported (a benchmark sets Numba's environment before Numba is imported, and
``--help`` stays fast); the other subcommands' one-line help is read from their module docstring without importing
them.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import importlib.util
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from ropecam.shared.cli import EXIT_RUNTIME
from ropecam.shared.errors import ConfigError, RopecamError


class UsageError(ValueError):
    """A bad combination of arguments found by a subcommand's `run`: reported as argparse does (exit code 2)."""


def positive_int(text: str) -> int:
    """An argparse type: an integer >= 1."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0."""
    value = float(text)
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def _summary(module: str) -> str:
    """The first line of `module`'s docstring, read from its source (without importing it)."""
    spec = importlib.util.find_spec(f"{__package__}.{module}")
    if spec is None or spec.origin is None:
        raise ImportError(f"no module {__package__}.{module} beside {Path(__file__).parent}")
    doc = ast.get_docstring(ast.parse(Path(spec.origin).read_text(), spec.origin)) or ""
    return doc.strip().splitlines()[0] if doc.strip() else ""


def dispatch(doc: str, commands: Mapping[str, str], argv: Sequence[str] | None = None) -> int:
    """Parse ``COMMAND [options]`` and run the command's module; return its exit code.

    Parameters
    ----------
    doc : str
        The entry script's docstring: its first line is the description, the rest the epilog of ``--help``.
    commands : Mapping[str, str]
        Subcommand name -> module name in `ropecam_tools`; the module has ``add_arguments(parser)`` and
        ``run(args) -> int``.
    argv : Sequence[str], optional
        The arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The subcommand's exit code, by the policy of `ropecam.shared.cli`: argparse exits with 2 on bad arguments,
        a `UsageError` or a `ConfigError`; any other `RopecamError` (a frame set that cannot be read, say) is
        printed, naming what failed, and gives 1.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    chosen = next((arg for arg in argv if not arg.startswith("-")), None)
    subparsers: dict[str, argparse.ArgumentParser] = {}
    for name, module_name in commands.items():
        if name != chosen:
            sub.add_parser(name, help=_summary(module_name))
            continue
        module = importlib.import_module(f"{__package__}.{module_name}")
        subparsers[name] = sub.add_parser(
            name,
            help=_summary(module_name),
            description=module.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        module.add_arguments(subparsers[name])
        subparsers[name].set_defaults(_run=module.run)
    args = parser.parse_args(argv)
    try:
        return int(args._run(args))
    except (UsageError, ConfigError) as exc:
        subparsers[args.command].error(str(exc))
        raise AssertionError("unreachable") from exc  # argparse's error() exits
    except RopecamError as exc:  # bad data: reported as every ropecam command reports it, without a traceback
        print(f"{subparsers[args.command].prog}: error: {exc}", file=sys.stderr)
        return EXIT_RUNTIME
