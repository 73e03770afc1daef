"""Measure every method on every preset and on one scene factor at a time (the robustness matrix).

Renders simulator frame sets with exact ground truth and runs each pipeline method over them, as the device would
(fixed end found automatically, only the rope's length given). Three sections (``--only``):

  presets  every simulator preset at each of its exposure times
  factors  the ideal scene (preset rig without noise, texture or non-uniform light: a 2.5 px bright rope,
           185 DN contrast, 4 ms at 119 FPS) with one factor changed at a time across its range
           (texture, contrast, noise, PSF, rope width, clamp, ...; the list is in docs/robustness.md)
  paper    the paper-exposure renders (1, 5, 9, 15 ms at 30 FPS, 800x512): tip error against exposure
           (the paper's Fig. 9/11) and the segmentation-point error table (its Table 4/5)

Columns per cell (scene x method): tip mean / p95 (px, begin and end tips pooled), centreline mean (px), material-
point error (mm on the motion plane, back-projected with the simulator's true camera: a perfect calibration),
missing % (no begin/end shapes), flagged % (both shapes, but a status that says not to trust them: any status
but OK and NO_BLUR), silent failures % (status OK but tip error > 3 px or centreline error > 1 px),
time order right % (frames whose tip moves >= 2 px), pipeline time per frame (ms, the pipeline's own clock).

Every figure is measured on simulated frames against the simulator's exact truth; the paper's figures are against
manual labels on real frames. The tables say which scene each figure belongs to.

Seed sets: ``--seed-set tuning`` (default) renders seed 0 from the release; ``validation`` renders seed 7919 from
0.25 s after the release and adds held-out pairs of factors. Keep the validation set out of all tuning.

Writes OUT/matrix.md (tables), OUT/matrix.csv and OUT/matrix.json (every figure, per-frame errors, timings),
OUT/index.html with the plots (OUT/plots/*.png). Frame sets are rendered to a temporary folder and deleted unless
--keep-frames (then OUT/framesets/, reused by a later run with the same configuration and frame count).

examples:
  python tools/evaluate.py matrix --out runs/matrix                          # everything, 60 frames per cell
  python tools/evaluate.py matrix --out runs/val --seed-set validation
  python tools/evaluate.py matrix --out runs/tex --only factors --factor texture contrast --frames 30
  python tools/evaluate.py matrix --out runs/p --only presets --preset rig --method blur_split --frames 8
  python tools/evaluate.py matrix --out runs/nc --only presets --preset lab-dark --set scene.clamp=false \
      scene.rod_width_px=0 scene.distractor=false                              # a preset without its clamp
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import asdict
from pathlib import Path
from typing import Any

from ropecam_tools.matrix_design import (
    FACTORS,
    METHODS,
    PAIRS,
    PAPER_PRESETS,
    REALDATA,
    SECTIONS,
    SEED_SETS,
    Scene,
    available_factors,
    build_scenes,
)

MIN_FRAMES = 2
PLANE_CHOICES = ("lab", "all", "none")
SETUP_CHOICES = ("lab", "none")


def uses_plane(scene: Scene, plane: str) -> bool:
    """Whether the pipeline gets the plane calibration on `scene` under ``--plane`` `plane`."""
    return plane == "all" or (plane == "lab" and scene.preset.startswith("lab"))


def uses_setup(scene: Scene, setup: str) -> bool:
    """Whether the pipeline measures `scene` with the config `ropecam-device setup` wrote under ``--setup``."""
    return setup == "lab" and scene.preset.startswith("lab")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the matrix's options to `parser`."""
    parser.add_argument("--out", type=Path, metavar="DIR", help="folder for the tables and plots (required)")
    parser.add_argument(
        "--list", action="store_true", help="print the factor rows and the presets as Markdown, and exit"
    )
    parser.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS), metavar="SECTION",
                        help=f"sections to run: {', '.join(SECTIONS)} (default: all)")  # fmt: skip
    parser.add_argument("--frames", type=int, default=60, metavar="N", help="frames per cell (default 60)")
    parser.add_argument("--workers", type=int, default=2, metavar="N",
                        help="processes rendering and measuring scenes (default 2; 1: no pool)")  # fmt: skip
    parser.add_argument("--seed-set", choices=tuple(SEED_SETS), default="tuning",
                        help="tuning (default) or validation (other seeds and motion, held-out pairs)")  # fmt: skip
    parser.add_argument("--seed", type=int, metavar="S",
                        help="tuning set only: render with seed S instead of the set's (0); the validation set's "
                        "seed is refused (held out)")  # fmt: skip
    parser.add_argument("--first-exposure-s", type=float, metavar="T",
                        help="tuning set only: render the motion from T s after the release instead of the set's "
                        "(0: the rope at rest when the stream starts; e.g. 0.3: already swinging)")  # fmt: skip
    parser.add_argument("--method", nargs="+", choices=METHODS, default=list(METHODS), metavar="M",
                        help=f"methods to measure (default: {' '.join(METHODS)})")  # fmt: skip
    parser.add_argument("--factor", nargs="+", metavar="NAME",
                        help="factor rows to run (default all): " + ", ".join(f.name for f in FACTORS))  # fmt: skip
    parser.add_argument(
        "--preset",
        nargs="+",
        metavar="NAME",
        help="presets for the presets and paper sections (default all; e.g. --only paper --preset lab: "
        "the lab look through the paper's camera only)",
    )
    parser.add_argument("--set", nargs="+", default=[], metavar="KEY=VALUE", dest="settings",
                        help="simulator keys set on every preset and paper scene (TOML values, e.g. "
                        "scene.clamp=false scene.rod_width_px=0); their rows are labelled with them")  # fmt: skip
    parser.add_argument("--photo-dir", type=Path, default=REALDATA, metavar="DIR",
                        help=f"folder of the real rope photographs (default {REALDATA})")  # fmt: skip
    parser.add_argument("--keep-frames", action="store_true",
                        help="keep the rendered frame sets in OUT/framesets (and reuse matching ones)")  # fmt: skip
    parser.add_argument("--plane", choices=PLANE_CHOICES, default="lab",
                        help="give the pipeline the plane calibration (the simulator's true camera and plane, as "
                        "plane.yaml would): lab (default: the lab presets' scenes, as a lab's device would have one), "
                        "all scenes, or none")  # fmt: skip
    parser.add_argument("--setup", choices=SETUP_CHOICES, default="lab",
                        help="measure with the device.toml `ropecam-device setup` writes from the cell's own frames "
                        "(with the plane calibration when the cell has one): lab (default: the lab presets' scenes, "
                        "as a lab's device is set up) or none (a fresh device: every key at its default)")  # fmt: skip
    parser.add_argument("--no-plots", action="store_true", help="write the tables only (no matplotlib)")
    parser.add_argument("--replot", action="store_true",
                        help="measure nothing: rewrite the tables and plots of OUT from OUT/matrix.json")  # fmt: skip


