"""Acceptance 7 of #19: `ropecam-device setup` on a frame set's first seconds, then the pipeline with the written
device.toml (no hand-set key) measured against the set's truth.

    python tools/evaluate.py setup SET [SET ...] --out DIR [--seconds 2] [--frames N] [--json]

For each simulator frame set (with ``truth.npz``; e.g. ``ropecam simulate lab --out sets/lab --frames 240
--photo-dir ../shared/realdata``, seed 0: the tuning seed set) it writes ``DIR/<set>.toml`` (with its mask and
overlay PNGs; the set's true plane calibration is written as ``DIR/<set>_plane.yaml`` and given to setup and to
the measurement, as a lab's device has one, unless --no-plane) and prints one row: what setup decided, or why it
refused, and the per-frame truth metrics of the default method with that config (`truth_metrics.summarise`: tip
mean/p95, centreline mean, material points, missing, silent, time order). Every figure is on the simulated scene
named in its row.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of the setup evaluation."""
    parser.add_argument("sets", nargs="+", type=Path, metavar="SET", help="simulator frame sets (with truth.npz)")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="folder for the device.toml files")
    parser.add_argument("--seconds", type=float, default=2.0, help="seconds setup decides from (default 2)")
    parser.add_argument("--frames", type=int, metavar="N", help="frames measured with the config (default all)")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    parser.add_argument("--no-plane", action="store_true",
                        help="set up without the plane calibration (default: the set's true plane as plane.yaml, "
                        "as a lab's device has one)")  # fmt: skip


def _row(frameset: Path, out: Path, seconds: float, frames: int | None, plane: bool = True) -> dict[str, Any]:
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.setup import run_setup
    from ropecam.shared.config import from_mapping, read_toml
    from ropecam.shared.errors import RopecamError
    from ropecam_tools.truth_metrics import frameset_camera, measure_frameset, summarise

    toml = out / f"{frameset.name}.toml"
    for stale in (toml, toml.with_name(toml.stem + "_mask.png"), toml.with_name(toml.stem + "_overlay.png")):
        stale.unlink(missing_ok=True)
    row: dict[str, Any] = {"scene": frameset.name}
    plane_file = None
    if plane:
        from ropecam.device.capture.frameset import FrameSet
        from ropecam.host.calibration.files import write_plane

        plane_file = out / f"{frameset.name}_plane.yaml"
        write_plane(plane_file, *frameset_camera(FrameSet(frameset).meta))
    try:
        run_setup(str(frameset), toml, seconds=seconds, plane_file=plane_file)
    except RopecamError as exc:
        row["setup"] = f"refused: {exc}"
        return row
    table = read_toml(toml).get("pipeline", {})
    row["setup"] = {k: v for k, v in table.items() if k not in ("rope_length_m", "material_points_m")}
    config = from_mapping(PipelineConfig, table, where=str(toml))
    row.update(summarise(measure_frameset(frameset, "blur_split", frames, plane=plane, config=config)))
    return row


def run(args: argparse.Namespace) -> int:
    """Run setup and the measurement on each set; print the rows."""
    args.out.mkdir(parents=True, exist_ok=True)
    rows = [_row(s, args.out, args.seconds, args.frames, not args.no_plane) for s in args.sets]
    if args.json:
        print(json.dumps(rows, indent=1, default=str))
        return 0
    print(
        "| scene | setup | tip mean px | tip p95 px | centreline mean px | material mm "
        "| missing % | flagged % | silent % | order % |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        if isinstance(row["setup"], str):
            print(f"| {row['scene']} | {row['setup']} | | | | | | | | |")
            continue
        decided = ", ".join(f"{k}={v}" for k, v in row["setup"].items())
        cells = [row[k] for k in ("tip_mean_px", "tip_p95_px", "curve_mean_px", "material_mean_mm")]
        cells += [row[k] for k in ("missing_pct", "flagged_pct", "silent_pct", "order_right_pct")]
        text = " | ".join("-" if isinstance(c, float) and math.isnan(c) else f"{c:.2f}" for c in cells)
        print(f"| {row['scene']} | {decided} | {text} |")
    return 0
