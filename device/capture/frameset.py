"""Frame sets: the project's recording format for raw frames (written by the simulator, read by the device).

A frame set is a folder::

    frameset.json   {"format": "ropecam-frameset", "version": 1, "image_size": [width, height], "fps": 119.0,
                     "camera": {...} | null, "plane": {...} | null, "rig": {...}}
    index.csv       frame,t_ns,exposure_us,file     (one row per frame; t_ns = start of the exposure, integer ns)
    frames/         000000.png, 000001.png, ...     (8-bit single-channel PNG)
    truth.npz       optional ground truth (named arrays, see docs/frameset.md)

`camera` holds ``camera_matrix`` (3x3), ``distortion`` (list) and ``image_size``; `plane` holds ``rvec`` and
``tvec_m`` (OpenCV extrinsics of the motion plane, ``X_camera = R X_plane + t``); `rig` is free metadata (preset,
rope length, diameter, polarity, fixed-end pixel, seed, ...). The index is appended and flushed frame by frame, so
a writer that dies leaves a readable set of every frame written so far.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import re
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any, Final

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.shared.errors import DataError

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "FrameRecord",
    "FrameSet",
    "FrameSetWriter",
    "is_frameset",
    "write_atomically",
]

FORMAT_NAME: Final = "ropecam-frameset"
FORMAT_VERSION: Final = 1
_META: Final = "frameset.json"
_INDEX: Final = "index.csv"
_TRUTH: Final = "truth.npz"
_FRAMES: Final = "frames"
_INDEX_HEADER: Final = ("frame", "t_ns", "exposure_us", "file")
_FRAME_NAME: Final = re.compile(r"\d{6,}\.png")
"""Names the writer gives frames (``000000.png``, ...); only these are removed when a set is overwritten."""


def is_frameset(path: str | Path) -> bool:
    """Return True when `path` is a folder holding a frame set's ``frameset.json``."""
    return (Path(path) / _META).is_file()


@dataclass(frozen=True, slots=True)
class FrameRecord:
    """One row of the index: frame number, exposure start in ns, exposure time in us, image file."""

    frame: int
    t_ns: int
    exposure_us: int
    path: Path


