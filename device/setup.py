"""`ropecam-device setup`: decide a new rig's `[pipeline]` settings from a few seconds of its frames."""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import tomllib
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

from ropecam.shared.cli import declare_outputs
from ropecam.shared.errors import ConfigError, DataError

__all__ = ["DECIDED_KEYS", "read_frames", "register", "run_setup", "with_pipeline_table"]

DECIDED_KEYS = (
    "polarity", "canny_low", "canny_high", "lens_blur_px", "sharpen_gain", "sharpen_sigma_px", "rope_width_px",
    "length0_px", "fixed_end_uv", "static_mask_png", "background_png",
)  # fmt: skip
"""The `[pipeline]` keys setup decides (an existing table's other keys are kept)."""

HELP = """\
Decide a rig's pipeline settings from a few seconds of its frames, with the rope swinging as it will when you
measure: edge thresholds, polarity (bright rope on dark ground or the reverse), the camera's blur and sharpening
(read across the rope's still part near the fixed end), the rope's width and length in pixels, the fixed end, and
the static mask (pixels that are edges in at least half the frames while the rope moves: clamp, rod, plate edge,
scratches, a static second cable); on a textured background (a sheet's grain, a table's weave), the background
itself, learned while the rope moves and divided out of each frame before its edges. Each candidate setting is
tried by running the pipeline itself over the frames; the one that measures most frames most consistently is kept.

It writes the [pipeline] table of OUT (a device.toml; with --force an existing file keeps its other tables and the
[pipeline] keys setup does not decide, such as rope_length_m), the static mask beside it (OUT_mask.png, white =
static), the background when it is used (OUT_background.png, 16-bit, linear light x 256), and an overlay picture
(OUT_overlay.png) to check by eye before measuring. It prints what it could not decide, and why; a scene in which
no setting finds a rope ends with exit status 1.

INPUT is what `extract` takes (a frame set, a folder of images in name order, a video) or a camera URL as the
daemon takes it (v4l2:///dev/video0?width=1024&height=544&fps=119&format=GREY, frames:DIR).

examples:
  ropecam-device setup sets/lab --out device.toml
  ropecam-device setup "v4l2:///dev/video0?fps=119&format=GREY" --exposure-ms 4 --out /etc/ropecam/device.toml \\
      --rope-length-m 0.411 --force
  ropecam-device extract sets/lab --config device.toml --out lab.jsonl
"""


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the `setup` sub-command."""
    parser = subparsers.add_parser(
        "setup",
        help="decide a rig's [pipeline] settings (thresholds, polarity, width, fixed end, mask) from its frames",
        description=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("input", metavar="INPUT", help="frame set, image folder, video, or camera URL (v4l2:, frames:)")
    parser.add_argument("--out", required=True, metavar="TOML", help="device.toml to write ([pipeline] table)")
    parser.add_argument("--overlay", metavar="PNG", help="overlay picture (default: OUT's name + _overlay.png)")
    parser.add_argument("--seconds", type=float, default=2.0, help="seconds of frames to decide from (default 2)")
    parser.add_argument("--fps", type=float, help="frame rate (needed for image folders; default: the input's)")
    parser.add_argument("--exposure-ms", type=float, help="exposure time in ms (default: the input's own)")
    parser.add_argument("--rope-length-m", type=float, help="rope length in metres (setup cannot see metres)")
    parser.add_argument(
        "--material-points-m", type=float, nargs="+", metavar="S", help="arc lengths of tracked points (m)"
    )
    parser.add_argument(
        "--plane",
        metavar="YAML",
        help="the rig's plane calibration (plane.yaml): the fixed end is its origin projected, as the device will "
        "measure with it; written to the table as plane_file",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    declare_outputs(parser, "out", derived=lambda args: _derived_outputs(args.out, args.overlay))
    parser.set_defaults(func=_main)


def _derived_outputs(out: str, overlay: str | None) -> list[Path]:
    path = Path(out)
    return [
        path.with_name(path.stem + "_mask.png"),
        path.with_name(path.stem + "_background.png"),
        Path(overlay) if overlay else _overlay_path(path),
    ]


def _overlay_path(out: Path) -> Path:
    return out.with_name(out.stem + "_overlay.png")


def _main(args: argparse.Namespace) -> int:
    if not args.seconds > 0:
        raise ConfigError(f"--seconds must be > 0, got {args.seconds}")
    exposure_us = None if args.exposure_ms is None else args.exposure_ms * 1000.0
    return run_setup(
        args.input,
        args.out,
        overlay=args.overlay,
        seconds=args.seconds,
        fps=args.fps,
        exposure_us=exposure_us,
        rope_length_m=args.rope_length_m,
        material_points_m=args.material_points_m,
        plane_file=args.plane,
        progress=not args.quiet,
    )


def _declared_gamma(source: str) -> float | None:
    """The camera gamma a frame set folder's metadata states (`FrameSet.camera_gamma`), else None."""
    from ropecam.device.capture.frameset import FrameSet
    from ropecam.shared.errors import RopecamError

    if not (Path(source) / "frameset.json").is_file():
        return None
    try:
        return FrameSet(source).camera_gamma
    except RopecamError:
        return None


