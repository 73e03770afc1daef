"""Open a frame source from a URL, as the daemon's ``--source`` and config take it.

- ``v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY&buffers=4&exposure_us=2000&gain=0&backend=auto``
  (every query key optional; ``v4l2:/dev/video0`` works too),
- ``frames:DIR?fps=119&loop=1&paced=1`` (DIR relative or absolute; ``frames:///abs/dir`` works too).

Keyword arguments of `open_camera_source` (``--fps``, ``--exposure-ms`` on the command line) override the URL's.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Final
from urllib.parse import urlsplit

from ropecam.device.capture.driver import DriverFactory
from ropecam.device.capture.replay import FrameSetSource
from ropecam.device.capture.source import CameraSource
from ropecam.device.capture.v4l2 import V4l2Source
from ropecam.shared.errors import ConfigError
from ropecam.shared.transport.base import parse_url

__all__ = ["FRAMES_KEYS", "V4L2_KEYS", "open_camera_source", "parse_source_url"]

V4L2_KEYS: Final[Mapping[str, type]] = {
    "width": int,
    "height": int,
    "fps": float,
    "format": str,
    "buffers": int,
    "exposure_us": int,
    "gain": int,
    "backend": str,
}
"""Query keys of ``v4l2:`` URLs and their types."""
FRAMES_KEYS: Final[Mapping[str, type]] = {"fps": float, "loop": bool, "paced": bool}
"""Query keys of ``frames:`` URLs and their types (booleans: 1/0, true/false, yes/no, on/off)."""
_EXAMPLES = "v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY or frames:DIR?fps=119&loop=1"


def parse_source_url(url: str) -> tuple[str, str, dict[str, object]]:
    """Split a source URL into (scheme, path, typed options); raises `ConfigError` naming what is wrong.

    The query is parsed by `ropecam.shared.transport.base.parse_url`, the parser of transport URLs, so both accept
    the same spellings and refuse unknown and repeated keys alike.
    """
    if not isinstance(url, str) or not url.strip():
        raise ConfigError(f"source URL must be a non-empty string like {_EXAMPLES}, got {url!r}")
    scheme = urlsplit(url.strip()).scheme.lower()
    if scheme not in ("v4l2", "frames"):
        raise ConfigError(f"source URL {url!r}: scheme must be v4l2 or frames, e.g. {_EXAMPLES}")
    allowed = V4L2_KEYS if scheme == "v4l2" else FRAMES_KEYS
    _, path, _, options = parse_url(url.strip(), allowed, path=True, what="source URL")
    if not path:
        raise ConfigError(f"source URL {url!r} names no {'device' if scheme == 'v4l2' else 'folder'}, e.g. {_EXAMPLES}")
    if scheme == "v4l2" and not path.startswith("/"):
        raise ConfigError(f"source URL {url!r}: the device must be an absolute path such as /dev/video0")
    for key, value in options.items():
        if isinstance(value, int | float) and not isinstance(value, bool):
            low_ok = value >= 0 if key == "gain" else value > 0
            if not low_ok:
                raise ConfigError(
                    f"source URL {url!r}: {key} must be {'>= 0' if key == 'gain' else '> 0'}, got {value}"
                )
    return scheme, path, options


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
    scheme, path, options = parse_source_url(url)
    if scheme == "frames":
        if exposure_us is not None:
            raise ConfigError(f"source {url!r}: a recorded frame set replays its own exposure; drop the exposure")
        folder = Path(path).expanduser()
        if not folder.is_dir():
            raise ConfigError(f"source URL {url!r}: {folder} is not a folder (a frame set written by `ropecam sim`)")
        return FrameSetSource(
            folder,
            fps=fps if fps is not None else options.get("fps"),  # type: ignore[arg-type]
            paced=bool(options.get("paced", True)),
            loop=loop if loop is not None else bool(options.get("loop", False)),
        )
    if loop:
        raise ConfigError(f"source {url!r}: loop applies to frame sets only")
    backend = options.get("backend", "auto")
    if backend not in ("auto", "linuxpy", "opencv"):
        raise ConfigError(f"source URL {url!r}: backend must be auto, linuxpy or opencv, got {backend!r}")
    width, height = options.get("width"), options.get("height")
    if (width is None) != (height is None):
        raise ConfigError(f"source URL {url!r}: give both width and height, or neither")
    try:
        return V4l2Source(
            path,
            width=width,  # type: ignore[arg-type]
            height=height,  # type: ignore[arg-type]
            fps=fps if fps is not None else options.get("fps"),  # type: ignore[arg-type]
            pixel_format=options.get("format"),  # type: ignore[arg-type]
            exposure_us=exposure_us if exposure_us is not None else options.get("exposure_us"),  # type: ignore[arg-type]
            gain=options.get("gain"),  # type: ignore[arg-type]
            buffer_count=options.get("buffers", 4),  # type: ignore[arg-type]
            driver_factory=driver_factory,
            backend=backend,
        )
    except ValueError as exc:
        raise ConfigError(f"source URL {url!r}: {exc}") from exc