def parse_settings(items: list[str]) -> dict[str, Any]:
    """Parse ``--set`` items ``KEY=VALUE`` (VALUE a TOML value; a bare word is a string) into {dotted key: value}.

    Raises
    ------
    SystemExit
        An item without ``=`` or with an empty key (the message names the item).
    """
    import tomllib

    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip() or not text.strip():
            raise SystemExit(f"matrix --set: expected KEY=VALUE (e.g. scene.clamp=false), got {item!r}")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        out[key.strip()] = value
    return out


def _motion_override(args: argparse.Namespace) -> tuple[int | None, float | None]:
    """The ``--seed`` and ``--first-exposure-s`` given (None: the seed set's).

    Raises
    ------
    SystemExit
        Either given with the validation set, the validation set's seed given, or a negative start.
    """
    seed, start = args.seed, args.first_exposure_s
    if seed is None and start is None:
        return None, None
    if args.seed_set != "tuning":
        raise SystemExit("matrix: --seed and --first-exposure-s render tuning-side scenes; the validation set is "
                         "held out as it is defined (drop --seed-set validation)")  # fmt: skip
    if seed is not None and seed == SEED_SETS["validation"].seed:
        raise SystemExit(f"matrix: --seed {seed} is the validation set's seed (held out): choose another")
    if seed is not None and seed < 0:
        raise SystemExit(f"matrix: --seed must be >= 0, got {seed}")
    if start is not None and not start >= 0.0:
        raise SystemExit(f"matrix: --first-exposure-s must be >= 0 s after the release, got {start}")
    return seed, start


def _config(scene: Scene, frames: int) -> Any:
    from ropecam.host.sim.config import merge_overrides
    from ropecam.host.sim.presets import preset, with_paper_timing

    base = preset(scene.preset)
    if scene.paper_timing:
        base = with_paper_timing(base)
    overrides = {**scene.overrides, "frames": frames}
    return merge_overrides(base, overrides, where=f"matrix scene {scene.label!r}")


