"""Time `ropecam simulate` on a preset (acceptance: the `rig` preset, 60 frames, in at most 30 s on one core).

Usage::

    python tools/bench.py simulate                  # rig preset, model solved, 3 repeats
    python tools/bench.py simulate --preset rig-soft --repeats 1
    python tools/bench.py simulate --trajectory sets/rig/trajectory.npz   # skip the model

Reports medians over the repeats: the ANCF solve, rendering (projection, sub-frames, rasteriser), the sensor model,
and the whole frame-set write (render + sensor + PNG + truth), plus the total. Everything runs in this process on
one thread (Numba kernels are single-threaded; OpenCV is limited to one thread here). Compilation is excluded by a
warm-up frame before timing.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import cv2

from ropecam.host.model.trajectory import Trajectory
from ropecam.host.sim.config import merge_overrides
from ropecam.host.sim.dynamics import solve_trajectory
from ropecam.host.sim.generate import arc_length_samples, write_frameset
from ropecam.host.sim.presets import preset
from ropecam.host.sim.render import RopeRenderer
from ropecam.host.sim.scene import Sensor, build_scene, rope_levels


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--preset", default="rig")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--trajectory", type=Path, help="use this trajectory instead of solving the model")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    cv2.setNumThreads(1)
    config = merge_overrides(preset(args.preset), {"frames": args.frames})
    exposure_ms = config.exposure_ms[0]

    solve_s: list[float] = []
    render_s: list[float] = []
    sensor_s: list[float] = []
    write_s: list[float] = []
    subframes = 0
    for _ in range(args.repeats):
        started = time.perf_counter()
        trajectory = Trajectory.load(args.trajectory) if args.trajectory else solve_trajectory(config)
        solve_s.append(time.perf_counter() - started)

        camera, plane = config.camera.camera_model(), config.camera.plane_pose()
        s_m = arc_length_samples(config)
        levels = rope_levels(config.scene, s_m, config.seed)
        renderer = RopeRenderer(camera, plane, s_m, config.render_diameter_m, levels, config.camera.edge_sigma_px)
        layers = build_scene(config.scene, config.camera.image_size, (500.0, 80.0), 400.0, 2.5, 0.5, config.seed)
        sensor = Sensor(layers, config.sensor, config.seed)
        renderer.render(trajectory, 0.0, exposure_ms * 1e-3)  # warm-up (kernels are cached; this is I/O-free)
        render_total = sensor_total = 0.0
        subframes = 0
        for frame in range(config.frames):
            t0 = config.first_exposure_s + frame / config.camera.fps
            tick = time.perf_counter()
            exposure = renderer.render(trajectory, t0, t0 + exposure_ms * 1e-3)
            tock = time.perf_counter()
            sensor.expose(exposure.cover, exposure.signal, frame)
            render_total += tock - tick
            sensor_total += time.perf_counter() - tock
            subframes += exposure.subframes
        render_s.append(render_total)
        sensor_s.append(sensor_total)

        with tempfile.TemporaryDirectory() as tmp:
            tick = time.perf_counter()
            write_frameset(config, trajectory, Path(tmp) / "set", exposure_ms)
            write_s.append(time.perf_counter() - tick)

    def med(values: list[float]) -> float:
        return statistics.median(values)

    width, height = config.camera.image_size
    print(f"preset {args.preset}: {config.frames} frames {width}x{height}, {exposure_ms:g} ms, "
          f"{config.camera.fps:g} FPS, {subframes} sub-frames in all, median of {args.repeats}")  # fmt: skip
    source = (
        "trajectory file load"
        if args.trajectory
        else f"ANCF solve ({config.model_solver().duration_s:.3f} s of motion)"
    )
    print(f"  {source:<40} {med(solve_s):7.2f} s")
    print(f"  {'render (project, sub-frames, rasterise)':<40} {med(render_s):7.2f} s")
    print(f"  {'sensor model':<40} {med(sensor_s):7.2f} s")
    print(f"  {'write_frameset (render+sensor+PNG+truth)':<40} {med(write_s):7.2f} s")
    total = med(solve_s) + med(write_s)
    print(f"  {'total (solve + write_frameset)':<40} {total:7.2f} s   (acceptance: <= 30 s)")
    return 0 if total <= 30.0 else 1
