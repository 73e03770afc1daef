"""Accuracy of the device pipeline against ground truth: the paper's Fig. 9/11 as a table and a plot.

For each exposure time and method it runs the pipeline over a sequence of frames with known centrelines and
reports: tip error (mean, p95, max) of the rope at the start and at the end of the exposure, the mean distance of
the true centreline to ours (curve error), the share of frames put in the right time order (among frames whose tip
moves >= 2 px during the exposure) and the share of frames with a result.

Ground truth comes from the synthetic renderer (default; `ropecam.device.capture.synthetic`) or from simulator
frame sets (``--frameset DIR``, repeatable; uses ``truth.npz``: ``begin_px``/``end_px`` (F, S, 2) in (u, v)).

    python tools/evaluate.py accuracy [--exposures-ms 1 5 9 15] [--methods blur_split paper centerline]
                                  [--frames 24] [--frameset DIR ...] [--fixed-end auto|truth]
                                  [--plot fig.png] [--json]

``--fixed-end truth`` gives the pipeline the true fixed end, to compare the methods without the automatic
fixed-end search. The "shapes by" column counts which method produced the shapes (``paper`` reports the
centreline where it finds no two segmentation points; ``blur_split`` its static fallback).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline.config import METHODS, PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam_tools.cli import UsageError
from ropecam_tools.truth_metrics import point_to_polyline, resample

RIG = SyntheticRope(
    width=640, height=400, fixed_uv=(320.4, 30.7), length_px=300.0, diameter_px=3.0, amplitude_rad=0.6,
    period_s=1.3, bend=0.3, fps=119.0, exposure_us=4000, noise_dn=2.0, phase_rad=1.2,
)  # fmt: skip


def synthetic_sequence(exposure_ms: float, frames: int) -> list[tuple[np.ndarray, int, float, np.ndarray, np.ndarray]]:
    """Frames and truth (u, v) of the synthetic rig at one exposure."""
    rope = replace(RIG, exposure_us=round(exposure_ms * 1000))
    return [(f.image, f.t_ns, float(f.exposure_us), f.begin_uv, f.end_uv) for f in rope.frames(frames)]


def frameset_sequence(path: str, frames: int) -> list[tuple[np.ndarray, int, float, np.ndarray, np.ndarray]]:
    """Frames and truth of a simulator frame set."""
    from ropecam.device.capture.frameset import FrameSet

    fs = FrameSet(path)
    truth = fs.truth()
    if truth is None:
        raise SystemExit(f"{path}: no truth.npz")
    out = []
    for position in range(min(frames, len(fs))):
        rec = fs.records[position]
        out.append((fs.read(position), rec.t_ns, float(rec.exposure_us), truth["begin_px"][position],
                    truth["end_px"][position]))  # fmt: skip
    return out


def truth_fixed_end(path: str) -> tuple[float, float]:
    """The fixed end (u, v) px recorded in a frame set's truth.npz."""
    from ropecam.device.capture.frameset import FrameSet

    truth = FrameSet(path).truth()
    if truth is None or "fixed_end_px" not in truth:
        raise SystemExit(f"{path}: no fixed_end_px in truth.npz (needed by --fixed-end truth)")
    u, v = (float(x) for x in truth["fixed_end_px"])
    return u, v