def read_frames(
    source: str, seconds: float, fps: float | None, exposure_us: float | None
) -> tuple[list[Any], str, float | None]:
    """Read up to `seconds` of frames from a frame set, image folder, video or camera URL.

    Returns the frames (`setup_decide.Frame`), a description of the input, and its frame rate (None if unknown:
    then up to 240 frames are read). Unreadable frames are skipped. Raises `CaptureError`/`ConfigError` when the
    input cannot be opened.
    """
    from ropecam.device.setup_decide import Frame

    frames: list[Frame] = []
    if source.split(":", 1)[0].lower() in ("v4l2", "frames"):
        from ropecam.device.capture.url import open_camera_source

        camera = open_camera_source(
            source, fps=fps, exposure_us=None if exposure_us is None else round(exposure_us), loop=False
        )
        with camera:
            rate = camera.fps or fps
            count = round(seconds * rate) if rate else 240
            misses = 0
            while len(frames) < count and misses < 5 and not camera.finished:
                item = camera.read(timeout_s=2.0)
                if item is None:
                    misses += 1
                    continue
                frames.append(Frame(item.image.copy(), int(item.t_ns), float(item.exposure_us)))
        return frames, f"camera {source}", rate
    from ropecam.device.capture.sources import open_source

    opened = open_source(source, fps, exposure_us)
    rate = opened.fps
    count = round(seconds * rate) if rate else 240
    for item in opened:
        if len(frames) >= count:
            break
        if item.image is not None:
            frames.append(Frame(item.image, int(item.t_ns), float(item.exposure_us or 0.0)))
    return frames, f"{opened.kind} {source}", rate


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, int | float):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r} to TOML")


def with_pipeline_table(old_text: str, table: str) -> str:
    """Return `old_text` (a TOML file) with its ``[pipeline]`` table and sub-tables replaced by `table` (appended
    when there was none)."""
    out: list[str] = []
    skipping = inserted = False
    for line in old_text.splitlines(keepends=True):
        stripped = line.split("#", 1)[0].strip()
        if stripped.startswith("["):
            name = stripped.strip("[]").strip()
            skipping = name == "pipeline" or name.startswith("pipeline.")
            if skipping and not inserted:
                out.append(table)
                inserted = True
        if not skipping:
            out.append(line)
    if not inserted:
        if out and not out[-1].endswith("\n"):
            out.append("\n")
        out.append(("\n" if out else "") + table)
    return "".join(out)