def _trajectory_key(config: Any) -> str:
    import hashlib

    text = json.dumps([asdict(config.rope), asdict(config.model_solver())], sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def solve_trajectory(scene: Scene, frames: int, path: str) -> dict[str, Any]:
    """Solve the ANCF model for `scene`'s configuration and save it to `path`; return the timings."""
    from ropecam.host.sim.dynamics import solve_trajectory as solve

    wall, cpu = time.perf_counter(), time.process_time()
    solve(_config(scene, frames)).save(path)
    return {"wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu}


def _reusable(folder: Path, frames: int) -> bool:
    from ropecam.device.capture.frameset import FrameSet, is_frameset

    if not (is_frameset(folder) and (folder / "truth.npz").is_file()):
        return False
    return len(FrameSet(folder)) == frames


def run_scene(
    scene: Scene,
    frames: int,
    methods: tuple[str, ...],
    trajectory: str,
    folder: str | None,
    plane: bool = False,
    setup: bool = False,
) -> dict:
    """Render `scene` (or reuse its kept frame set) and measure every method on it (with the true plane
    calibration when `plane`; with the config `ropecam-device setup` writes from the same frames when `setup`).

    Returns the per-method summaries and per-frame errors, and the wall and CPU seconds of each step (and what
    setup decided, or why it refused: the cell is then measured as a fresh device).
    """
    from ropecam.host.model.trajectory import Trajectory
    from ropecam.host.sim.generate import write_frameset
    from ropecam_tools.truth_metrics import frame_rows, measure_frameset, summarise

    keep = folder is not None
    root = Path(folder) if keep else Path(tempfile.mkdtemp(prefix="ropecam-matrix-"))
    target = root if keep else root / scene.folder
    timings: dict[str, Any] = {"render_reused": False}
    setup_dir: Path | None = None
    try:
        wall, cpu = time.perf_counter(), time.process_time()
        if keep and _reusable(target, frames):
            timings["render_reused"] = True
        else:
            config = _config(scene, frames)
            write_frameset(config, Trajectory.load(trajectory), target, scene.exposure_ms, overwrite=True)
        timings["render_wall_s"] = time.perf_counter() - wall
        timings["render_cpu_s"] = time.process_time() - cpu
        config = None
        if setup:
            wall, cpu = time.perf_counter(), time.process_time()
            setup_dir = Path(tempfile.mkdtemp(prefix="ropecam-setup-"))
            config, timings["setup"] = _set_up(target, setup_dir, plane)
            timings["setup_wall_s"] = time.perf_counter() - wall
            timings["setup_cpu_s"] = time.process_time() - cpu
        results = {}
        for method in methods:
            wall, cpu = time.perf_counter(), time.process_time()
            errors = measure_frameset(target, method, frames, plane=plane, config=config)
            results[method] = {
                "summary": summarise(errors),
                "frames": frame_rows(errors),
                "wall_s": time.perf_counter() - wall,
                "cpu_s": time.process_time() - cpu,
            }
    finally:
        if not keep:
            shutil.rmtree(root, ignore_errors=True)
        if setup_dir is not None:
            shutil.rmtree(setup_dir, ignore_errors=True)
    return {"timings": timings, "methods": results}


def _set_up(frameset: Path, folder: Path, plane: bool) -> tuple[Any, str | dict[str, Any]]:
    """Run `ropecam-device setup` on all of `frameset`'s frames (with its true plane as plane.yaml when `plane`);
    return the config it wrote (None when it refused) and what it decided (or its refusal)."""
    import contextlib
    import io

    from ropecam.device.capture.frameset import FrameSet
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.setup import run_setup
    from ropecam.host.calibration.files import write_plane
    from ropecam.shared.config import from_mapping, read_toml
    from ropecam.shared.errors import RopecamError
    from ropecam_tools.truth_metrics import frameset_camera

    folder.mkdir(parents=True, exist_ok=True)
    plane_file = None
    if plane:
        plane_file = write_plane(folder / "plane.yaml", *frameset_camera(FrameSet(frameset).meta))
    toml = folder / "device.toml"
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            run_setup(str(frameset), toml, seconds=1e6, plane_file=plane_file)
    except RopecamError as exc:
        return None, f"refused: {exc}"
    table = read_toml(toml).get("pipeline", {})
    decided = {k: v for k, v in table.items() if k not in ("plane_file", "static_mask_png")}
    return from_mapping(PipelineConfig, table, where=str(toml)), decided


class _Progress:
    """Cells done / total with an ETA, one line per finished scene on stderr."""

    def __init__(self, total_cells: int, total_scenes: int) -> None:
        self.total_cells, self.total_scenes = total_cells, total_scenes
        self.cells = self.scenes = 0
        self.started = time.perf_counter()

    def step(self, what: str, cells: int) -> None:
        self.cells += cells
        self.scenes += 1
        spent = time.perf_counter() - self.started
        left = spent / self.scenes * (self.total_scenes - self.scenes)
        print(f"[{self.cells}/{self.total_cells} cells, {self.scenes}/{self.total_scenes} scenes, "
              f"{spent / 60:.1f} min, ETA {left / 60:.1f} min] {what}", file=sys.stderr, flush=True)  # fmt: skip


def _executor(workers: int) -> ProcessPoolExecutor | None:
    if workers == 1:
        return None
    import multiprocessing

    # spawn: the workers must not inherit a half-initialised Numba or OpenCV thread pool from this process
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))


