"""Accuracy of the device pipeline against ground truth: the paper's Fig. 9/11 as a table and a plot.

For each exposure time and method it runs the pipeline over a sequence of frames with known centrelines and
reports: tip error (mean, p95, max) of the rope at the start and at the end of the exposure, the mean distance of
the true centreline to ours (curve error), the share of frames put in the right time order (among frames whose tip
moves >= 2 px during the exposure) and the share of frames with a result.

Ground truth comes from the synthetic renderer (default; `ropecam.device.capture.synthetic`) or from simulator
frame sets (``--frameset DIR``, repeatable; uses ``truth.npz``: ``begin_px``/``end_px`` (F, S, 2) in (u, v)).

    python tools/eval_accuracy.py [--exposures-ms 1 5 9 15] [--methods blur_split paper centerline]
                                  [--frames 24] [--frameset DIR ...] [--plot fig.png] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from typing import Any

import numpy as np

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline

RIG = SyntheticRope(
    width=640, height=400, fixed_uv=(320.4, 30.7), length_px=300.0, diameter_px=3.0, amplitude_rad=0.6,
    period_s=1.3, bend=0.3, fps=119.0, exposure_us=4000, noise_dn=2.0, phase_rad=1.2,
)  # fmt: skip


def point_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point (k, 2) to the polyline (m, 2)."""
    a = poly[:-1][None]
    d = (poly[1:] - poly[:-1])[None]
    p = points[:, None]
    t = np.clip(((p - a) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-12), 0.0, 1.0)
    foot = a + t[..., None] * d
    return np.min(np.hypot(*(p - foot).transpose(2, 0, 1)), axis=1)


def resample(poly: np.ndarray, count: int) -> np.ndarray:
    """`count` points at equal arc length along `poly`."""
    seg = np.hypot(*np.diff(poly, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    target = np.linspace(0.0, s[-1], count)
    return np.stack([np.interp(target, s, poly[:, 0]), np.interp(target, s, poly[:, 1])], axis=1)


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


def evaluate(sequence: list, method: str) -> dict[str, Any]:
    """Run `method` over `sequence`; return the error statistics."""
    height, width = sequence[0][0].shape
    pipeline = Pipeline(PipelineConfig(method=method), (width, height))
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
    return {
        "method": method,
        "frames": len(sequence),
        "result_rate": results / len(sequence),
        "tip_mean_px": float(np.mean(tips)),
        "tip_p95_px": float(np.percentile(tips, 95)),
        "tip_max_px": float(np.max(tips)),
        "curve_mean_px": float(np.mean(curve_errors)) if curve_errors else float("nan"),
        "order_right": float(np.mean(order_ok)) if order_ok else float("nan"),
        "order_frames": len(order_ok),
        "methods_used": methods,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--exposures-ms", type=float, nargs="+", default=[1.0, 5.0, 9.0, 15.0])
    parser.add_argument("--methods", nargs="+", default=["blur_split", "paper", "centerline"])
    parser.add_argument("--frames", type=int, default=24, help="frames per sequence (default 24)")
    parser.add_argument(
        "--frameset", action="extend", nargs="+", help="simulator frame set(s) instead of synthetic frames"
    )
    parser.add_argument("--plot", help="write the tip-error-vs-exposure plot (PNG) here")
    parser.add_argument("--json", action="store_true", help="print JSON rows")
    args = parser.parse_args(argv)
    sequences = []
    if args.frameset:
        for path in args.frameset:
            seq = frameset_sequence(path, args.frames)
            sequences.append((path, seq[0][2] / 1000.0, seq))
    else:
        for exposure in args.exposures_ms:
            sequences.append(("synthetic", exposure, synthetic_sequence(exposure, args.frames)))
    rows = []
    for name, exposure, seq in sequences:
        for method in args.methods:
            row = {"input": name, "exposure_ms": exposure, **evaluate(seq, method)}
            rows.append(row)
            if args.json:
                print(json.dumps(row), flush=True)
    if not args.json:
        print(f"{'input':12s} {'exp ms':>6s} {'method':12s} {'tip mean':>8s} {'tip p95':>8s} {'tip max':>8s} "
              f"{'curve':>6s} {'order':>6s} {'result':>6s}  methods used")  # fmt: skip
        for r in rows:
            print(f"{r['input'][-12:]:12s} {r['exposure_ms']:6.1f} {r['method']:12s} {r['tip_mean_px']:8.2f} "
                  f"{r['tip_p95_px']:8.2f} {r['tip_max_px']:8.2f} {r['curve_mean_px']:6.2f} "
                  f"{r['order_right']:6.2f} {r['result_rate']:6.2f}  {r['methods_used']}")  # fmt: skip
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 4))
        for method in args.methods:
            pts = sorted((r["exposure_ms"], r["tip_mean_px"], r["tip_p95_px"]) for r in rows if r["method"] == method)
            ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[[0] * len(pts), [p[2] - p[1] for p in pts]],
                        marker="o", capsize=3, label=method)  # fmt: skip
        ax.set_xlabel("exposure time (ms)")
        ax.set_ylabel("tip error (px): mean, bar to p95")
        ax.set_title("Tip error against exposure (cf. the paper's Fig. 9/11)")
        ax.grid(True, alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