def _check_writable_folder(path: Path) -> None:
    """Raise `DataError` unless `path`'s folder exists and is writable or can be made (its nearest existing ancestor
    is a writable folder)."""
    folder = path.resolve().parent
    existing = next(p for p in (folder, *folder.parents) if p.exists())
    if not existing.is_dir():
        raise DataError(f"{path}: cannot write here: {existing} is a file, not a folder. Nothing was written.")
    if not os.access(existing, os.W_OK | os.X_OK):
        what = "its folder" if existing == folder else f"{existing} (to make its folder {folder})"
        raise DataError(f"{path}: cannot write here: no write permission on {what}. Nothing was written.")


def _make_folder(path: Path) -> None:
    try:
        path.resolve().parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(f"{path}: cannot make its folder: {exc.strerror}") from exc


def _write_text(path: Path, text: str) -> None:
    temporary = path.with_name(path.name + ".tmp")
    try:
        temporary.write_text(text)
        temporary.replace(path)
    except OSError as exc:
        raise DataError(f"{path}: cannot write: {exc.strerror}") from exc


def run_setup(
    source: str,
    out: str | Path,
    *,
    overlay: str | Path | None = None,
    seconds: float = 2.0,
    fps: float | None = None,
    exposure_us: float | None = None,
    rope_length_m: float | None = None,
    material_points_m: Iterable[float] | None = None,
    plane_file: str | Path | None = None,
    progress: bool = False,
) -> int:
    """Decide the settings from `source`, write `out` ([pipeline] table), its mask and overlay PNGs; returns 0.

    Raises
    ------
    DataError
        Too few readable frames, no rope found with any setting, or an output cannot be written.
    ConfigError
        The existing `out` is not valid TOML, the given rope length / material points are invalid, or
        `plane_file` cannot be read or does not fit the frames (it is then used as the device will: every
        candidate runs with the fixed end it gives, and the table gets ``plane_file``).
    """
    from ropecam.device.capture.background_file import write_background_png
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.setup_background import background_path, choose_background
    from ropecam.device.setup_decide import MIN_MEASURED, decide
    from ropecam.device.setup_overlay import COLOURS, draw_overlay, write_png
    from ropecam.shared.config import from_mapping

    def say(line: str) -> None:
        if progress:
            print(f"setup: {line}", file=sys.stderr, flush=True)

    out = Path(out)
    old_text = ""
    kept: dict[str, Any] = {}
    readout_us: Any = 0
    if out.exists():
        try:
            old_text = out.read_text()
            old = tomllib.loads(old_text)
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise ConfigError(f"{out}: cannot read the existing file to update its [pipeline] table: {exc}") from exc
        kept = dict(old.get("pipeline", {}))
        readout_us = old.get("capture", {}).get("readout_us", 0)
    kept = {k: v for k, v in kept.items() if k not in DECIDED_KEYS and not isinstance(v, dict)}
    if rope_length_m is not None:
        kept["rope_length_m"] = rope_length_m
    if material_points_m is not None:
        kept["material_points_m"] = list(material_points_m)
    elif rope_length_m is not None and "material_points_m" in kept:
        kept["material_points_m"] = [s for s in kept["material_points_m"] if s <= rope_length_m]
    if plane_file is not None:
        kept["plane_file"] = str(Path(plane_file).resolve())
    if rope_length_m is not None and "material_points_m" not in kept:
        kept["material_points_m"] = [round(rope_length_m * f, 6) for f in (0.25, 0.5, 0.75, 1.0)]
    base = from_mapping(PipelineConfig, kept, where=f"{out} [pipeline] (kept keys and options)")

    overlay_path = Path(overlay) if overlay else _overlay_path(out)
    for path in (out, overlay_path):
        _check_writable_folder(path)  # before minutes of work, not after
    frames, described, rate = read_frames(source, seconds, fps, exposure_us)
    declared = _declared_gamma(source)
    if "gamma" not in kept and declared is not None and declared != 1.0:
        kept["gamma"] = declared  # the camera's own output curve, as its recording states it
        base = from_mapping(PipelineConfig, kept, where=f"{source}: the gamma its metadata states")
        say(f"gamma {declared:g}: the camera's output curve, as the frame set's metadata states; frames are linearised")
    if len(frames) < 5:
        raise DataError(f"{source}: {len(frames)} readable frames, setup needs at least 5 (a few seconds of the rope)")
    shape = frames[0].image.shape
    if any(f.image.shape != shape for f in frames):
        raise DataError(f"{source}: the frames are not all of one size (the first is {shape[1]}x{shape[0]})")
    say(f"{len(frames)} frames of {shape[1]}x{shape[0]} from {described}" + (f" at {rate:g} fps" if rate else ""))
    _check_kept(out, base, (shape[1], shape[0]), readout_us, rate)
    background, background_note = choose_background([f.image for f in frames], base.gamma, base.smooth_sigma_px)
    say(background_note)
    with tempfile.TemporaryDirectory(prefix="ropecam-setup-") as folder:
        if background is not None:  # every candidate runs with it, as the device will
            write_background_png(Path(folder) / "background.png", background)
            base = replace(base, background_png=str(Path(folder) / "background.png"))
        findings = decide(frames, base, say)
    findings.notes.append(background_note)
    run = findings.run
    if run.measured < MIN_MEASURED and run.found:
        reasons = "; ".join(f"{why} ({count})" for why, count in sorted(run.reasons.items(), key=lambda i: -i[1]))
        raise DataError(
            f"{source}: a rope was found but too few frames measure: the pipeline measured it on "
            f"{100 * run.measured:.0f} % of {run.frames} frames with the best of every edge threshold and polarity "
            f"tried ({100 * MIN_MEASURED:.0f} % needed); it moves (tips within {run.tip_spread_px:.0f} px, p90) and "
            f"its length stays within {100 * run.length_spread:.1f} % (IQR/median) on the frames measured. "
            f"The others: {reasons}. A faint band (a long exposure, low contrast) against a textured or unevenly "
            "lit background loses its far end; a shorter exposure, more light or a plainer background help. "
            "Nothing was written."
        )
    if run.measured < MIN_MEASURED:
        statuses = ", ".join(f"{k} {v}" for k, v in sorted(run.statuses.items()))
        reasons = "; ".join(f"{why} ({count})" for why, count in sorted(run.reasons.items(), key=lambda i: -i[1]))
        raise DataError(
            f"{source}: no rope found: the pipeline measured a rope on {100 * run.measured:.0f} % of "
            f"{run.frames} frames with every edge threshold and polarity tried (statuses with the best: {statuses}; "
            f"why: {reasons}). {_hint(run.statuses, run.reasons)} Nothing was written."
        )
    if not run.moving:
        raise DataError(
            f"{source}: no rope found: what the pipeline measured does not move (its tips stay within "
            f"{run.tip_spread_px:.0f} px over {run.frames} frames): a rod, clamp or static cable, not a swinging "
            "rope. Record the rope swinging. Nothing was written."
        )
    mask_path = out.resolve().with_name(out.stem + "_mask.png")
    if findings.mask is not None:
        findings.settings["static_mask_png"] = str(mask_path)
    if background is not None:
        findings.settings["background_png"] = str(background_path(out))
    settings = {**kept, **findings.settings}
    config = from_mapping(PipelineConfig, settings, where="the decided settings")
    lines = [
        "[pipeline]",
        f"# written by `ropecam-device setup` from {described} ({len(frames)} frames)",
        f"# check {_overlay_name(out, overlay)} by eye before measuring",
    ]
    lines += [f"{key} = {_toml_value(value)}" for key, value in settings.items()]
    table = "\n".join(lines) + "\n"
    text = with_pipeline_table(old_text, table)
    del config

    for path in (out, overlay_path):
        _make_folder(path)
    if findings.mask is not None:
        write_png(mask_path, findings.mask.astype("uint8") * 255)
    if background is not None:
        write_background_png(background_path(out), background)
    from_mapping(PipelineConfig, tomllib.loads(text)["pipeline"], where=f"{out} [pipeline]")  # what extract reads
    position = findings.split_frame
    begin = end = segmentation = None
    if position is not None:
        begin, end, segmentation = run.shapes[position]
    fixed = findings.settings.get("fixed_end_uv")
    image = frames[position if position is not None else 0].image
    write_png(overlay_path, draw_overlay(image, findings.mask, begin, end, segmentation, fixed))
    _write_text(out, text)

    report = [f"setup: shapes on {100 * run.measured:.0f} % of {run.frames} frames with the chosen settings"]
    report += [f"  {key} = {_toml_value(value)}" for key, value in findings.settings.items()]
    if findings.length_px is not None:
        report.append(f"  rope length on the frames: {findings.length_px:.1f} px (median of the shapes)")
    report += [f"  {note}" for note in findings.notes]
    if findings.undecided:
        report.append("not decided:")
        report += [f"  {item}" for item in findings.undecided]
    if "rope_length_m" not in settings:
        report.append("  rope_length_m: metres cannot be seen in pixels; give --rope-length-m (default 1.0 m applies)")
    legend = ", ".join(f"{name} #{rgb[0]:02x}{rgb[1]:02x}{rgb[2]:02x}" for name, rgb in COLOURS.items())
    report.append(f"wrote {out}, {overlay_path} (frame {position}: {legend})")
    if findings.mask is not None:
        report.append(f"wrote {out.with_name(out.stem + '_mask.png')}")
    if background is not None:
        report.append(f"wrote {background_path(out)}")
    report.append(f"check the overlay, then: ropecam-device extract INPUT --config {out} --out results.jsonl")
    print("\n".join(report), file=sys.stderr)
    return 0


