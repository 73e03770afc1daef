"""`ropecam simulate`: write simulated frame sets with exact ground truth from a preset rig."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ropecam.host.sim.options import REALISM_OPTIONS
from ropecam.host.sim.presets import PRESET_HELP, PRESETS
from ropecam.shared.cli import declare_outputs

__all__ = ["register"]

EPILOG = """\
presets:
{presets}

Each frame set is a folder of PNG frames, an index, metadata and ground truth (truth.npz, trajectory.npz);
see docs/frameset.md. With several exposure times (the paper preset has four), DIR gets one set per exposure,
DIR/exposure_<ms>ms. Anything of a preset can be changed with --config FILE.toml, e.g.

    [rope]                 # the ANCF model's rope: same keys as `ropecam model simulate --config`
    ei_nm2 = 3e-6          # softer rope
    fixed_end = "clamped"
    mass_damping_per_s = 0.2
    [solver]               # the model's [solver]; duration_s is extended to the last exposure
    elements = 24
    [scene]
    render_diameter_m = 0.003
    polarity = "dark"
    [camera]
    plane_rvec = [0.0, 0.1, 0.0]

A file written for `ropecam model simulate --config` works as it is: its [rope] and [solver] tables apply.

realism options ([table] key: unit, range: meaning; set with --config FILE.toml; the lab presets use them):
{options}

examples:
  ropecam simulate lab --out sets/lab --photo-dir ../shared/realdata   # a lab's footage: 60 frames, 4 ms
  ropecam simulate lab-rolling --out sets/lab-paper --paper-exposures  # four sets: 1, 5, 9, 15 ms at 30 FPS
  ropecam simulate rig --out sets/rig                      # 60 frames, 4 ms, 119 FPS (about 10 s)
  ropecam simulate paper --out sets/paper --frames 30      # four sets: 1, 5, 9 and 15 ms
  ropecam simulate rig-soft --out sets/soft --exposure-ms 0.1 --clean --seed 3
  ropecam simulate rig --out sets/b --trajectory sets/rig/trajectory.npz --polarity dark --clamp --scratch
