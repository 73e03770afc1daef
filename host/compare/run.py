"""Compare one recording with the model, end to end: the function both `ropecam compare` and its batch mode run.

It takes only paths and plain values, so Dask can ship it to worker processes.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ropecam.host.calibration.files import read_camera, read_plane
from ropecam.host.calibration.geometry import pixels_to_plane
from ropecam.host.compare.identify import FITTABLE, fit_parameters, model_for_tracks
from ropecam.host.compare.inputs import read_measurement
from ropecam.host.compare.measurement import default_points
from ropecam.host.compare.release import fit_release
from ropecam.host.compare.report import Comparison, summary, write_report
from ropecam.host.compare.tracks import model_positions, point_errors
from ropecam.host.model.cli import load_model_config
from ropecam.host.progress import fit_progress
from ropecam.shared.errors import ConfigError, DataError

__all__ = ["compare_recording", "default_points", "provenance"]


def provenance(command_line: str | None, files: dict[str, Path | None]) -> dict[str, Any]:
    """Where a report's numbers came from: ropecam version, date (UTC), command line, and each input file given
    (role -> path; None: not given) with its SHA-256."""
    import datetime
    import hashlib

    from ropecam.shared.cli import ropecam_version

    entries = []
    for role, path in files.items():
        if path is None:
            continue
        try:
            digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError as exc:
            raise DataError(f"{path}: cannot read the {role} file: {exc.strerror or exc}") from exc
        entries.append({"role": role, "path": str(Path(path).resolve()), "sha256": digest})
    return {
        "ropecam_version": ropecam_version(),
        "date_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "command_line": command_line,
        "files": entries,
    }


def compare_recording(
    measurement: Path,
    plane_path: Path,
    out: Path,
    camera_path: Path | None = None,
    model_path: Path | None = None,
    points_m: Sequence[float] | None = None,
    fit: Sequence[str] = (),
    release_time_s: float | None = None,
    verbose: bool = True,
    device_id: int | None = None,
    pipeline_config: Path | None = None,
    command_line: str | None = None,
    plots: bool = True,
) -> dict[str, Any]:
    """Compare one measurement (see `ropecam.host.compare.inputs`) with the model, write its report into `out`
    (with its PNG plots unless `plots` is False), return the summary mapping. The report records the ropecam
    version, the date, `command_line` and the calibration and model files with their SHA-256.

    Raises
    ------
    ConfigError, DataError, ModelError
        Unknown fit parameters, unreadable files, a model that cannot be simulated (messages name the file).
    """
    unknown = [name for name in fit if name not in FITTABLE or name == "t0"]
    if unknown:
        raise ConfigError(f"--fit: unknown parameter {unknown[0]!r} (choose from ei, damping, drag)")
    plane_file = read_plane(plane_path)
    camera = read_camera(camera_path).camera if camera_path else plane_file.camera
    plane = plane_file.plane
    rope, solver = load_model_config(model_path)
    points = list(points_m) if points_m else default_points(rope.length_m)
    if verbose and Path(measurement).is_dir():
        print(f"{measurement}: measuring the frames with the device pipeline", file=sys.stderr)
    frames = read_measurement(Path(measurement), device_id, pipeline_config)
    report = fit_progress(verbose)
    if verbose:
        print(f"{measurement}: {len(frames)} frames", file=sys.stderr)
    release = fit_release(frames, (camera, plane), rope, solver, points, release_time_s, report, str(measurement))
    tracks, before = release.tracks, release.fit
    result, trajectory, errors, errors_before = before, release.trajectory, release.errors, None
    if fit:
        result = fit_parameters(tracks, rope, solver, names=(*fit, "t0"), release_time_s=before.release_time_s,
                                progress=report)  # fmt: skip
        trajectory = model_for_tracks(result.rope, solver, tracks, result.release_time_s)
        errors, errors_before = point_errors(tracks, model_positions(trajectory, tracks, result.release_time_s)), errors
    if verbose:
        newline = "\n" if sys.stderr.isatty() else ""  # ends the progress line rewritten in place
        print(f"{newline}{int(tracks.measured.any(axis=1).sum())} measured samples", file=sys.stderr)
        for line in release.skipped[:5]:
            print(f"warning: {line}", file=sys.stderr)
        if len(release.skipped) > 5:
            print(f"warning: {len(release.skipped) - 5} more shapes off the plane skipped", file=sys.stderr)
    curves = []  # the shapes the tracks were made of (those of non-OK frames and off the plane are not drawn)
    for f in frames:
        if f.begin_px is not None and f.status == "OK":
            try:
                curves.append((f.t_begin_ns * 1e-9, pixels_to_plane(f.begin_px, camera, plane)))
            except ValueError:
                continue
    comparison = Comparison(
        source=str(measurement),
        tracks=tracks,
        curves_m=curves,
        trajectory=trajectory,
        release_time_s=result.release_time_s,
        errors=errors,
        fit=result if fit else None,
        errors_before=errors_before,
        notes=[
            f"model: L = {rope.length_m} m, EI = {result.rope.bending_stiffness_nm2:.4g} N m², "
            f"{solver.elements} elements, h = {solver.step_s} s",
            *([f"{len(release.skipped)} shapes skipped: they miss the motion plane"] if release.skipped else []),
        ],
    )
    files = {"plane": plane_path, "camera": camera_path, "model": model_path, "pipeline config": pipeline_config}
    comparison.provenance = provenance(command_line, files)
    index = write_report(comparison, out, plots=plots)
    numbers = summary(comparison)
    numbers["report"] = str(index)
    numbers["finite"] = bool(np.isfinite(errors.overall_rms_m))
    return numbers
