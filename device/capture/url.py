"""Open a frame source from a URL, as the daemon's ``--source`` and config take it.

- ``v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY&buffers=4&exposure_us=2000&gain=0&backend=auto``
  (every query key optional; ``v4l2:/dev/video0`` works too),
- ``frames:DIR?fps=119&loop=1&paced=1`` (DIR relative or absolute; ``frames:///abs/dir`` works too).

Keyword arguments of `open_camera_source` (``--fps``, ``--exposure-ms`` on the command line) override the URL's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from urllib.parse import parse_qsl, unquote, urlsplit

from ropecam.device.capture.driver import DriverFactory
from ropecam.device.capture.replay import FrameSetSource
from ropecam.device.capture.source import CameraSource
from ropecam.device.capture.v4l2 import V4l2Source
from ropecam.shared.errors import ConfigError

__all__ = ["FRAMES_KEYS", "V4L2_KEYS", "open_camera_source", "parse_source_url"]

V4L2_KEYS = ("width", "height", "fps", "format", "buffers", "exposure_us", "gain", "backend")
FRAMES_KEYS = ("fps", "loop", "paced")
_EXAMPLES = "v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY or frames:DIR?fps=119&loop=1"


def parse_source_url(url: str) -> tuple[str, str, dict[str, str]]:
    """Split a source URL into (scheme, path, query); raises `ConfigError` naming what is wrong."""
    if not isinstance(url, str) or not url.strip():
        raise ConfigError(f"source URL must be a non-empty string like {_EXAMPLES}, got {url!r}")
    parts = urlsplit(url.strip())
    scheme = parts.scheme.lower()
    if scheme not in ("v4l2", "frames"):
        raise ConfigError(f"source URL {url!r}: scheme must be v4l2 or frames, e.g. {_EXAMPLES}")
    path = unquote(parts.netloc + parts.path)
    if not path:
        raise ConfigError(f"source URL {url!r} names no {'device' if scheme == 'v4l2' else 'folder'}, e.g. {_EXAMPLES}")
    allowed = V4L2_KEYS if scheme == "v4l2" else FRAMES_KEYS
    query: dict[str, str] = {}
    for key, value in parse_qsl(parts.query, keep_blank_values=True, strict_parsing=False):
        if key not in allowed:
            raise ConfigError(f"source URL {url!r}: unknown key {key!r}; {scheme} takes {', '.join(allowed)}")
        if key in query:
            raise ConfigError(f"source URL {url!r}: key {key!r} given twice")
        query[key] = value
    if scheme == "v4l2" and not path.startswith("/"):
        raise ConfigError(f"source URL {url!r}: the device must be an absolute path such as /dev/video0")
    return scheme, path, query


def _number(url: str, query: Mapping[str, str], key: str, kind: Callable[[str], float]) -> float | None:
    if key not in query:
        return None
    text = query[key]
    try:
        value = kind(text)
    except ValueError:
        expected = "an integer" if kind is int else "a number"
        raise ConfigError(f"source URL {url!r}: {key} must be {expected}, got {text!r}") from None
    in_range = value >= 0 if key == "gain" else value > 0
    if not (math.isfinite(value) and in_range):
        raise ConfigError(f"source URL {url!r}: {key} must be {'>= 0' if key == 'gain' else '> 0'}, got {text!r}")
    return value


def _flag(url: str, query: Mapping[str, str], key: str, default: bool) -> bool:
    text = query.get(key)
    if text is None:
        return default
    if text.lower() in ("1", "true", "yes", "on"):
        return True
    if text.lower() in ("0", "false", "no", "off"):
        return False
    raise ConfigError(f"source URL {url!r}: {key} must be 0 or 1, got {text!r}")


def open_camera_source(
    url: str,
    *,
    fps: float | None = None,
    exposure_us: int | None = None,
    loop: bool | None = None,
    driver_factory: DriverFactory | None = None,
) -> CameraSource:
    """Build the (not yet started) source a URL names; keyword arguments that are not None override the URL.

    Parameters
    ----------
    url
        ``v4l2:///dev/videoN[?...]`` or ``frames:DIR[?...]`` (see the module docstring for the keys).
    fps
        Frame rate (camera) or replay rate (frame set).
    exposure_us
        Manual exposure in us (camera only; a frame set replays its recorded exposure).
    loop
        Replay the frame set in a loop.
    driver_factory
        Opens V4L2 nodes (tests pass `ropecam.device.capture.fake.fake_factory`); default linuxpy/OpenCV.

    Returns
    -------
    CameraSource
        Use it as a context manager to start and stop it.

    Raises
    ------
    ConfigError
        The URL is malformed, has an unknown key or a bad value, or asks for exposure on a frame set.
    DataError
        The frame set cannot be read.
    """
    scheme, path, query = parse_source_url(url)
    if scheme == "frames":
        if exposure_us is not None:
            raise ConfigError(f"source {url!r}: a recorded frame set replays its own exposure; drop the exposure")
        folder = Path(path).expanduser()
        if not folder.is_dir():
            raise ConfigError(f"source URL {url!r}: {folder} is not a folder (a frame set written by `ropecam sim`)")
        return FrameSetSource(
            folder,
            fps=fps if fps is not None else _number(url, query, "fps", float),
            paced=_flag(url, query, "paced", True),
            loop=loop if loop is not None else _flag(url, query, "loop", False),
        )
    if loop:
        raise ConfigError(f"source {url!r}: loop applies to frame sets only")
    backend = query.get("backend", "auto")
    if backend not in ("auto", "linuxpy", "opencv"):
        raise ConfigError(f"source URL {url!r}: backend must be auto, linuxpy or opencv, got {backend!r}")
    width = _number(url, query, "width", int)
    height = _number(url, query, "height", int)
    if (width is None) != (height is None):
        raise ConfigError(f"source URL {url!r}: give both width and height, or neither")
    url_exposure = _number(url, query, "exposure_us", int)
    url_gain = _number(url, query, "gain", int)
    buffers = _number(url, query, "buffers", int)
    try:
        return V4l2Source(
            path,
            width=None if width is None else int(width),
            height=None if height is None else int(height),
            fps=fps if fps is not None else _number(url, query, "fps", float),
            pixel_format=query.get("format"),
            exposure_us=exposure_us
            if exposure_us is not None
            else (None if url_exposure is None else int(url_exposure)),
            gain=None if url_gain is None else int(url_gain),
            buffer_count=4 if buffers is None else int(buffers),
            driver_factory=driver_factory,
            backend=backend,
        )
    except ValueError as exc:
        raise ConfigError(f"source URL {url!r}: {exc}") from exc
