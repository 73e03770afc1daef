"""Evaluations of ropecam against ground truth: `python tools/evaluate.py SUBCOMMAND --help`."""

from __future__ import annotations

import argparse
import importlib
import sys

SUBCOMMANDS = {
    "matrix": "ropecam_tools.matrix",
}
"""Subcommand name -> module under tools/ropecam_tools/ exposing `add_arguments(parser)` and `run(args) -> int`."""


def main(argv: list[str] | None = None) -> int:
    """Parse the command line and run the chosen subcommand; return its exit code."""
    parser = argparse.ArgumentParser(prog="evaluate.py", description=__doc__)
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="SUBCOMMAND")
    modules = {}
    for name, module_name in SUBCOMMANDS.items():
        module = importlib.import_module(module_name)
        doc = (module.__doc__ or "").strip()
        sub = subparsers.add_parser(name, help=doc.splitlines()[0] if doc else None, description=doc,
                                    formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
        module.add_arguments(sub)
        modules[name] = module
    args = parser.parse_args(argv)
    return modules[args.command].run(args)


if __name__ == "__main__":
    sys.exit(main())