def evaluate(sequence: list, method: str, fixed_uv: tuple[float, float] | None = None) -> dict[str, Any]:
    """Run `method` over `sequence` (fixed end found by the pipeline, or `fixed_uv`); return the error statistics."""
    height, width = sequence[0][0].shape
    pipeline = Pipeline(PipelineConfig(method=method, fixed_end_uv=fixed_uv), (width, height))
    tip_errors, curve_errors, order_ok, results, methods = [], [], [], 0, {}
    for index, (image, t_ns, exposure_us, begin_uv, end_uv) in enumerate(sequence):
        r = pipeline.process(image, index, t_ns, exposure_us)
        if r.begin is None or r.end is None:
            continue
        results += 1
        name = "none" if r.method is None else r.method.name
        methods[name] = methods.get(name, 0) + 1
        ours_b = r.begin[:, ::-1].astype(np.float64)  # (u, v)
        ours_e = r.end[:, ::-1].astype(np.float64)
        tip_errors.append(np.hypot(*(ours_b[-1] - begin_uv[-1])))
        tip_errors.append(np.hypot(*(ours_e[-1] - end_uv[-1])))
        for ours, true in ((ours_b, begin_uv), (ours_e, end_uv)):
            curve_errors.append(float(point_to_polyline(resample(true, 100), ours).mean()))
        if np.hypot(*(end_uv[-1] - begin_uv[-1])) >= 2.0:
            right = np.hypot(*(ours_b[-1] - begin_uv[-1])) + np.hypot(*(ours_e[-1] - end_uv[-1]))
            wrong = np.hypot(*(ours_b[-1] - end_uv[-1])) + np.hypot(*(ours_e[-1] - begin_uv[-1]))
            order_ok.append(right <= wrong)
    tips = np.array(tip_errors) if tip_errors else np.array([np.nan])
    begin_tips, end_tips = (tips[0::2], tips[1::2]) if tip_errors else (tips, tips)
    return {
        "method": method,
        "frames": len(sequence),
        "result_rate": results / len(sequence),
        "tip_mean_px": float(np.mean(tips)),
        "tip_p95_px": float(np.percentile(tips, 95)),
        "tip_max_px": float(np.max(tips)),
        "tip_begin_mean_px": float(np.mean(begin_tips)),
        "tip_begin_p95_px": float(np.percentile(begin_tips, 95)),
        "tip_end_mean_px": float(np.mean(end_tips)),
        "tip_end_p95_px": float(np.percentile(end_tips, 95)),
        "curve_mean_px": float(np.mean(curve_errors)) if curve_errors else float("nan"),
        "order_right": float(np.mean(order_ok)) if order_ok else float("nan"),
        "order_frames": len(order_ok),
        "methods_used": methods,
    }


def build_sequences(
    framesets: list[str] | None, exposures_ms: list[float], frames: int, fixed_end: str
) -> list[tuple[str, float, list, tuple[float, float] | None]]:
    """The inputs of an evaluation: (label, exposure ms, frames with truth, fixed end or None) per simulator frame set,
    or per exposure of the synthetic renderer when no frame set is given; ``fixed_end="truth"`` gives the true one."""
    sequences = []
    if framesets:
        for path in framesets:
            seq = frameset_sequence(path, frames)
            fixed = truth_fixed_end(path) if fixed_end == "truth" else None
            sequences.append((input_label(path), seq[0][2] / 1000.0, seq, fixed))
    else:
        fixed = (float(RIG.fixed_uv[0]), float(RIG.fixed_uv[1])) if fixed_end == "truth" else None
        for exposure in exposures_ms:
            sequences.append(("synthetic", exposure, synthetic_sequence(exposure, frames), fixed))
    return sequences


def input_label(path: str) -> str:
    """A short, readable name of a frame set: its folder, with the parent when that says more (paper/exposure_1ms)."""
    parts = Path(path).resolve().parts
    return "/".join(parts[-2:]) if parts[-1].startswith("exposure") else parts[-1]


def print_table(rows: list[dict[str, Any]]) -> None:
    """The full table: one row per input and method (the paper's Fig. 9/11 in numbers)."""
    width = max(12, *(len(r["input"]) for r in rows))
    print(f"{'input':{width}s} {'exp ms':>6s} {'method':10s} {'tip mean':>8s} {'tip p95':>8s} {'tip max':>8s} "
          f"{'begin':>11s} {'end':>11s} {'curve':>6s} {'order':>6s} {'result':>6s}  shapes by")  # fmt: skip
    print(f"{'':{width}s} {'':6s} {'':10s} {'(px)':>8s} {'(px)':>8s} {'(px)':>8s} {'mean/p95':>11s} "
          f"{'mean/p95':>11s} {'(px)':>6s} {'(%)':>6s} {'(%)':>6s}")  # fmt: skip
    for r in rows:
        used = ", ".join(f"{k} {v}" for k, v in sorted(r["methods_used"].items(), key=lambda kv: -kv[1]))
        print(f"{r['input']:{width}s} {r['exposure_ms']:6.1f} {r['method']:10s} {r['tip_mean_px']:8.2f} "
              f"{r['tip_p95_px']:8.2f} {r['tip_max_px']:8.2f} "
              f"{r['tip_begin_mean_px']:5.2f}/{r['tip_begin_p95_px']:<5.2f} "
              f"{r['tip_end_mean_px']:5.2f}/{r['tip_end_p95_px']:<5.2f} "
              f"{r['curve_mean_px']:6.2f} "
              f"{100 * r['order_right']:6.0f} {100 * r['result_rate']:6.0f}  {used}")  # fmt: skip


