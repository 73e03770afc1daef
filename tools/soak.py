"""Soak runs of ropecam: a component at its working rate for a long time, watching memory, drops and timing.

python tools/soak.py COMMAND [options]         python tools/soak.py COMMAND --help
"""

import sys

from ropecam_tools.cli import dispatch

COMMANDS = {"device": "soak_device"}
"""Subcommand -> module of `ropecam_tools` (with ``add_arguments(parser)`` and ``run(args) -> int``)."""

if __name__ == "__main__":
    sys.exit(dispatch(__doc__, COMMANDS))
