"""`ropecam compare`: measured rope motion against the ANCF model, with optional parameter identification."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

__all__ = ["register"]

EPILOG = """\
examples:
  ropecam-device extract sim/rig --out rig.jsonl
  ropecam compare rig.jsonl --plane plane.yaml --model rope.toml --out report/
  ropecam compare rig.jsonl --plane plane.yaml --model rope.toml --fit ei,t0 --out report/

INPUT is the JSON-lines output of `ropecam-device extract` (one object per frame, shapes in distorted pixels).
The shapes are converted to metres on the motion plane with the calibration (plane.yaml from `ropecam calibrate
plane`, which also holds the camera; --camera overrides it), material points are tracked by arc length with
uniform stretch, and the model (rope.toml as for `ropecam model simulate`) is simulated from the release, whose
time on the device clock is always estimated by least squares. --fit adds model parameters to the fit:
ei (bending stiffness), damping (Kelvin-Voigt time), drag (drag coefficient). The report folder gets PNG plots,
summary.json and index.html.
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
    parser.add_argument("input", type=Path, help="measurement: extract JSON lines (.jsonl)")
    parser.add_argument("--plane", type=Path, required=True, help="plane.yaml from `ropecam calibrate plane`")
    parser.add_argument("--camera", type=Path, help="camera.yaml (default: the camera stored in the plane file)")
    parser.add_argument("--model", type=Path, help="rope.toml with [rope] and [solver] (default: the paper's rope)")
    parser.add_argument(
        "--points",
        help="material points as unstretched arc lengths in m, comma-separated (default: L/4, L/2, 3L/4, L)",
    )
    parser.add_argument("--fit", default="", help="parameters to fit besides t0: any of ei,damping,drag")
    parser.add_argument("--release-time-s", type=float, help="start value of the release time (default: first frame)")
    parser.add_argument("--out", type=Path, required=True, help="report folder (created)")
    parser.set_defaults(func=run_compare)


def _parse_points(text: str | None, length_m: float) -> list[float]:
    from ropecam.shared.errors import ConfigError

    if not text:
        return [length_m * f for f in (0.25, 0.5, 0.75, 1.0)]
    try:
        points = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise ConfigError(f"--points: expected comma-separated numbers in m, got {text!r}") from exc
    bad = [p for p in points if not 0 <= p <= length_m]
    if not points or bad:
        raise ConfigError(f"--points must lie in [0, {length_m}] m (the rope length), got {text!r}")
    return points


def run_compare(args: argparse.Namespace) -> int:
    """Run `ropecam compare`."""
    import dataclasses

    import numpy as np

    from ropecam.host.calibration.files import read_camera, read_plane
    from ropecam.host.calibration.geometry import pixels_to_plane
    from ropecam.host.compare.identify import FITTABLE, fit_parameters
    from ropecam.host.compare.measurement import read_extract_jsonl, tracks_from_frames
    from ropecam.host.compare.report import Comparison, write_report
    from ropecam.host.compare.tracks import model_positions, point_errors
    from ropecam.host.model.cli import load_model_config
    from ropecam.host.model.solver import CableModel
    from ropecam.shared.errors import ConfigError

    extra = [name.strip() for name in args.fit.split(",") if name.strip()]
    unknown = [name for name in extra if name not in FITTABLE]
    if unknown:
        raise ConfigError(f"--fit: unknown parameter {unknown[0]!r} (choose from ei, damping, drag)")
    plane_file = read_plane(args.plane)
    camera = read_camera(args.camera).camera if args.camera else plane_file.camera
    plane = plane_file.plane
    rope, solver = load_model_config(args.model)
    points = _parse_points(args.points, rope.length_m)
    frames = read_extract_jsonl(args.input)
    tracks, _ = tracks_from_frames(frames, camera, plane, points, rope.length_m)
    measured = tracks.measured.any(axis=1)
    if not measured.any():
        raise ConfigError(f"{args.input}: no frame has a measured rope shape")
    start_t0 = args.release_time_s if args.release_time_s is not None else float(tracks.times_s[measured][0])
    print(f"{args.input}: {len(frames)} frames, {int(measured.sum())} measured samples; fitting the release time",
          file=sys.stderr)  # fmt: skip

    def report(evaluations: int, rms_m: float) -> None:
        print(f"  model runs {evaluations}: RMS {rms_m * 1e3:.3f} mm", file=sys.stderr, end="\r")

    before = fit_parameters(tracks, rope, solver, names=("t0",), release_time_s=start_t0, progress=report)
    fit = before
    if extra:
        print(f"\nfitting {', '.join(extra)} and t0", file=sys.stderr)
        fit = fit_parameters(tracks, rope, solver, names=(*extra, "t0"), release_time_s=before.release_time_s,
                             progress=report)  # fmt: skip
    print(file=sys.stderr)
    duration = float(tracks.times_s[-1] - fit.release_time_s) + 0.01
    trajectory, _ = CableModel(fit.rope, dataclasses.replace(solver, duration_s=max(duration, 2 * solver.step_s))).run()
    errors = point_errors(tracks, model_positions(trajectory, tracks, fit.release_time_s))
    errors_before = None
    if extra:
        duration_b = float(tracks.times_s[-1] - before.release_time_s) + 0.01
        trajectory_b, _ = CableModel(rope, dataclasses.replace(solver, duration_s=duration_b)).run()
        errors_before = point_errors(tracks, model_positions(trajectory_b, tracks, before.release_time_s))
    curves = [
        (frame.t_begin_ns * 1e-9, pixels_to_plane(frame.begin_px, camera, plane))
        for frame in frames
        if frame.begin_px is not None
    ]
    comparison = Comparison(
        source=str(args.input),
        tracks=tracks,
        curves_m=curves,
        trajectory=trajectory,
        release_time_s=fit.release_time_s,
        errors=errors,
        fit=fit if extra else None,
        errors_before=errors_before,
        notes=[f"model: L = {rope.length_m} m, EI = {fit.rope.bending_stiffness_nm2:.4g} N m², "
               f"{solver.elements} elements, h = {solver.step_s} s"],
    )  # fmt: skip
    index = write_report(comparison, args.out)
    rms = ", ".join(f"s={s:.3f}: {v * 1e3:.3f}" for s, v in zip(tracks.s_m, errors.rms_m, strict=True))
    print(f"release time {fit.release_time_s:.6f} s; RMS error per point (mm): {rms}")
    if extra:
        for name in extra:
            print(f"{name}: {fit.start[name]:.6g} -> {fit.values[name]:.6g} ± {fit.std_errors[name]:.2g}")
    print(f"report: {index}")
    return 0 if np.isfinite(errors.overall_rms_m) else 2