def _submit(pool: ProcessPoolExecutor | None, fn: Any, *args: Any) -> Future:
    if pool is not None:
        return pool.submit(fn, *args)
    future: Future = Future()
    try:
        future.set_result(fn(*args))
    except BaseException as exc:  # handed to the caller through the future, as a pool does
        future.set_exception(exc)
    return future


def factor_table(presets_available: tuple[str, ...], photo_dir: Path) -> str:
    """Return the matrix's rows as Markdown: the factor rows (key, values, unit, range, meaning) and the presets."""
    from ropecam.host.sim.presets import preset

    base = preset("rig").to_dict()
    have = {f.name for f in available_factors(base, photo_dir)[0]}
    lines = [
        "| factor | simulator key | values (ideal first) | unit | simulator's range | meaning |",
        "|---|---|---|---|---|---|",
    ]
    for f in FACTORS:
        extra = "".join(f"; with {key} = {value}" for key, value in f.extra)
        values = ", ".join(str(v) for v in f.values)
        missing = "" if f.name in have else " (left out here)"
        lines.append(f"| {f.name}{missing} | `{f.key}`{extra} | {values} | {f.unit} | {f.stated_range} | {f.meaning} |")
    lines += ["", f"Presets: {', '.join(presets_available)}; at the paper's exposures: {', '.join(PAPER_PRESETS)}."]
    pairs = "; ".join(f"{a} = {va} with {b} = {vb}" for (a, va), (b, vb) in PAIRS)
    lines += ["", f"Held-out pairs (validation set only): {pairs}."]
    return "\n".join(lines)


