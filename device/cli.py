"""`ropecam-device`: the camera-computer program (offline extraction, the rig daemon, camera probing)."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from ropecam.shared.cli import run

__all__ = ["COMMAND_MODULES", "main"]

DESCRIPTION = """\
ropecam-device turns camera frames into rope shapes and tracked material points and streams them to the host.

`ropecam-device COMMAND --help` explains each command below.
"""

# One module per sub-command; each defines register(subparsers).
COMMAND_MODULES: tuple[str, ...] = (
    "ropecam.device.extract",
    "ropecam.device.setup",
    "ropecam.device.capture.probe",
    "ropecam.device.daemon.cli",
)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the `ropecam-device` command line; returns the exit code."""
    return run("ropecam-device", DESCRIPTION, COMMAND_MODULES, argv)


if __name__ == "__main__":
    sys.exit(main())
