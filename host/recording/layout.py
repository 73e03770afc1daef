"""The Foxglove layout shipped with ropecam (``ropecam_layout.json``, package data) and written beside each recording.

The layout shows the plane scene, material points and model rope in a 3D panel following ``device<ID>/plane``,
plots of the device's frame rate and drops and of the model error at the tip, and the device log. Its topics name
one device: the shipped file says ``@DEVICE@``; the copy beside a recording names its lowest device id. Open
it in Foxglove with Layouts -> Import from file.
"""

from __future__ import annotations

import logging
from importlib import resources
from pathlib import Path
from typing import Final

__all__ = ["DEVICE_TOKEN", "LAYOUT_FILE", "layout_path", "layout_text", "write_layout"]

LAYOUT_FILE: Final = "ropecam_layout.json"
DEVICE_TOKEN: Final = "@DEVICE@"
log = logging.getLogger(__name__)


def layout_text(device_id: int) -> str:
    """Return the shipped layout with its topics naming device `device_id`."""
    template = resources.files("ropecam.host.recording").joinpath(LAYOUT_FILE).read_text(encoding="utf-8")
    return template.replace(DEVICE_TOKEN, str(int(device_id)))


def layout_path(recording: Path) -> Path:
    """Return where the layout of `recording` goes: ``run.mcap`` -> ``run.layout.json``."""
    return recording.with_name(recording.stem + ".layout.json")


def write_layout(recording: Path, device_id: int, overwrite: bool) -> Path | None:
    """Write the layout for `device_id` beside `recording`; return its path, or None when it was not written.

    An existing layout file is kept unless `overwrite` (the recording's own --force); a failure to write is
    logged, never fatal (the recording is complete without it).
    """
    path = layout_path(recording)
    try:
        with open(path, "w" if overwrite else "x", encoding="utf-8") as handle:
            handle.write(layout_text(device_id))
    except FileExistsError:
        log.warning("%s exists; not replaced (pass --force to replace it)", path)
        return None
    except OSError as exc:
        log.warning("could not write the Foxglove layout %s: %s", path, exc.strerror or exc)
        return None
    return path
