"""Fuzzers of ropecam: random and mutated inputs until a finding or the count is reached.

    python tools/fuzz.py COMMAND [options]         python tools/fuzz.py COMMAND --help

The short, bounded runs are in the test suite; these are the long ones.
"""

import sys

from ropecam_tools.cli import dispatch

COMMANDS = {"protocol": "fuzz_protocol"}
"""Subcommand -> module of `ropecam_tools` (with ``add_arguments(parser)`` and ``run(args) -> int``)."""

if __name__ == "__main__":
    sys.exit(dispatch(__doc__, COMMANDS))