def _check_kept(out: Path, base: Any, image_size: tuple[int, int], readout_us: object, rate: float | None) -> None:
    """Refuse (`ConfigError`, nothing written) the kept settings of the existing `out` that do not fit these
    frames: its [pipeline] plane_file (unreadable, another image size, its origin outside the image) and its
    [capture] readout_us (negative, longer than the frame period), as `extract` and the daemon would refuse them."""
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.shared.config import check_readout
    from ropecam.shared.plane import read_plane_file

    check_readout(f"{out} [capture] readout_us", readout_us, rate)
    if base.plane_file is not None:
        plane = read_plane_file(base.plane_file)
        Pipeline(base, image_size, 0, plane)  # the plane's image size and its origin inside the image


def _hint(statuses: dict[str, int], reasons: dict[str, int] | None = None) -> str:
    """What the most frequent status of a failed run (and, for LOST_TRACK, its most frequent reason) suggests to
    the user."""
    worst = max(statuses, key=statuses.__getitem__) if statuses else "NO_ROPE"
    if worst == "LOST_TRACK" and reasons:
        lost = {why: count for why, count in reasons.items() if why.startswith("LOST_TRACK")}
        common = max(lost, key=lost.__getitem__) if lost else ""
        if "broken" in common or "differ in length" in common:
            # The outline was there but not the band's: its faint far end or sides were lost to noise or texture.
            return (
                "Most frames were LOST_TRACK because the blurred band's outline was broken or its two sides did "
                "not pair: the band is too faint against the frame's noise or texture for its edges (low contrast, "
                "a long exposure, a grainy or textured background). More light or contrast, a shorter exposure or "
                "a plainer background help."
            )
    return {
        "ROPE_CLIPPED": "Most frames were ROPE_CLIPPED: the edges the pipeline took for the rope reach the image "
        "border (a rod, cable or plate edge joined to the rope, or the rope swinging out of view).",
        "LOST_TRACK": "Most frames were LOST_TRACK: an outline was found but could not be split into two shapes "
        '(is the rope moving? a still rope needs method = "static").',
    }.get(worst, "Is the rope in view, in focus, and against a plain background?")


def _overlay_name(out: Path, overlay: str | Path | None) -> str:
    return Path(overlay).name if overlay else _overlay_path(out).name
