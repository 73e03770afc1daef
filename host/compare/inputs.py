"""The measurements `ropecam compare` reads: extract JSON lines, MCAP recordings, and raw frame sets.

Every kind becomes the same list of `MeasuredFrame` (shapes in distorted pixels, exposure times on the device clock):

* ``*.jsonl``: the output of ``ropecam-device extract`` (or ``ropecam replay --export-jsonl``).
* ``*.mcap``: a recording of ``ropecam monitor --record`` (rolled parts ``run_001.mcap``, ... are read in order);
  the FrameResults of one device (``device_id``, default the first one seen), each frame once.
* a folder holding a frame set (``frameset.json``), or an image folder or video: measured now with the device
  pipeline, offline, exactly as ``ropecam-device extract`` would (settings from the ``[pipeline]`` table of
  ``pipeline_config``).
"""

from __future__ import annotations

import re
from pathlib import Path

from ropecam.host.compare.measurement import MeasuredFrame, measured_frame, read_extract_jsonl
from ropecam.shared.errors import DataError

__all__ = ["MEASUREMENT_KINDS", "find_measurements", "is_single_measurement", "read_measurement"]

MEASUREMENT_KINDS = "an extract .jsonl, a .mcap recording, or a frame set folder"
_VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov")
_IMAGE_SUFFIXES = (".png", ".pgm")
_LATER_PART = re.compile(r"^(?P<stem>.+)_\d{3}$")


def read_measurement(
    path: Path, device_id: int | None = None, pipeline_config: Path | None = None
) -> list[MeasuredFrame]:
    """Read (or measure) the frames of one measurement; see the module docstring for the kinds.

    Raises
    ------
    DataError
        The path does not exist, is of no known kind, or holds no frames of the device (the message names it).
    ConfigError
        `pipeline_config` is unreadable or invalid.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path} does not exist (expected {MEASUREMENT_KINDS})")
    suffix = path.suffix.lower()
    if path.is_file() and suffix == ".jsonl":
        return read_extract_jsonl(path)
    from ropecam.host.offline import frames_messages
    from ropecam.host.recording.reader import device_frames, iter_raw, recording_parts

    if path.is_file() and suffix == ".mcap":
        records, found = device_frames(iter_raw(recording_parts(path)), device_id)
        if found is None or not records:
            which = "any device" if device_id is None else f"device {device_id}"
            raise DataError(f"{path} holds no FrameResult of {which}: nothing to compare with the model")
        return [measured_frame(record) for record in records]
    if path.is_dir() or suffix in _VIDEO_SUFFIXES:
        records, _ = device_frames(frames_messages(path, pipeline_config))
        return [measured_frame(record) for record in records]
    raise DataError(f"{path}: unknown measurement kind {suffix or '(no suffix)'!r} (expected {MEASUREMENT_KINDS})")


def is_single_measurement(path: Path) -> bool:
    """True for a file, a frame set folder or an image folder (one measurement); False for a folder of
    measurements (batch)."""
    if not path.is_dir() or (path / "frameset.json").is_file():
        return True
    return any(p.suffix.lower() in _IMAGE_SUFFIXES for p in path.iterdir() if p.is_file())


def find_measurements(folder: Path) -> list[Path]:
    """The measurements in a batch folder: ``*.jsonl``, ``*.mcap`` (first parts only) and frame set sub-folders.

    Raises
    ------
    DataError
        The folder holds none (the message says what was looked for).
    """
    found = sorted(folder.glob("*.jsonl"))
    for mcap in sorted(folder.glob("*.mcap")):
        later = _LATER_PART.match(mcap.stem)
        if later and (mcap.with_name(later["stem"] + mcap.suffix)).exists():
            continue  # a later part of a rolled recording: read with its first part
        found.append(mcap)
    found += sorted(p for p in folder.iterdir() if p.is_dir() and (p / "frameset.json").is_file())
    if not found:
        raise DataError(f"{folder}: no measurements in this folder (looked for {MEASUREMENT_KINDS}s)")
    return found