class FrameSet:
    """Read a frame set folder.

    Parameters
    ----------
    root
        The folder.

    Raises
    ------
    DataError
        The folder, its metadata or its index is missing or malformed (the message names the file and the line).
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        meta_path = self.root / _META
        try:
            meta = json.loads(meta_path.read_text(encoding="utf-8"))
        except FileNotFoundError as exc:
            raise DataError(f"{self.root}: not a frame set (no {_META})") from exc
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise DataError(f"{meta_path}: cannot read frame-set metadata: {exc}") from exc
        if not isinstance(meta, dict):
            raise DataError(f"{meta_path}: must hold a JSON object, got {type(meta).__name__}")
        self.meta: dict[str, Any] = meta
        if meta.get("format") != FORMAT_NAME:
            raise DataError(f"{meta_path}: format is {meta.get('format')!r}, expected {FORMAT_NAME!r}")
        if meta.get("version") != FORMAT_VERSION:
            raise DataError(f"{meta_path}: version {meta.get('version')!r} not supported (expected 1)")
        self.image_size = _image_size(meta.get("image_size"), meta_path)
        self.fps = _fps(meta.get("fps"), meta_path)
        self.records = self._read_index()

    def _read_index(self) -> list[FrameRecord]:
        index_path = self.root / _INDEX
        records: list[FrameRecord] = []
        reader = None
        try:
            with index_path.open(newline="", encoding="utf-8") as handle:
                reader = csv.reader(handle, strict=True)
                header = next(reader, None)
                if tuple(header or ()) != _INDEX_HEADER:
                    raise DataError(f"{index_path}: header must be {','.join(_INDEX_HEADER)}, got {header}")
                for row in reader:
                    if not row:
                        continue
                    where = f"{index_path}:{reader.line_num}"
                    try:
                        frame, t_ns, exposure_us, name = int(row[0]), int(row[1]), int(row[2]), row[3]
                    except (IndexError, ValueError) as exc:
                        raise DataError(f"{where}: bad row {row!r} ({exc})") from exc
                    records.append(FrameRecord(frame, t_ns, exposure_us, _member_path(self.root, name, where)))
        except FileNotFoundError as exc:
            raise DataError(f"{self.root}: frame set has no {_INDEX}") from exc
        except UnicodeDecodeError as exc:
            raise DataError(f"{index_path}: not UTF-8 text ({exc})") from exc
        except csv.Error as exc:
            line = f":{reader.line_num}" if reader is not None else ""
            raise DataError(f"{index_path}{line}: malformed CSV ({exc})") from exc
        except OSError as exc:
            raise DataError(f"{index_path}: cannot read the index: {exc}") from exc
        return records

    def __len__(self) -> int:
        return len(self.records)

    @property
    def exposure_us(self) -> int | None:
        """The exposure time of the first frame in us (None for an empty set)."""
        return self.records[0].exposure_us if self.records else None

    @property
    def camera_gamma(self) -> float | None:
        """The gamma of the camera's output curve, when the metadata states it (``camera.gamma``, or the
        simulator's ``rig.config.sensor.gamma``); None when it does not say."""
        camera = self.meta.get("camera")
        value = camera.get("gamma") if isinstance(camera, dict) else None
        if value is None:
            sensor = self.meta.get("rig", {}).get("config", {}).get("sensor", {})
            value = sensor.get("gamma") if isinstance(sensor, dict) else None
        return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None

    def read(self, position: int) -> NDArray[np.uint8]:
        """Return frame number `position` of the index as a (height, width) uint8 array.

        Raises
        ------
        DataError
            The image is missing, unreadable or not of the set's image size.
        """
        record = self.records[position]
        image = cv2.imread(str(record.path), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise DataError(f"{record.path}: missing or unreadable image (frame {record.frame})")
        if image.ndim == 3:
            image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if image.dtype != np.uint8:
            raise DataError(f"{record.path}: expected 8-bit pixels, got {image.dtype}")
        width, height = self.image_size
        if image.shape != (height, width):
            raise DataError(f"{record.path}: image is {image.shape[1]}x{image.shape[0]}, set says {width}x{height}")
        return np.ascontiguousarray(image)

    def __iter__(self) -> Iterator[tuple[FrameRecord, NDArray[np.uint8]]]:
        for position, record in enumerate(self.records):
            yield record, self.read(position)

    def truth(self) -> dict[str, NDArray[Any]] | None:
        """Return the ground-truth arrays, or None when the set has none."""
        path = self.root / _TRUTH
        if not path.is_file():
            return None
        try:
            with np.load(path) as data:
                return {key: data[key] for key in data.files}
        except (OSError, ValueError) as exc:
            raise DataError(f"{path}: cannot read ground truth: {exc}") from exc


def _image_size(value: object, meta_path: Path) -> tuple[int, int]:
    """Return the metadata's ``image_size`` as (width, height), both positive integers."""
    if (
        not isinstance(value, list)
        or len(value) != 2
        or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in value)
    ):
        raise DataError(f"{meta_path}: image_size must be [width, height], two integers > 0, got {value!r}")
    return int(value[0]), int(value[1])


def _fps(value: object, meta_path: Path) -> float:
    """Return the metadata's ``fps``: a finite number > 0."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not (math.isfinite(value) and value > 0):
        raise DataError(f"{meta_path}: fps must be a finite number > 0 (frames per second), got {value!r}")
    return float(value)


def _member_path(root: Path, name: str, where: str) -> Path:
    """Return ``root / name`` for an index's `file` column, refusing names that leave the frame set's folder."""
    relative = PurePosixPath(name)
    if not name or relative.is_absolute() or PureWindowsPath(name).is_absolute() or ".." in relative.parts:
        raise DataError(
            f"{where}: file {name!r} must be a path inside the frame set (relative, no '..'), e.g. frames/000000.png"
        )
    return root / relative


def write_atomically(path: str | Path, write: Callable[[Path], object], what: str = "file") -> None:
    """Write `path` through a temporary file in the same folder renamed into place, so it is never half written.

    Parameters
    ----------
    path
        The file to (re)place.
    write
        Writes the content to the path it is given (``<name>.tmp<suffix>``: same suffix, so writers that add a
        missing suffix, as `numpy.savez` does, write exactly there).
    what
        What the file holds, for the error message (``"ground truth"``).

    Raises
    ------
    DataError
        Writing or renaming failed (an OS error); the temporary file is removed and an existing `path` is kept.
    """
    path = Path(path)
    tmp = path.with_name(f"{path.stem}.tmp{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise DataError(f"{path}: cannot write the {what}: {exc}") from exc


def _frame_files(folder: Path) -> list[Path]:
    """Return the files in `folder` named like the writer's frames, sorted (none if the folder does not exist)."""
    try:
        return sorted(p for p in folder.iterdir() if _FRAME_NAME.fullmatch(p.name) and p.is_file())
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise DataError(f"{folder}: cannot list frames: {exc}") from exc


