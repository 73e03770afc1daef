"""The ``--encoding`` option of the commands that record (light: imported by ``--help``)."""

from __future__ import annotations

import argparse
from importlib.util import find_spec

__all__ = ["add_encoding_option"]


def add_encoding_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--encoding {protobuf,json}`` (the Foxglove channels of a recording) to a command's parser."""
    installed = find_spec("foxglove_schemas_protobuf") is not None
    default = "protobuf" if installed else "json (foxglove-schemas-protobuf is not installed)"
    parser.add_argument(
        "--encoding",
        choices=("protobuf", "json"),
        help="message encoding of the Foxglove channels (scenes, point clouds, transforms, log, images): protobuf "
        f"(about half the file size) or json (readable with any tool). Default here: {default}",
    )
