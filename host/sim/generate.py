"""Write simulated frame sets: frames rendered from a rope trajectory, the index, the metadata and the ground truth.

One frame set per exposure time (`write_frameset`); `write_framesets` writes all of a configuration's exposure times
from one trajectory. The ground truth (``truth.npz``, documented in docs/frameset.md) is written when the set is
complete and also when the run stops early (error or Ctrl-C), covering the frames written so far.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.device.capture.frameset import FrameSetWriter, is_frameset, write_atomically
from ropecam.host.calibration.geometry import plane_to_pixels
from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import SimConfig
from ropecam.host.sim.render import RopeRenderer, max_pixels_per_metre
from ropecam.host.sim.rope_photo import PhotoStrip, load_plate_texture, load_rope_strip, rope_texture
from ropecam.host.sim.scene import Sensor, build_scene, rope_levels
from ropecam.host.sim.shutter import flicker_gain
from ropecam.shared.cli import ropecam_version
from ropecam.shared.errors import ConfigError, DataError

__all__ = [
    "TRAJECTORY_FILE",
    "SetSummary",
    "arc_length_samples",
    "check_inputs",
    "frameset_paths",
    "write_frameset",
    "write_framesets",
]

log = logging.getLogger(__name__)

TRAJECTORY_FILE = "trajectory.npz"
MODEL_SOURCE = "ANCF model"
"""`trajectory_source` of a set whose motion was solved from the configuration (``rig.model`` records how)."""
SAMPLE_SPACING_PX = 0.5
"""Largest image distance between consecutive centreline samples (truth and rendering)."""

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class SetSummary:
    """What `write_frameset` wrote.

    Attributes
    ----------
    path
        The frame set's folder.
    frames
        Frames written.
    exposure_us
        Exposure time of every frame.
    subframes_max
        Largest number of sub-frames averaged for one frame.
    width_px
        Median apparent rope width over the set, pixels.
    frames_out_of_view
        Frames in which part of the rope (at the start or the end of the exposure) lies outside the image.
    seconds
        Wall time spent.
    """

    path: Path
    frames: int
    exposure_us: int
    subframes_max: int
    width_px: float
    frames_out_of_view: int
    seconds: float


@functools.lru_cache(maxsize=4)
def cached_rope_strip(path: str) -> PhotoStrip:
    """Return `load_rope_strip(path)`, read once per process (a preset's exposures share it)."""
    return load_rope_strip(path)


def check_inputs(config: SimConfig) -> None:
    """Read the files the configuration names (rope and plate photos) so that a missing one fails before any work.

    Raises
    ------
    ConfigError
        A file is missing or unusable (naming the key and the path).
    """
    photo = config.scene.rope_photo_path
    if photo is not None:
        cached_rope_strip(str(photo))
    plate = config.scene.plate_photo_path
    if plate is not None:
        load_plate_texture(plate, (64, 64))


def frameset_paths(out: str | Path, exposure_ms: tuple[float, ...]) -> list[tuple[float, Path]]:
    """Return (exposure_ms, folder) pairs: `out` itself for one exposure, ``out/exposure_<ms>ms`` for several."""
    out = Path(out)
    if len(exposure_ms) == 1:
        return [(exposure_ms[0], out)]
    return [(ms, out / f"exposure_{ms:g}ms") for ms in exposure_ms]


def arc_length_samples(config: SimConfig) -> NDArray[np.float64]:
    """Return the arc lengths (S,) of the centreline samples: uniform, at most `SAMPLE_SPACING_PX` apart in the image.

    The image scale is the largest over the region the rope can reach (a disc of radius L around the fixed end,
    widened by the amplitudes of a prescribed fixed-end motion).
    """
    length = config.rope.length_m
    motion = config.rope.fixed_end_motion
    reach_x, reach_y = length + abs(motion.amplitude_x_m), length + abs(motion.amplitude_y_m)
    scale = max_pixels_per_metre(
        config.camera.camera_model(), config.camera.plane_pose(), (-reach_x, reach_x), (-reach_y, reach_y)
    )
    count = math.ceil(length * scale / SAMPLE_SPACING_PX) + 1
    return np.linspace(0.0, length, count)


def _check_trajectory(config: SimConfig, trajectory: Trajectory, exposure_us: int) -> None:
    if not math.isclose(trajectory.length_m, config.rope.length_m, rel_tol=1e-9):
        raise ConfigError(
            f"the trajectory's rope is {trajectory.length_m} m long but the configuration says rope.length_m = "
            f"{config.rope.length_m} m (set rope.length_m with --config, or use a matching trajectory)"
        )
    last_end_s = _begin_ns(config, config.frames - 1) * 1e-9 + exposure_us * 1e-6 + config.camera.readout_ms * 1e-3
    first_s = config.first_exposure_s
    t0, t1 = float(trajectory.times_s[0]), float(trajectory.times_s[-1])
    if first_s < t0 - 1e-12 or last_end_s > t1 + 1e-9:
        span_s = exposure_us * 1e-6 + config.camera.readout_ms * 1e-3
        available = max(0, math.floor((t1 - span_s - first_s) * config.camera.fps + 1e-9) + 1)
        raise ConfigError(
            f"the trajectory covers {t0:g}..{t1:g} s but {config.frames} frames at {config.camera.fps:g} FPS need "
            f"{first_s:g}..{last_end_s:.6f} s (it holds {available} frames; use fewer frames or a longer trajectory)"
        )


def _begin_ns(config: SimConfig, frame: int) -> int:
    return round((config.first_exposure_s + frame / config.camera.fps) * 1e9)


def _metadata(
    config: SimConfig, exposure_us: int, fixed_end_px: NDArray[np.float64], s_count: int, trajectory_source: str | None
) -> dict[str, Any]:
    camera, rope = config.camera, config.rope
    return {
        "camera": {
            "camera_matrix": camera.camera_model().camera_matrix.tolist(),
            "distortion": list(camera.distortion),
            "image_size": list(camera.image_size),
        },
        "plane": {"rvec": list(camera.plane_rvec), "tvec_m": list(camera.plane_tvec_m)},
        "rig": {
            "source": "ropecam simulate",
            "ropecam_version": ropecam_version(),
            "preset": config.preset,
            "rope_length_m": rope.length_m,
            "rope_diameter_m": rope.diameter_m,
            "render_diameter_m": config.render_diameter_m,
            "polarity": config.scene.polarity,
            "fixed_end_px": fixed_end_px.tolist(),
            "fps": camera.fps,
            "exposure_us": exposure_us,
            "first_exposure_s": config.first_exposure_s,
            "seed": config.seed,
            "edge_sigma_px": camera.edge_sigma_px,
            "centreline_samples": s_count,
            "trajectory": TRAJECTORY_FILE,
            "truth": "truth.npz",
            "config": config.to_dict(),
            "trajectory_source": trajectory_source or MODEL_SOURCE,
            "model": None if trajectory_source else _model_metadata(config),
        },
    }


def _model_metadata(config: SimConfig) -> dict[str, Any]:
    """The ANCF model's configuration as run: ``[rope]`` and ``[solver]`` of ``ropecam model simulate --config``."""
    return {
        "rope": dataclasses.asdict(config.rope),
        "solver": dataclasses.asdict(config.model_solver()),
    }


def _save_trajectory(trajectory: Trajectory, root: Path) -> None:
    write_atomically(root / TRAJECTORY_FILE, trajectory.save, "trajectory")


def write_frameset(
    config: SimConfig,
    trajectory: Trajectory,
    out: str | Path,
    exposure_ms: float,
    overwrite: bool = False,
    progress: Progress | None = None,
    trajectory_source: str | None = None,
) -> SetSummary:
    """Render `config.frames` frames of `trajectory` at one exposure time into a frame set folder.

    Parameters
    ----------
    config
        The rig and the recording (its `exposure_ms` is ignored in favour of `exposure_ms`).
    trajectory
        The rope's motion; must cover every exposure and have the configuration's rope length.
    out
        Folder of the frame set.
    exposure_ms
        Exposure time, milliseconds (rounded to whole microseconds, as the index stores it).
    overwrite
        Replace an existing frame set in `out`.
    progress
        Called as ``progress(frames_done, frames_total)`` after every frame.
    trajectory_source
        Where `trajectory` came from when it was not solved from ``config.rope`` and ``config.model_solver()``
        (e.g. the file it was loaded from). None (solved): the metadata records the model configuration
        (``rig.model``); otherwise it records this text as ``rig.trajectory_source`` and ``rig.model`` is null.

    Returns
    -------
    SetSummary
        What was written.

    Raises
    ------
    ConfigError
        The trajectory does not match the configuration (length, time span).
    DataError
        `out` holds a frame set already (without `overwrite`) or cannot be written.
    """
    started = time.perf_counter()
    out = Path(out)
    exposure_us = round(exposure_ms * 1000.0)
    if exposure_us < 1:
        raise ConfigError(f"exposure_ms must be at least 0.001 ms, got {exposure_ms!r}")
    _check_trajectory(config, trajectory, exposure_us)
    camera = config.camera.camera_model()
    plane = config.camera.plane_pose()
    s_m = arc_length_samples(config)
    levels = rope_levels(config.scene, s_m, config.seed)
    fixed_end_px = plane_to_pixels(np.zeros(2), camera, plane)
    sigma = config.camera.edge_sigma_px
    readout_s = config.camera.readout_ms / 1000.0
    renderer = RopeRenderer(camera, plane, s_m, config.render_diameter_m, levels, sigma, readout_s=readout_s)
    first_m = trajectory.positions([trajectory.times_s[0]], s_m)[0]
    first_px = renderer.project(first_m)
    rope_length_px = float(np.linalg.norm(np.diff(first_px, axis=0), axis=-1).sum())
    width_px = 2.0 * float(np.median(renderer.half_width_px(first_m, first_px)))
    photo = config.scene.rope_photo_path
    if photo is not None:
        strip = cached_rope_strip(str(photo))
        renderer.texture = rope_texture(
            strip, config.scene.rope_photo_contrast, config.render_diameter_m, float(s_m[1] - s_m[0]), width_px
        )
    layers = build_scene(
        config.scene, config.camera.image_size, tuple(fixed_end_px), rope_length_px, width_px, sigma, config.seed
    )
    sensor = Sensor(layers, config.sensor, config.seed)
    metadata = _metadata(config, exposure_us, fixed_end_px, s_m.size, trajectory_source)
    if layers.clamp_box_px is not None:
        metadata["rig"]["clamp_box_px"] = list(layers.clamp_box_px)
    if layers.scratch_px is not None:
        metadata["rig"]["scratch_px"] = list(layers.scratch_px)
    if photo is not None:
        metadata["rig"]["rope_photo"] = str(photo)
    if config.scene.plate_photo_path is not None:
        metadata["rig"]["plate_photo"] = str(config.scene.plate_photo_path)
    metadata["rig"].update(layers.parts)
    rolling = readout_s > 0
    if rolling:
        metadata["rig"]["readout_ms"] = config.camera.readout_ms
    if config.scene.flicker > 0:
        metadata["rig"]["flicker"] = {"amplitude": config.scene.flicker, "frequency_hz": config.scene.flicker_hz}

    truth: dict[str, list[Any]] = {key: [] for key in ("begin_px", "end_px", "begin_m", "end_m", "width_px")}
    truth.update({"t_begin_ns": [], "t_end_ns": [], "subframes": [], "begin_point_t_ns": [], "end_point_t_ns": []})
    width, height = config.camera.image_size
    out_of_view = 0
    with FrameSetWriter(out, config.camera.image_size, config.camera.fps, metadata, overwrite=overwrite) as writer:
        _save_trajectory(trajectory, out)
        try:
            for frame in range(config.frames):
                t_begin_ns = _begin_ns(config, frame)
                t_end_ns = t_begin_ns + exposure_us * 1000
                exposure = renderer.render(trajectory, t_begin_ns * 1e-9, t_end_ns * 1e-9)
                illumination = None
                if config.scene.flicker > 0:
                    illumination = flicker_gain(t_begin_ns * 1e-9 + renderer.row_offsets_s, exposure_us * 1e-6,
                                                config.scene.flicker, config.scene.flicker_hz)  # fmt: skip
                image = sensor.expose(exposure.cover, exposure.signal, frame, illumination)
                writer.add(image, t_begin_ns, exposure_us)
                for key in ("begin_px", "end_px", "begin_m", "end_m"):
                    truth[key].append(getattr(exposure, key).copy())
                truth["width_px"].append(2.0 * float(np.median(exposure.half_width_px)))
                truth["t_begin_ns"].append(t_begin_ns)
                truth["t_end_ns"].append(t_end_ns)
                truth["subframes"].append(exposure.subframes)
                if rolling:
                    truth["begin_point_t_ns"].append(exposure.begin_t_s * 1e9)
                    truth["end_point_t_ns"].append(exposure.end_t_s * 1e9)
                both = np.concatenate([exposure.begin_px, exposure.end_px])
                inside = (both[:, 0] >= -0.5) & (both[:, 0] <= width - 0.5)
                inside &= (both[:, 1] >= -0.5) & (both[:, 1] <= height - 0.5)
                if not inside.all():
                    out_of_view += 1
                if progress is not None:
                    progress(frame + 1, config.frames)
        finally:
            if truth["t_begin_ns"]:
                arrays = _truth_arrays(truth, s_m, fixed_end_px)
                if rolling:
                    arrays["row_offset_ns"] = renderer.row_offsets_s * 1e9
                    arrays["begin_point_t_ns"] = np.stack(truth["begin_point_t_ns"])
                    arrays["end_point_t_ns"] = np.stack(truth["end_point_t_ns"])
                writer.write_truth(arrays)
    if out_of_view:
        log.warning("%s: the rope leaves the image in %d of %d frames", out, out_of_view, config.frames)
    return SetSummary(
        path=out,
        frames=len(truth["t_begin_ns"]),
        exposure_us=exposure_us,
        subframes_max=max(truth["subframes"]),
        width_px=float(np.median(truth["width_px"])),
        frames_out_of_view=out_of_view,
        seconds=time.perf_counter() - started,
    )


def _truth_arrays(
    truth: dict[str, list[Any]], s_m: NDArray[np.float64], fixed_end_px: NDArray[np.float64]
) -> dict[str, NDArray[Any]]:
    arrays: dict[str, NDArray[Any]] = {"s_m": s_m, "fixed_end_px": np.asarray(fixed_end_px, dtype=np.float64)}
    for key in ("begin_px", "end_px", "begin_m", "end_m"):
        arrays[key] = np.stack(truth[key])
    arrays["tip_begin_px"] = arrays["begin_px"][:, -1, :]
    arrays["tip_end_px"] = arrays["end_px"][:, -1, :]
    arrays["tip_begin_m"] = arrays["begin_m"][:, -1, :]
    arrays["tip_end_m"] = arrays["end_m"][:, -1, :]
    arrays["t_begin_ns"] = np.asarray(truth["t_begin_ns"], dtype=np.int64)
    arrays["t_end_ns"] = np.asarray(truth["t_end_ns"], dtype=np.int64)
    arrays["width_px"] = np.asarray(truth["width_px"], dtype=np.float64)
    arrays["subframes"] = np.asarray(truth["subframes"], dtype=np.int32)
    return arrays


def write_framesets(
    config: SimConfig,
    trajectory: Trajectory,
    out: str | Path,
    overwrite: bool = False,
    progress: Callable[[float, int, int], None] | None = None,
    trajectory_source: str | None = None,
) -> list[SetSummary]:
    """Write one frame set per exposure time of `config` (folders as `frameset_paths`).

    Parameters
    ----------
    progress
        Called as ``progress(exposure_ms, frames_done, frames_total)`` after every frame.
    trajectory_source
        As `write_frameset`.

    Raises
    ------
    ConfigError, DataError
        As `write_frameset`; checked for every exposure before anything is written.
    """
    paths = frameset_paths(out, config.exposure_ms)
    check_inputs(config)
    for exposure_ms, _ in paths:
        _check_trajectory(config, trajectory, round(exposure_ms * 1000.0))
    if not overwrite:
        existing = [str(path) for _, path in paths if is_frameset(path)]
        if existing:
            raise DataError(f"{existing[0]}: a frame set exists already (use --overwrite to replace it)")
    summaries = []
    for exposure_ms, path in paths:
        callback = None if progress is None else (lambda done, total, ms=exposure_ms: progress(ms, done, total))
        summaries.append(write_frameset(config, trajectory, path, exposure_ms, overwrite, callback, trajectory_source))
    return summaries