class FrameSetWriter:
    """Write a frame set folder frame by frame; usable as a context manager.

    Parameters
    ----------
    root
        The folder to create.
    image_size
        (width, height) of every frame.
    fps
        Frame rate in frames per second.
    metadata
        Extra top-level keys for ``frameset.json`` (``camera``, ``plane``, ``rig``); JSON-serialisable.
    overwrite
        Replace an existing frame set in `root`: its metadata, index, ground truth and the frames the writer named
        (``frames/NNNNNN.png``; other files are left alone). Otherwise an existing set, or frames without a set's
        metadata, is an error.

    Raises
    ------
    DataError
        `root` holds a frame set or frame files already (without `overwrite`), or cannot be written.
    """

    def __init__(
        self,
        root: str | Path,
        image_size: tuple[int, int],
        fps: float,
        metadata: Mapping[str, Any] | None = None,
        overwrite: bool = False,
    ) -> None:
        self.root = Path(root)
        if is_frameset(self.root) and not overwrite:
            raise DataError(f"{self.root}: a frame set exists already (use overwrite to replace it)")
        stale_frames = _frame_files(self.root / _FRAMES)
        if stale_frames and not overwrite:
            raise DataError(
                f"{self.root / _FRAMES}: holds {len(stale_frames)} frame files (e.g. {stale_frames[0].name}) but "
                f"{self.root} has no {_META}; use overwrite to replace them"
            )
        if not (fps > 0 and np.isfinite(fps)):
            raise ValueError(f"fps must be > 0, got {fps!r}")
        width, height = image_size
        if width <= 0 or height <= 0:
            raise ValueError(f"image_size must be (width, height) > 0, got {image_size}")
        self.image_size = (int(width), int(height))
        try:
            (self.root / _FRAMES).mkdir(parents=True, exist_ok=True)
            # The index goes first: an interrupted overwrite must not leave an index naming deleted frames.
            for stale in (self.root / _INDEX, self.root / _TRUTH, *stale_frames):
                stale.unlink(missing_ok=True)
            meta = {"format": FORMAT_NAME, "version": FORMAT_VERSION, "image_size": list(self.image_size)}
            meta.update({"fps": float(fps), "camera": None, "plane": None, "rig": {}})
            meta.update(metadata or {})
            (self.root / _META).write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
            self._index = (self.root / _INDEX).open("w", newline="", encoding="utf-8")
        except OSError as exc:
            raise DataError(f"{self.root}: cannot create frame set: {exc}") from exc
        self._writer = csv.writer(self._index)
        self._writer.writerow(_INDEX_HEADER)
        self.count = 0

    def add(self, image: NDArray[np.uint8], t_ns: int, exposure_us: int) -> FrameRecord:
        """Write one frame; returns its index record."""
        width, height = self.image_size
        if image.dtype != np.uint8 or image.shape != (height, width):
            raise ValueError(f"image must be uint8 of shape ({height}, {width}), got {image.dtype} {image.shape}")
        name = f"{_FRAMES}/{self.count:06d}.png"
        if not cv2.imwrite(str(self.root / name), image):
            raise DataError(f"{self.root / name}: cannot write image")
        record = FrameRecord(self.count, int(t_ns), int(exposure_us), self.root / name)
        self._writer.writerow([record.frame, record.t_ns, record.exposure_us, name])
        self._index.flush()
        self.count += 1
        return record

    def write_truth(self, arrays: Mapping[str, NDArray[Any]]) -> None:
        """Write the ground-truth arrays (atomically: a temporary file renamed into place).

        Raises
        ------
        DataError
            The file cannot be written (the message names it).
        """
        write_atomically(self.root / _TRUTH, lambda tmp: np.savez_compressed(tmp, **dict(arrays)), "ground truth")

    def close(self) -> None:
        """Close the index file."""
        if not self._index.closed:
            self._index.close()

    def __enter__(self) -> FrameSetWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
