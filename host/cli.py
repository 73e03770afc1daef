"""`ropecam`: the host program (model, simulator, calibration, monitor, replay, comparison, demo)."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from ropecam.shared.cli import run

__all__ = ["COMMAND_MODULES", "main"]

DESCRIPTION = """\
ropecam measures a swinging rope from one camera and checks an ANCF cable model against the measurement.

Start with `ropecam demo` (simulated rig end to end), or `ropecam COMMAND --help` for any command below.
"""

# One module per sub-command; each defines register(subparsers).
COMMAND_MODULES: tuple[str, ...] = (
    "ropecam.host.demo",
    "ropecam.host.model.cli",
    "ropecam.host.sim.cli",
    "ropecam.host.calibration.cli",
    "ropecam.host.compare.cli",
    "ropecam.host.keygen",
    "ropecam.host.monitor.cli",
    "ropecam.host.replay",
    "ropecam.host.recording.recover",
    "ropecam.host.sim.stream",
)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the `ropecam` command line; returns the exit code."""
    return run("ropecam", DESCRIPTION, COMMAND_MODULES, argv)


if __name__ == "__main__":
    sys.exit(main())
