"""`ropecam-device probe`: list the cameras, their formats, frame sizes, rates and controls.

The library side, `probe_cameras`, returns plain dicts (JSON-ready); the command prints them as text or ``--json``.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ropecam.device.capture.driver import DriverFactory
from ropecam.device.capture.v4l2 import (
    AUTO_EXPOSURE_CONTROLS,
    EXPOSURE_CONTROLS,
    EXPOSURE_UNIT_US,
    PIXEL_FORMATS,
    default_driver_factory,
    describe_os_error,
)

__all__ = ["format_report", "list_video_nodes", "probe_camera", "probe_cameras", "register"]

EXIT_NO_CAMERA = 1

HELP = """\
List the V4L2 cameras (/dev/video*), with the pixel formats, frame sizes and frame rates each offers and its
controls (range, default, current value). Formats ropecam can use (GREY/Y8 or YUYV) are marked with *.

examples:
  ropecam-device probe                      every /dev/video* node
  ropecam-device probe /dev/video0 --json   one camera, machine-readable

Use the size, rate and format in the daemon's source URL:
  v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY
Exit code 1 when no camera could be probed.
"""


def list_video_nodes(dev_dir: str | Path = "/dev") -> list[str]:
    """Return the ``video*`` nodes in `dev_dir`, in numeric order."""

    def number(path: Path) -> tuple[int, str]:
        digits = re.sub(r"\D", "", path.name)
        return (int(digits) if digits else -1, path.name)

    return [str(path) for path in sorted(Path(dev_dir).glob("video*"), key=number)]


def probe_camera(path: str, driver_factory: DriverFactory) -> dict[str, Any]:
    """Return what one node offers; an OS error is reported in ``"error"`` instead of raised."""
    report: dict[str, Any] = {"path": path, "error": None}
    try:
        with driver_factory(path) as driver:
            report.update(driver.info())
            report["formats"] = [
                {
                    "fourcc": fmt.fourcc,
                    "description": fmt.description,
                    "usable": fmt.fourcc in PIXEL_FORMATS,
                    "sizes": [
                        {"width": s.width, "height": s.height, "fps": list(s.fps), "fps_range": s.fps_range}
                        for s in fmt.sizes
                    ],
                    "size_range": fmt.size_range,
                }
                for fmt in driver.formats()
            ]
            try:
                current = driver.get_format()
                report["current"] = {"width": current.width, "height": current.height, "fourcc": current.fourcc}
                report["fps"] = driver.get_fps()
            except OSError:  # a metadata node (uvcvideo makes one per camera) has no capture format
                report["current"], report["fps"] = None, None
            report["controls"] = [
                {
                    "name": c.name,
                    "kind": c.kind,
                    "minimum": c.minimum,
                    "maximum": c.maximum,
                    "step": c.step,
                    "default": c.default,
                    "value": c.value,
                    "menu": {str(k): v for k, v in c.menu.items()},
                }
                for c in driver.controls().values()
            ]
    except OSError as exc:
        report["error"] = describe_os_error(path, exc)
    return report


def probe_cameras(
    paths: Sequence[str] | None = None, driver_factory: DriverFactory | None = None
) -> list[dict[str, Any]]:
    """Probe `paths` (default: every /dev/video* node); see `probe_camera`."""
    factory = driver_factory or default_driver_factory()
    return [probe_camera(path, factory) for path in (list_video_nodes() if paths is None else paths)]


def _rates(size: dict[str, Any]) -> str:
    if size["fps"]:
        return ", ".join(f"{r:g}" for r in size["fps"]) + " fps"
    if size["fps_range"]:
        return f"{size['fps_range'][0]:g}..{size['fps_range'][1]:g} fps"
    return "rates not listed"


def format_report(cameras: Sequence[dict[str, Any]]) -> str:
    """Return the probe result as readable text."""
    lines = []
    for camera in cameras:
        if camera["error"]:
            lines.append(f"{camera['path']}: cannot probe: {camera['error']}")
            continue
        lines.append(f"{camera['path']}: {camera.get('card', '?')} (driver {camera.get('driver', '?')})")
        current = camera["current"]
        if current is not None:
            size = f"{current['width']}x{current['height']} {current['fourcc']}"
            lines.append(f"  current: {size} at {camera['fps']:g} fps")
        if not camera["formats"]:
            lines.append("  no capture formats (a metadata node?)")
        for fmt in camera["formats"]:
            mark = "*" if fmt["usable"] else " "
            lines.append(f"  {mark} {fmt['fourcc']:<4}  {fmt['description']}")
            for size in fmt["sizes"]:
                lines.append(f"        {size['width']}x{size['height']}: {_rates(size)}")
            if fmt["size_range"]:
                w0, w1, h0, h1 = fmt["size_range"]
                lines.append(f"        any size {w0}..{w1} x {h0}..{h1}")
        if camera["controls"]:
            lines.append("  controls:")
        for c in camera["controls"]:
            span = f" [{c['minimum']}..{c['maximum']}]" if c["minimum"] is not None else ""
            note = ""
            if c["name"] in EXPOSURE_CONTROLS and c["value"] is not None:
                note = f"  (= {c['value'] * EXPOSURE_UNIT_US} us; 100 us units)"
            elif c["name"] in AUTO_EXPOSURE_CONTROLS and c["menu"]:
                note = "  (" + ", ".join(f"{k}: {v}" for k, v in c["menu"].items()) + ")"
            lines.append(f"    {c['name']:<28} {c['kind']:<7} value {c['value']}{span}{note}")
    return "\n".join(lines)


def _run(args: argparse.Namespace) -> int:
    paths = args.devices or list_video_nodes(args.dev_dir)
    if not paths:
        message = (
            f"no camera found: {args.dev_dir}/video* does not exist. Check the cable and `dmesg | tail`; "
            "a CSI camera may need its driver enabled (dtoverlay) and a reboot."
        )
        if args.json:
            print(json.dumps({"cameras": [], "message": message}, indent=2))
        print(f"ropecam-device probe: {message}", file=sys.stderr)
        return EXIT_NO_CAMERA
    cameras = probe_cameras(paths, default_driver_factory(args.backend))
    if args.json:
        print(json.dumps({"cameras": cameras}, indent=2))
    else:
        print(format_report(cameras))
    if all(camera["error"] for camera in cameras):
        denied = any("permission denied" in camera["error"] for camera in cameras)
        hint = " (add the user to the `video` group and log in again)" if denied else ""
        print(f"ropecam-device probe: no camera could be opened{hint}", file=sys.stderr)
        return EXIT_NO_CAMERA
    return 0


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``probe`` sub-command."""
    parser = subparsers.add_parser(
        "probe",
        help="list cameras, their formats, sizes, frame rates and controls",
        description=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("devices", nargs="*", metavar="DEVICE", help="device nodes to probe (default: all)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    parser.add_argument(
        "--backend",
        choices=("auto", "linuxpy", "opencv"),
        default="auto",
        help="V4L2 access: linuxpy (default when installed) or OpenCV (lists no formats or ranges)",
    )
    parser.add_argument("--dev-dir", default="/dev", help=argparse.SUPPRESS)
    parser.set_defaults(func=_run)