"""


def register(subparsers: Any) -> None:
    """Add the `simulate` sub-command."""
    presets = "\n".join(f"  {name:<11} {text}" for name, text in PRESET_HELP.items())
    options = "\n".join(f"  {key:<27} {unit}, {allowed}: {meaning}" for key, unit, allowed, meaning in REALISM_OPTIONS)
    parser = subparsers.add_parser(
        "simulate",
        help="write simulated frame sets (motion-blurred rope frames with ground truth)",
        description="Render a swinging rope through a simulated camera into frame sets with exact ground truth: "
        "the ANCF model gives the motion, the renderer draws the anti-aliased, motion-blurred rope, a sensor "
        "model adds background, vignetting and noise.",
        epilog=EPILOG.format(presets=presets, options=options),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("preset", metavar="PRESET", choices=list(PRESETS), help=f"one of: {', '.join(PRESETS)}")
    parser.add_argument("--out", required=True, type=Path, metavar="DIR", help="folder to write the frame set(s) to")
    parser.add_argument("--frames", type=int, metavar="N", help="frames per exposure time (preset: 60)")
    parser.add_argument(
        "--exposure-ms", type=float, nargs="+", metavar="X", help="exposure time(s) in ms; one set per value"
    )
    parser.add_argument("--seed", type=int, metavar="S", help="seed of background, texture, noise (default 0)")
    parser.add_argument(
        "--first-exposure-ms", type=float, metavar="T", help="start of frame 0's exposure after the release (0)"
    )
    parser.add_argument(
        "--polarity", choices=("bright", "dark"), help="bright rope on dark (default) or dark on bright"
    )
    parser.add_argument(
        "--clean",
        action="store_true",
        help="no noise, uniform background, no vignetting (for accuracy checks of the pipeline)",
    )
    parser.add_argument("--texture", type=float, metavar="A", help="background texture amplitude, relative (0.1)")
    parser.add_argument("--uneven", type=float, metavar="A", help="uneven rope brightness, relative (e.g. 0.3)")
    parser.add_argument(
        "--rope-photo",
        metavar="FILE",
        help="scene.rope_photo: paint the rope with the braid/texture of a real rope photo (relative to --photo-dir)",
    )
    parser.add_argument(
        "--photo-dir",
        metavar="DIR",
        help="scene.photo_dir: folder of the rope photos (default ../shared/realdata, from the current directory)",
    )
    parser.add_argument("--scratch", action="store_true", help="add a static bright scratch on the background")
    parser.add_argument("--clamp", action="store_true", help="add a clamp block over the fixed end")
    camera = parser.add_argument_group("camera and lamps (all off in the rig and paper presets)")
    camera.add_argument(
        "--gamma", type=float, metavar="G", help="sensor.gamma: output code = 255 (light/255)^(1/G), G in [1, 3]"
    )
    camera.add_argument(
        "--sharpen", type=float, metavar="A", help="sensor.sharpen: unsharp-mask amount in [0, 3] (sigma 1 px)"
    )
    camera.add_argument(
        "--jpeg-quality", type=int, metavar="Q", help="sensor.jpeg_quality: JPEG/MJPEG round trip at quality 1-100"
    )
    camera.add_argument(
        "--readout-ms",
        type=float,
        metavar="T",
        help="camera.readout_ms: rolling shutter, the frame readout time T (row r starts r x T / height ms after "
        "row 0; 0: global shutter)",
    )
    camera.add_argument(
        "--flicker", type=float, metavar="A", help="scene.flicker: lamp brightness 1 + A sin(2 pi f t), A in [0, 0.9]"
    )
    camera.add_argument(
        "--flicker-hz", type=float, metavar="F", help="scene.flicker_hz: lamp flicker frequency f (100 on 50 Hz mains)"
    )
    parser.add_argument(
        "--paper-exposures",
        action="store_true",
        help="render the preset's look through the paper's camera and timing: 800x512, 30 FPS, 1/5/9/15 ms",
    )
    parser.add_argument("--config", type=Path, metavar="FILE", help="TOML file overriding any preset value")
    parser.add_argument(
        "--trajectory", type=Path, metavar="FILE", help="use a saved trajectory (.npz) instead of solving the model"
    )
    parser.add_argument(
        "--calibration-views",
        type=int,
        default=0,
        metavar="N",
        help="also write a calibration set into DIR/calibration: N checkerboard views (50 recommended) through the "
        "same camera, plus boards lying in the motion plane, with the true camera and plane in truth.json",
    )
    declare_outputs(parser, "out")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    parser.set_defaults(func=run)


def _overrides(args: argparse.Namespace) -> dict[str, Any]:
    overrides: dict[str, Any] = {}
    scene: dict[str, Any] = {}
    if args.frames is not None:
        overrides["frames"] = args.frames
    if args.exposure_ms is not None:
        overrides["exposure_ms"] = list(args.exposure_ms)
    if args.seed is not None:
        overrides["seed"] = args.seed
    if args.first_exposure_ms is not None:
        overrides["first_exposure_s"] = args.first_exposure_ms / 1000.0
    if args.clean:
        scene.update(background_variation=0.0, vignetting=0.0, texture=0.0)
        overrides["sensor"] = {"read_noise_dn": 0.0, "gain_dn_per_electron": 0.0}
    if args.polarity is not None:
        scene["polarity"] = args.polarity
    if args.texture is not None:
        scene["texture"] = args.texture
    if args.uneven is not None:
        scene["rope_unevenness"] = args.uneven
    if args.scratch:
        scene["scratch"] = True
    if args.clamp:
        scene["clamp"] = True
    sensor = overrides.setdefault("sensor", {})
    for key in ("gamma", "sharpen", "jpeg_quality"):
        if getattr(args, key) is not None:
            sensor[key] = getattr(args, key)
    if not sensor:
        del overrides["sensor"]
    if args.rope_photo is not None:
        scene["rope_photo"] = args.rope_photo
    if args.photo_dir is not None:
        scene["photo_dir"] = args.photo_dir
    if args.flicker is not None:
        scene["flicker"] = args.flicker
    if args.flicker_hz is not None:
        scene["flicker_hz"] = args.flicker_hz
    if args.readout_ms is not None:
        overrides["camera"] = {"readout_ms": args.readout_ms}
    if scene:
        overrides["scene"] = scene
    return overrides


def run(args: argparse.Namespace) -> int:
    """Run `ropecam simulate`; returns the exit code."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from ropecam.host.model.trajectory import Trajectory
    from ropecam.host.sim.config import merge_overrides
    from ropecam.host.sim.dynamics import solve_trajectory
    from ropecam.host.sim.generate import check_inputs, frameset_paths, write_framesets
    from ropecam.host.sim.presets import preset, with_paper_timing
    from ropecam.shared.config import read_toml

    _check_calibration_request(args)  # before minutes of model solving and rendering
    console = Console(stderr=True, quiet=args.quiet, soft_wrap=True)
    config = preset(args.preset)
    if args.paper_exposures:
        config = with_paper_timing(config)
    if args.config is not None:
        config = merge_overrides(config, read_toml(args.config), where=str(args.config))
    config = merge_overrides(config, _overrides(args), where="command line")
    check_inputs(config)  # a missing photo fails before the model is solved and before anything is written

    if args.trajectory is not None:
        trajectory = Trajectory.load(args.trajectory)
        console.print(
            f"trajectory: {args.trajectory} ({trajectory.duration_s:.3f} s, {trajectory.n_elements} elements)"
        )
    else:
        columns = (TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed:.2f}/{task.total:.2f} s"))
        with Progress(*columns, console=console, disable=args.quiet, transient=True) as bar:
            model_s = config.model_solver().duration_s
            task = bar.add_task(f"ANCF model, {config.solver.elements} elements", total=model_s)
            trajectory = solve_trajectory(config, lambda t_s: bar.update(task, completed=min(t_s, model_s)))
        console.print(f"model solved: {trajectory.duration_s:.3f} s of motion")

    paths = dict(frameset_paths(args.out, config.exposure_ms))
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, disable=args.quiet) as bar:
        tasks = {ms: bar.add_task(f"{ms:g} ms -> {paths[ms]}", total=config.frames) for ms in config.exposure_ms}

        def progress(exposure_ms: float, done: int, total: int) -> None:
            bar.update(tasks[exposure_ms], completed=done, total=total)

        source = None if args.trajectory is None else str(args.trajectory)
        summaries = write_framesets(
            config, trajectory, args.out, overwrite=args.force, progress=progress, trajectory_source=source
        )
    for summary in summaries:
        note = f", rope leaves the image in {summary.frames_out_of_view} frames" if summary.frames_out_of_view else ""
        console.print(
            f"{summary.path}: {summary.frames} frames, {summary.exposure_us} us, rope {summary.width_px:.2f} px wide, "
            f"up to {summary.subframes_max} sub-frames, {summary.seconds:.1f} s{note}"
        )
    if args.calibration_views:
        _write_calibration(config, args, console)
    sys.stderr.flush()
    return 0