def plot(path: str, rows: list[dict[str, Any]], methods: list[str]) -> None:
    """Tip error (mean, bar to p95) and curve error against exposure, one line per method and family of inputs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colours = {"blur_split": "tab:orange", "paper": "tab:blue", "centerline": "tab:green", "static": "tab:gray"}
    fig, (ax_tip, ax_curve) = plt.subplots(1, 2, figsize=(12, 5.4))
    families = sorted({r["input"].split("/")[0] if "/" in r["input"] else r["input"] for r in rows})
    markers = dict(zip(families, "osD^v<>ph", strict=False))
    for number, method in enumerate(methods):
        colour = colours.get(method)
        shift = 0.15 * (number - (len(methods) - 1) / 2)  # side by side: the p95 bars do not hide each other
        for family in families:
            pts = sorted(
                (r["exposure_ms"], r["tip_mean_px"], r["tip_p95_px"], r["curve_mean_px"])
                for r in rows
                if r["method"] == method and (r["input"].split("/")[0] if "/" in r["input"] else r["input"]) == family
            )
            if not pts:
                continue
            x = np.array([p[0] for p in pts]) + shift
            mean = np.array([p[1] for p in pts])
            p95 = np.array([p[2] for p in pts])
            label = method if len(families) == 1 else f"{method} ({family} preset)"
            ax_tip.errorbar(x, mean, yerr=[np.zeros_like(mean), np.maximum(p95 - mean, 0)], marker=markers[family],
                            color=colour, capsize=3, label=label)  # fmt: skip
            ax_curve.plot(x, [p[3] for p in pts], marker=markers[family], color=colour, label=label)
    for ax in (ax_tip, ax_curve):
        ax.set_yscale("log")
        ax.set_xlabel("exposure time (ms)")
        ax.grid(True, which="both", alpha=0.3)
    ax_tip.set_ylabel("tip error (px): mean, bar up to p95")
    ax_tip.set_title("Tip error against exposure (cf. the paper's Fig. 9/11)")
    ax_curve.set_ylabel("mean distance, true centreline to ours (px)")
    ax_curve.set_title("Curve error against exposure")
    handles, labels = ax_tip.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 3), fontsize=8)
    fig.tight_layout(rect=(0, 0.04 + 0.035 * ((len(labels) + 2) // 3), 1, 1))
    fig.savefig(path, dpi=120)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--exposures-ms", type=float, nargs="+", default=[1.0, 5.0, 9.0, 15.0],
                        help="synthetic exposures when no --frameset is given (default 1 5 9 15)")  # fmt: skip
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=["blur_split", "paper", "centerline"])
    parser.add_argument("--frames", type=int, default=24, help="frames per sequence (default 24)")
    parser.add_argument(
        "--frameset", action="extend", nargs="+", help="simulator frame set(s) instead of synthetic frames"
    )
    parser.add_argument("--fixed-end", choices=("auto", "truth"), default="auto",
                        help="find the fixed end (default, as the device does) or take it from the truth")  # fmt: skip
    parser.add_argument("--plot", help="write the tip-error-vs-exposure plot (PNG) here")
    parser.add_argument("--json", action="store_true", help="print JSON rows")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    if args.frames < 1:
        raise UsageError(f"--frames must be >= 1, got {args.frames}")
    sequences = build_sequences(args.frameset, args.exposures_ms, args.frames, args.fixed_end)
    rows = []
    for number, (name, exposure, seq, fixed) in enumerate(sequences, 1):
        print(f"[{number}/{len(sequences)}] {name}: {exposure:g} ms, {len(seq)} frames", file=sys.stderr, flush=True)
        for method in args.methods:
            row = {"input": name, "exposure_ms": exposure, "fixed_end": args.fixed_end, **evaluate(seq, method, fixed)}
            rows.append(row)
            if args.json:
                print(json.dumps(row), flush=True)
    if not args.json:
        print_table(rows)
    if args.plot:
        plot(args.plot, rows, args.methods)
        print(f"plot written to {args.plot}", file=sys.stderr)
    return 0
