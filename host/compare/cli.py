"""`ropecam compare`: measured rope motion against the ANCF model, with optional parameter identification."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ropecam.shared.cli import EXIT_OK, EXIT_RUNTIME, declare_outputs

__all__ = ["parse_points", "register"]

EPILOG = """\
examples:
  ropecam compare run.mcap --plane plane.yaml --model rope.toml --out report/          # a monitor recording
  ropecam compare sim/rig --plane plane.yaml --model rope.toml --out report/           # raw frames, measured now
  ropecam-device extract sim/rig --out rig.jsonl
  ropecam compare rig.jsonl --plane plane.yaml --model rope.toml --out report/
  ropecam compare rig.jsonl --plane plane.yaml --model rope.toml --fit ei,damping --out report/
  ropecam compare runs/ --plane plane.yaml --model rope.toml --out reports/            # every run in runs/, Dask
  ropecam compare runs/ --plane plane.yaml --scheduler tcp://10.0.0.5:8786 --out reports/

INPUT is a measurement: an MCAP recording of `ropecam monitor --record` (its rolled parts are read too; --device
picks the device), the JSON-lines output of `ropecam-device extract` (one object per frame, shapes in distorted
pixels), or a raw frame set folder (measured now with the device pipeline; --config gives its [pipeline] settings).
A folder of measurements (*.mcap, *.jsonl, frame set sub-folders) is compared in parallel on Dask (a local cluster
unless --scheduler names one).
The shapes are converted to metres on the motion plane with the calibration (plane.yaml from `ropecam calibrate
plane`, which also holds the camera; --camera overrides it), material points are tracked by arc length with
uniform stretch, and the model (rope.toml as for `ropecam model simulate`) is simulated from the release, whose
time on the device clock is always estimated by least squares. --fit adds model parameters to the fit:
ei (bending stiffness), damping (Kelvin-Voigt time), drag (drag coefficient). The report folder gets PNG plots
(among them x(t) and y(t) of each material point), samples.csv (and samples.parquet with pyarrow: per sample and
material point the measured and model positions in metres, the error, and the velocity measured within the frame
beside the model's), summary.json (also: ropecam version, date, command line, input files with SHA-256) and
index.html (per recording in batch mode, plus an overall summary). An existing non-empty --out needs --force.
"""


def register(subparsers: Any) -> None:
    """Add `ropecam compare` to the command line."""
    parser = subparsers.add_parser(
        "compare",
        help="compare measured rope motion with the ANCF model (and fit its parameters)",
        description=__doc__,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "input", type=Path, help="measurement: run.mcap, extract .jsonl, a frame set folder, or a folder of these"
    )
    parser.add_argument("--plane", type=Path, required=True, help="plane.yaml from `ropecam calibrate plane`")
    parser.add_argument("--camera", type=Path, help="camera.yaml (default: the camera stored in the plane file)")
    parser.add_argument("--model", type=Path, help="rope.toml with [rope] and [solver] (default: the paper's rope)")
    parser.add_argument(
        "--points", help="material points as unstretched arc lengths in m, comma-separated (default: L/4, L/2, 3L/4, L)"
    )
    parser.add_argument("--fit", default="", help="parameters to fit besides t0: any of ei,damping,drag")
    parser.add_argument("--release-time-s", type=float, help="start value of the release time (default: first frame)")
    parser.add_argument("--device", type=int, help="MCAP input: the device id to compare (default: the first seen)")
    parser.add_argument(
        "--config", type=Path, metavar="device.toml", help="frame set input: device config whose [pipeline] to use"
    )
    parser.add_argument("--out", type=Path, required=True, help="report folder (created)")
    parser.add_argument(
        "--no-plots", action="store_true",
        help="leave the PNG plots out of the report (numbers, tables and HTML only; a batch of many runs is faster)",
    )  # fmt: skip
    parser.add_argument("--scheduler", help="batch mode: address of an existing Dask scheduler (default: local)")
    parser.add_argument("--workers", type=int, default=2, help="batch mode: local Dask worker processes (default 2)")
    declare_outputs(parser, "out")
    parser.set_defaults(func=run_compare)


def parse_points(text: str | None) -> list[float] | None:
    """Parse ``--points``: comma-separated arc lengths in m (None when not given).

    Raises
    ------
    ConfigError
        A value is not a number.
    """
    from ropecam.shared.errors import ConfigError

    if not text:
        return None
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise ConfigError(f"--points: expected comma-separated numbers in m, got {text!r}") from exc


def run_compare(args: argparse.Namespace) -> int:
    """Run `ropecam compare` on one file or, for a folder, on every file in it with Dask."""
    from ropecam.host.compare.inputs import find_measurements, is_single_measurement
    from ropecam.host.compare.run import compare_recording
    from ropecam.host.model.cli import load_model_config
    from ropecam.shared.errors import ConfigError

    fit = tuple(name.strip() for name in args.fit.split(",") if name.strip())
    points = parse_points(args.points)
    rope, _ = load_model_config(args.model)
    if points is not None and (not points or any(not 0 <= p <= rope.length_m for p in points)):
        raise ConfigError(f"--points must lie in [0, {rope.length_m}] m (the rope length), got {args.points!r}")
    options = {
        "plane_path": args.plane,
        "camera_path": args.camera,
        "model_path": args.model,
        "points_m": points,
        "fit": fit,
        "release_time_s": args.release_time_s,
        "device_id": args.device,
        "pipeline_config": args.config,
        "command_line": getattr(args, "command_line", None),
        "plots": not args.no_plots,
    }
    if is_single_measurement(args.input):
        numbers = compare_recording(args.input, out=args.out, **options)
        _print_summary(numbers)
        return EXIT_OK if numbers["finite"] else EXIT_RUNTIME
    recordings = find_measurements(args.input)
    from ropecam.host.compare.batch import compare_batch

    results = compare_batch(recordings, args.out, options, scheduler=args.scheduler, workers=args.workers)
    (args.out / "summary.json").write_text(json.dumps(results, indent=2) + "\n")
    failed = [name for name, entry in results.items() if "error" in entry]
    for name, entry in results.items():
        status = entry.get("error") or f"RMS {entry['overall_rms_error_mm']} mm, report {entry['report']}"
        print(f"{name}: {status}")
    print(f"batch summary: {args.out / 'summary.json'}")
    return EXIT_RUNTIME if failed else EXIT_OK


def _print_summary(numbers: dict[str, Any]) -> None:
    rms = ", ".join(
        f"s={s:.3f}: {v}" for s, v in zip(numbers["material_points_s_m"], numbers["rms_error_mm"], strict=True)
    )
    release = f"release time {numbers['release_time_s']:.6f} s"
    if numbers.get("first_sample_time_s") is not None:  # a live recording's clock is the device's uptime
        lead = numbers["first_sample_time_s"] - numbers["release_time_s"]
        release += f" on the recording's clock ({lead:.4f} s before its first frame)"
    print(f"{release}; RMS error per point (mm): {rms}")
    if "fit" in numbers:
        fit = numbers["fit"]
        for name in fit["parameters"]:
            if name != "t0":
                print(f"{name}: {fit['start'][name]:.6g} -> {fit['values'][name]:.6g} ± {fit['std_errors'][name]:.2g}")
    print(f"report: {numbers['report']}")
    sys.stdout.flush()