def _check_calibration_request(args: argparse.Namespace) -> None:
    """Refuse a bad --calibration-views or an existing calibration set without --force."""
    from ropecam.shared.errors import ConfigError, UsageError

    if not args.calibration_views:
        return
    if args.calibration_views < 4:
        raise ConfigError(f"--calibration-views must be 0 (none) or >= 4, got {args.calibration_views}")
    folder = args.out / "calibration"
    if (folder / "truth.json").exists() and not args.force:
        raise UsageError(f"{folder}: a calibration set exists already (use --force to replace it)")


def _write_calibration(config: Any, args: argparse.Namespace, console: Any) -> None:
    """Render the calibration set through the preset's camera and motion plane."""
    from ropecam.host.sim.boards import make_calibration_set, write_calibration_set
    from ropecam.shared.errors import ConfigError

    _check_calibration_request(args)  # again: the folder may have appeared while the frame sets were rendered
    folder = args.out / "calibration"
    with console.status(f"rendering {args.calibration_views} calibration views -> {folder}"):
        try:
            calib = make_calibration_set(
                camera=config.camera.camera_model(),
                n_views=args.calibration_views,
                seed=config.seed,
                plane_pose=config.camera.plane_pose(),
            )
        except ValueError as exc:
            raise ConfigError(f"cannot place the calibration boards for preset {config.preset!r}: {exc}") from exc
        write_calibration_set(calib, folder)
    console.print(f"{folder}: {len(calib.views)} views, plane.png + {len(calib.extra_plane_views)} more plane views")