def _replot(out: Path, plots: bool) -> int:
    from ropecam_tools.matrix_report import write_reports

    source = out / "matrix.json"
    try:
        payload = json.loads(source.read_text(encoding="utf-8"))
        rows, run_info = payload["rows"], payload["run"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SystemExit(f"matrix --replot: cannot read {source}: {exc}") from None
    paths = write_reports(out, rows, run_info, plots)
    print(f"wrote {', '.join(str(p) for p in paths)}", file=sys.stderr)
    return 0


def _as_done(pool: ProcessPoolExecutor | None, jobs: dict[str, tuple]) -> Iterator[tuple[str, Future]]:
    """Yield (key, finished future) of each job ``(fn, *args)``: in the pool as they finish, else one at a time."""
    if pool is None:
        for key, (fn, *job_args) in jobs.items():
            yield key, _submit(None, fn, *job_args)
        return
    pending = {pool.submit(fn, *job_args): key for key, (fn, *job_args) in jobs.items()}
    while pending:
        done, _ = wait(pending, return_when=FIRST_COMPLETED)
        for future in done:
            yield pending.pop(future), future


def run(args: argparse.Namespace) -> int:
    """Run the matrix and write its outputs; return the exit code."""
    from ropecam.host.sim.presets import PRESETS, preset, with_paper_timing
    from ropecam_tools.matrix_report import write_outputs

    if args.list:
        print(factor_table(tuple(PRESETS), args.photo_dir))
        return 0
    if args.out is None:
        raise SystemExit("matrix: --out DIR is required")
    if args.replot:
        return _replot(args.out, plots=not args.no_plots)
    if args.frames < MIN_FRAMES:
        raise SystemExit(f"--frames must be >= {MIN_FRAMES}, got {args.frames}")
    if args.workers < 1:
        raise SystemExit(f"--workers must be >= 1, got {args.workers}")
    seed, first_exposure_s = _motion_override(args)
    started_wall = time.perf_counter()
    presets = {name: preset(name).to_dict() for name in PRESETS}
    paper_timed = {
        name: with_paper_timing(preset(name)).to_dict() for name in PAPER_PRESETS if name in PRESETS and name != "paper"
    }
    try:
        scenes, missing = build_scenes(
            presets, args.seed_set, tuple(args.only), None if args.factor is None else tuple(args.factor),
            None if args.preset is None else tuple(args.preset), args.photo_dir.resolve(),
            paper_timed, parse_settings(args.settings), seed, first_exposure_s,
        )  # fmt: skip
    except ValueError as exc:
        raise SystemExit(f"matrix: {exc}") from None
    if not scenes:
        raise SystemExit("matrix: the selection holds no scene (check --only, --factor and --preset)")
    for factor, reason in missing:
        print(f"note: factor {factor.name!r} left out: {reason}", file=sys.stderr)
    methods = tuple(args.method)
    unique: dict[str, Scene] = {}
    for scene in scenes:
        unique.setdefault(scene.key, scene)
    args.out.mkdir(parents=True, exist_ok=True)
    trajectories = args.out / "trajectories"
    trajectories.mkdir(exist_ok=True)
    frames_root = args.out / "framesets" if args.keep_frames else None
    print(f"matrix: {len(scenes)} rows, {len(unique)} scenes to render, {len(unique) * len(methods)} cells "
          f"({len(methods)} methods), {args.frames} frames per cell, seed set {args.seed_set}, "
          f"{args.workers} worker(s) -> {args.out}", file=sys.stderr, flush=True)  # fmt: skip

    pool = _executor(args.workers)
    try:
        by_traj: dict[str, Scene] = {}
        scene_traj: dict[str, str] = {}
        for key, scene in unique.items():
            tkey = _trajectory_key(_config(scene, args.frames))
            by_traj.setdefault(tkey, scene)
            scene_traj[key] = str(trajectories / f"{tkey}.npz")
        solving = {
            tkey: _submit(pool, solve_trajectory, scene, args.frames, str(trajectories / f"{tkey}.npz"))
            for tkey, scene in by_traj.items()
            if not (trajectories / f"{tkey}.npz").is_file()
        }
        model_timings = {}
        for tkey, future in solving.items():
            model_timings[tkey] = future.result()
            print(f"model solved for {by_traj[tkey].label} ({model_timings[tkey]['wall_s']:.1f} s)", file=sys.stderr)
        progress = _Progress(len(unique) * len(methods), len(unique))
        jobs = {}
        for key, scene in unique.items():
            folder = None if frames_root is None else str(frames_root / scene.folder)
            jobs[key] = (
                run_scene, scene, args.frames, methods, scene_traj[key], folder, uses_plane(scene, args.plane),
                uses_setup(scene, args.setup),
            )  # fmt: skip
        measured: dict[str, dict] = {}
        failed: dict[str, str] = {}
        for key, future in _as_done(pool, jobs):
            try:
                measured[key] = future.result()
            except Exception as exc:  # one scene's failure is reported in the tables; the others still run
                failed[key] = f"{type(exc).__name__}: {exc}"
                progress.step(f"{unique[key].label}: FAILED {failed[key]}", len(methods))
                continue
            summary = ", ".join(
                f"{m} p95 {r['summary']['tip_p95_px']:.2f} px" for m, r in measured[key]["methods"].items()
            )
            progress.step(f"{unique[key].label}: {summary}", len(methods))
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    usage_self = resource.getrusage(resource.RUSAGE_SELF)
    usage_children = resource.getrusage(resource.RUSAGE_CHILDREN)
    run_info = {
        "seed_set": args.seed_set,
        "seed": SEED_SETS[args.seed_set].seed if seed is None else seed,
        "first_exposure_s": SEED_SETS[args.seed_set].first_exposure_s if first_exposure_s is None else first_exposure_s,
        "frames_per_cell": args.frames,
        "methods": list(methods),
        "sections": list(args.only),
        "workers": args.workers,
        "plane": args.plane,
        "setup": args.setup,
        "settings": args.settings,
        "wall_s": time.perf_counter() - started_wall,
        "cpu_s": sum(u.ru_utime + u.ru_stime for u in (usage_self, usage_children)),
        "cpus": os.cpu_count(),
        "load_average": os.getloadavg(),
        "factors_left_out": [{"name": f.name, "reason": reason} for f, reason in missing],
        "failed_scenes": [{"scene": unique[key].label, "error": error} for key, error in failed.items()],
        "model": model_timings,
    }
    paths = write_outputs(args.out, scenes, measured, run_info, plots=not args.no_plots)
    print(f"matrix done in {run_info['wall_s'] / 60:.1f} min wall, {run_info['cpu_s'] / 60:.1f} min CPU; "
          f"wrote {', '.join(str(p) for p in paths)}", file=sys.stderr)  # fmt: skip
    if failed:
        print(f"matrix: {len(failed)} scene(s) failed (listed in the report)", file=sys.stderr)
        return 1
    return 0
