"""Offline frame sources: a frame set, a folder of PNG/PGM images in name order, or a video file.

Every source yields `SourceFrame` records in order. A frame that cannot be read is yielded with ``image=None`` and
a message, so the caller can record a BAD_FRAME status and go on; only an unusable input as a whole (missing
path, unknown format, video that cannot be opened) raises `CaptureError`.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ropecam.device.capture.frameset import FrameSet, is_frameset
from ropecam.shared.errors import CaptureError, DataError

__all__ = ["IMAGE_SUFFIXES", "VIDEO_SUFFIXES", "FrameSource", "SourceFrame", "open_source"]

IMAGE_SUFFIXES = (".png", ".pgm", ".ppm", ".pnm", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg")
VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov", ".m4v", ".webm", ".mjpeg", ".h264")


@dataclass(frozen=True, slots=True)
class SourceFrame:
    """One frame of an offline source; `image` is None when it could not be read (see `message`)."""

    index: int
    t_ns: int
    exposure_us: float
    image: NDArray[np.uint8] | None
    message: str = ""


class FrameSource:
    """Base of the offline sources: iterate over `SourceFrame`; `image_size` is (width, height) when known."""

    kind = "source"

    def __init__(self, path: Path, fps: float | None, exposure_us: float | None) -> None:
        self.path = path
        self.fps = fps
        self.exposure_us = exposure_us
        self.image_size: tuple[int, int] | None = None
        self.independent = False
        """Whether the frames are separate photos rather than a sequence (each to be measured on its own)."""

    def __len__(self) -> int:
        return 0

    def __iter__(self) -> Iterator[SourceFrame]:
        raise NotImplementedError

    def _time(self, index: int) -> int:
        fps = self.fps or 30.0
        return round(index * 1e9 / fps)


def _gray(image: NDArray[np.generic]) -> tuple[NDArray[np.uint8] | None, str]:
    """Return the 8-bit grey image of a decoded file or video frame, or None and what is wrong with it.

    1 channel is grey, 2 channels grey + alpha (the alpha channel is dropped: it holds no light), 3 BGR, 4 BGRA.
    """
    if image.ndim == 3:
        channels = image.shape[2]
        if channels in (1, 2):
            image = image[:, :, 0]
        elif channels in (3, 4):
            image = cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY if channels == 4 else cv2.COLOR_BGR2GRAY)
        else:
            return None, f"{channels} channels, expected 1 (grey), 2 (grey + alpha), 3 (BGR) or 4 (BGRA)"
    elif image.ndim != 2:
        return None, f"image array of shape {image.shape}, expected (height, width[, channels])"
    if image.dtype == np.uint16:
        return None, "16-bit image: convert to 8 bits first"
    if image.dtype != np.uint8:
        return None, f"unsupported pixel type {image.dtype}, expected uint8"
    return np.ascontiguousarray(image), ""


class _FrameSetSource(FrameSource):
    kind = "frame set"

    def __init__(self, path: Path, fps: float | None, exposure_us: float | None) -> None:
        try:
            self.frameset = FrameSet(path)
        except DataError as exc:
            raise CaptureError(str(exc)) from exc
        super().__init__(path, fps or self.frameset.fps, exposure_us)
        self.image_size = self.frameset.image_size

    def __len__(self) -> int:
        return len(self.frameset)

    def __iter__(self) -> Iterator[SourceFrame]:
        for position, record in enumerate(self.frameset.records):
            exposure = self.exposure_us if self.exposure_us is not None else float(record.exposure_us)
            try:
                image = self.frameset.read(position)
                yield SourceFrame(record.frame, record.t_ns, exposure, image)
            except DataError as exc:
                yield SourceFrame(record.frame, record.t_ns, exposure, None, str(exc))


class _FolderSource(FrameSource):
    """A folder of images in name order: a sequence when a frame rate is given, else separate photos."""

    kind = "image folder"

    def __init__(self, path: Path, fps: float | None, exposure_us: float | None) -> None:
        super().__init__(path, fps, exposure_us)
        self.independent = fps is None
        if self.independent:
            self.kind = "folder of separate photos"
        self.files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
        if not self.files:
            raise CaptureError(f"{path}: no images ({', '.join(IMAGE_SUFFIXES)}) in this folder")

    def __len__(self) -> int:
        return len(self.files)

    def __iter__(self) -> Iterator[SourceFrame]:
        for index, file in enumerate(self.files):
            t_ns = self._time(index)
            exposure = self.exposure_us or 0.0
            raw = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
            if raw is None:
                yield SourceFrame(index, t_ns, exposure, None, f"{file}: unreadable image")
                continue
            image, message = _gray(raw)
            yield SourceFrame(index, t_ns, exposure, image, f"{file}: {message}" if message else "")


class _VideoSource(FrameSource):
    kind = "video"

    def __init__(self, path: Path, fps: float | None, exposure_us: float | None) -> None:
        capture = cv2.VideoCapture(str(path))
        if not capture.isOpened():
            raise CaptureError(f"{path}: cannot open the video (codec or container not supported by OpenCV)")
        video_fps = capture.get(cv2.CAP_PROP_FPS)
        self.count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        capture.release()
        super().__init__(path, fps or (video_fps if video_fps and video_fps > 0 else None), exposure_us)

    def __len__(self) -> int:
        return self.count

    def __iter__(self) -> Iterator[SourceFrame]:
        capture = cv2.VideoCapture(str(self.path))
        try:
            index = 0
            while True:
                ok, raw = capture.read()
                if not ok:
                    break
                image, message = _gray(raw)
                message = f"{self.path} frame {index}: {message}" if message else ""
                yield SourceFrame(index, self._time(index), self.exposure_us or 0.0, image, message)
                index += 1
        finally:
            capture.release()


def open_source(path: str | Path, fps: float | None = None, exposure_us: float | None = None) -> FrameSource:
    """Open `path` as a frame set, an image folder or a video file.

    Parameters
    ----------
    path
        The input.
    fps
        Frame rate for image folders and videos (a frame set's own rate is used when None).
    exposure_us
        Exposure time; overrides a frame set's per-frame value.

    Raises
    ------
    CaptureError
        The path does not exist or is not one of the three kinds.
    """
    path = Path(path)
    if fps is not None and not fps > 0:
        raise CaptureError(f"fps must be > 0, got {fps}")
    if exposure_us is not None and not exposure_us >= 0:
        raise CaptureError(f"exposure must be >= 0, got {exposure_us} us")
    if not path.exists():
        raise CaptureError(f"{path}: no such file or folder")
    if path.is_dir():
        if is_frameset(path):
            return _FrameSetSource(path, fps, exposure_us)
        return _FolderSource(path, fps, exposure_us)
    if path.suffix.lower() in VIDEO_SUFFIXES:
        return _VideoSource(path, fps, exposure_us)
    raise CaptureError(f"{path}: not a frame set folder, an image folder or a video ({', '.join(VIDEO_SUFFIXES)})")
