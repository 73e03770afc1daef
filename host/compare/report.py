"""The comparison report: labelled plots (PNG), the per-sample table (CSV, Parquet), a summary JSON recording where
the numbers came from (ropecam version, date, command line, input files with their SHA-256), and an HTML page that
links them."""

from __future__ import annotations

import html
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.host.compare.identify import FitResult
from ropecam.host.compare.table import sample_table, write_table
from ropecam.host.compare.tracks import MaterialPointTracks, PointErrors, model_positions, model_velocities
from ropecam.host.model.trajectory import Trajectory
from ropecam.shared.errors import DataError

__all__ = ["Comparison", "write_report"]


@dataclass
class Comparison:
    """Everything a report shows: the measurement, the model at the estimated release time, errors, fits."""

    source: str
    tracks: MaterialPointTracks
    curves_m: list[tuple[float, NDArray[np.float64]]]  # (time s, measured centreline (n, 2) m)
    trajectory: Trajectory
    release_time_s: float
    errors: PointErrors
    fit: FitResult | None = None
    errors_before: PointErrors | None = None
    notes: list[str] = field(default_factory=list)
    provenance: dict[str, Any] = field(default_factory=dict)


def _mm(values: NDArray[np.float64]) -> list[float | None]:
    return [None if not np.isfinite(v) else round(float(v) * 1e3, 4) for v in values]


def _finite(values: dict[str, float]) -> dict[str, float | None]:
    """JSON has no NaN or infinity: an undetermined value (e.g. an unidentifiable parameter's error) is null."""
    return {name: (float(v) if np.isfinite(v) else None) for name, v in values.items()}


def summary(comparison: Comparison) -> dict[str, Any]:
    """The numbers of the report as a JSON-ready mapping (lengths in mm, times in s)."""
    c = comparison
    result: dict[str, Any] = {
        "source": c.source,
        "samples": int(c.tracks.times_s.size),
        "measured_samples": int(c.tracks.measured.any(axis=1).sum()),
        "release_time_s": c.release_time_s,
        "first_sample_time_s": float(c.tracks.times_s[0]) if c.tracks.times_s.size else None,
        "material_points_s_m": [float(s) for s in c.tracks.s_m],
        "rms_error_mm": _mm(c.errors.rms_m),
        "rms_error_m": [float(v) if np.isfinite(v) else None for v in c.errors.rms_m],  # unrounded: the table's
        "max_error_mm": _mm(c.errors.max_m),
        "overall_rms_error_mm": _mm(np.array([c.errors.overall_rms_m]))[0],
        "notes": c.notes,
        "table": "samples.csv",
        "provenance": c.provenance,
    }
    if c.fit is not None:
        result["fit"] = {
            "parameters": list(c.fit.names),
            "start": _finite(c.fit.start),
            "values": _finite(c.fit.values),
            "std_errors": _finite(c.fit.std_errors),
            "rms_before_mm": round(c.fit.rms_before_m * 1e3, 4),
            "rms_after_mm": round(c.fit.rms_after_m * 1e3, 4),
            "model_evaluations": c.fit.evaluations,
            "converged": c.fit.success,
            "message": c.fit.message,
        }
    return result


def _plots(c: Comparison, out: Path) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    t = c.tracks.times_s
    seen = c.tracks.point_times_s  # each point at its own time (a rolling shutter's rows)
    assert seen is not None  # set by MaterialPointTracks
    model = model_positions(c.trajectory, c.tracks, c.release_time_s)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]

    fig, ax = plt.subplots(figsize=(7.5, 6), constrained_layout=True)
    for k, s in enumerate(c.tracks.s_m):
        colour = colours[k % len(colours)]
        ax.plot(c.tracks.positions_m[:, k, 0], c.tracks.positions_m[:, k, 1], ".", ms=3, color=colour,
                label=f"measured, s = {s:.3f} m")  # fmt: skip
        ax.plot(model[:, k, 0], model[:, k, 1], "-", lw=1, color=colour, label=f"model, s = {s:.3f} m")
    ax.set_xlabel("x (m, horizontal)")
    ax.set_ylabel("y (m, down)")
    ax.invert_yaxis()
    ax.set_aspect("equal")
    ax.set_title("Material point trajectories: measured (dots) and model (lines)")
    ax.legend(fontsize=7, ncol=2)
    fig.savefig(out / "trajectories.png", dpi=110)
    plt.close(fig)
    written.append(("trajectories.png", "Material point trajectories in the motion plane"))

    fig, ax = plt.subplots(figsize=(9, 4.5), constrained_layout=True)
    for k, s in enumerate(c.tracks.s_m):
        ax.plot(seen[:, k] - c.release_time_s, c.errors.error_m[:, k] * 1e3, ".-", ms=2, lw=0.6, label=f"s = {s:.3f} m")
    ax.set_xlabel(f"time after the fitted release (s; release at {c.release_time_s:.4f} s on the device clock)")
    ax.set_ylabel("position error |measured - model| (mm)")
    ax.set_title("Error against time")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(out / "error_vs_time.png", dpi=110)
    plt.close(fig)
    written.append(("error_vs_time.png", "Position error of each material point against time"))

    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    positions = np.arange(c.tracks.s_m.size)
    ax.bar(positions - 0.2, c.errors.rms_m * 1e3, 0.4, label="RMS")
    ax.bar(positions + 0.2, c.errors.max_m * 1e3, 0.4, label="max")
    if c.errors_before is not None:
        ax.plot(positions - 0.2, c.errors_before.rms_m * 1e3, "kx", ms=9, label="RMS before the fit")
        ax.set_yscale("log")  # before and after differ by orders of magnitude
    for x, value in zip(positions - 0.2, c.errors.rms_m * 1e3, strict=True):
        if np.isfinite(value):
            ax.annotate(f"{value:.3g}", (x, value), ha="center", va="bottom", fontsize=8)
    ax.set_xticks(positions, [f"{s:.3f}" for s in c.tracks.s_m])
    ax.set_xlabel("material point: unstretched arc length s (m)")
    ax.set_ylabel("position error (mm)")
    ax.set_title("Error per material point")
    ax.legend()
    ax.grid(alpha=0.3, axis="y")
    fig.savefig(out / "error_per_point.png", dpi=110)
    plt.close(fig)
    written.append(("error_per_point.png", "RMS and maximum error per material point"))

    fig, axes = plt.subplots(c.tracks.s_m.size, 2, figsize=(10, 2.2 * c.tracks.s_m.size + 0.8), sharex=True,
                             squeeze=False, constrained_layout=True)  # fmt: skip
    dense_t = np.linspace(t[0], c.tracks.last_time_s, max(200, 4 * t.size))

    model_t = np.clip(dense_t - c.release_time_s, c.trajectory.times_s[0], c.trajectory.times_s[-1])
    dense = c.trajectory.positions(model_t, c.tracks.s_m)
    for k, s in enumerate(c.tracks.s_m):
        for axis, name in enumerate(("x (m, horizontal)", "y (m, down)")):
            ax = axes[k, axis]
            ax.plot(seen[:, k] - c.release_time_s, c.tracks.positions_m[:, k, axis], ".", ms=3, label="measured")
            ax.plot(dense_t - c.release_time_s, dense[:, k, axis], "k-", lw=0.8, label="model")
            ax.set_ylabel(f"{name[0]}, s = {s:.3f} m")
            ax.grid(alpha=0.3)
        axes[k, 1].invert_yaxis()
    for axis, name in enumerate(("x (m, horizontal)", "y (m, down; axis downwards)")):
        axes[0, axis].set_title(name)
        axes[-1, axis].set_xlabel("time after the fitted release (s)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Material point coordinates against time: measured (dots) and model (line)")
    fig.savefig(out / "xy_vs_time.png", dpi=110)
    plt.close(fig)
    written.append(("xy_vs_time.png", "x(t) and y(t) of each material point, measured and model"))

    picks = np.linspace(0, len(c.curves_m) - 1, min(6, len(c.curves_m))).astype(int) if c.curves_m else []
    if len(picks):
        fig, axes = plt.subplots(1, len(picks), figsize=(3.2 * len(picks), 3.6), constrained_layout=True)
        axes = np.atleast_1d(axes)
        s_dense = np.linspace(0, c.trajectory.length_m, 101)
        for ax, index in zip(axes, picks, strict=True):
            time_s, curve = c.curves_m[index]
            shape = c.trajectory.positions([np.clip(time_s - c.release_time_s, 0, c.trajectory.times_s[-1])], s_dense)[
                0
            ]
            ax.plot(curve[:, 0], curve[:, 1], "-", lw=2.5, alpha=0.6, label="measured")
            ax.plot(shape[:, 0], shape[:, 1], "k--", lw=1, label="model")
            ax.set_title(f"{time_s - c.release_time_s:.3f} s after release", fontsize=9)
            ax.set_xlabel("x (m)")
            ax.invert_yaxis()
            ax.set_aspect("equal", adjustable="datalim")  # equal panels, limits widened
        axes[0].set_ylabel("y (m, down)")
        axes[0].legend(fontsize=7)
        fig.suptitle("Measured and model rope shapes")
        fig.savefig(out / "shapes.png", dpi=110)
        plt.close(fig)
        written.append(("shapes.png", "Measured and model rope shapes at a few times"))
    return written


def _num(value: float | None) -> str:
    return "–" if value is None else f"{value:.6g}"


def _provenance_html(provenance: dict[str, Any]) -> str:
    if not provenance:
        return ""
    files = "".join(
        f"<tr><td>{html.escape(f['role'])}</td><td>{html.escape(f['path'])}</td><td><code>{f['sha256']}</code></td></tr>"
        for f in provenance.get("files", [])
    )
    return (
        f"<h2>Provenance</h2><p>ropecam {html.escape(str(provenance.get('ropecam_version')))}, "
        f"{html.escape(str(provenance.get('date_utc')))}<br><code>{html.escape(str(provenance.get('command_line')))}"
        f"</code></p><table><tr><th>file</th><th>path</th><th>SHA-256</th></tr>{files}</table>"
    )


def write_report(comparison: Comparison, out: str | Path, plots: bool = True) -> Path:
    """Write plots (unless `plots` is False), ``samples.csv`` (and ``.parquet``), ``summary.json`` and
    ``index.html`` into `out` (created); return the HTML path."""
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        pictures = _plots(comparison, out) if plots else []
        c = comparison
        table = sample_table(
            c.tracks,
            model_positions(c.trajectory, c.tracks, c.release_time_s),
            c.errors.error_m,
            model_velocities(c.trajectory, c.tracks, c.release_time_s),
        )
        tables = write_table(table, out / "samples.csv")
        numbers = summary(comparison)
        (out / "summary.json").write_text(json.dumps(numbers, indent=2, allow_nan=False) + "\n")
    except OSError as exc:
        raise DataError(f"{out}: cannot write the report: {exc}") from exc
    rows = "".join(
        f"<tr><td>{s:.3f}</td><td>{rms}</td><td>{worst}</td></tr>"
        for s, rms, worst in zip(comparison.tracks.s_m, numbers["rms_error_mm"], numbers["max_error_mm"], strict=True)
    )
    fit_html = ""
    if comparison.fit is not None:
        fit = numbers["fit"]
        fit_rows = "".join(
            f"<tr><td>{html.escape(name)}</td><td>{_num(fit['start'][name])}</td><td>{_num(fit['values'][name])}</td>"
            f"<td>{_num(fit['std_errors'][name])}</td></tr>"
            for name in fit["parameters"]
        )
        fit_html = (
            "<h2>Identification</h2><table><tr><th>parameter</th><th>start</th><th>fitted</th><th>std. error</th>"
            f"</tr>{fit_rows}</table><p>RMS error {fit['rms_before_mm']} mm before, {fit['rms_after_mm']} mm after "
            f"({fit['model_evaluations']} model runs; {html.escape(fit['message'])}). Units: ei N m², damping s, "
            "drag coefficient –, t0 s. Standard errors allow for residuals correlated in time (HAC sandwich); "
            "systematic errors of the calibration are not in them.</p>"
        )
    figures = "".join(
        f'<figure><img src="{name}" alt="{html.escape(text)}"><figcaption>{html.escape(text)}</figcaption></figure>'
        for name, text in pictures
    )
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in comparison.notes)
    provenance = _provenance_html(comparison.provenance)
    links = " · ".join(f'<a href="{p.name}">{p.name}</a>' for p in [*tables, Path("summary.json")])
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>ropecam comparison</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:3px 8px;text-align:right}}img{{max-width:100%}}</style></head><body>
<h1>Measurement against the ANCF model</h1>
<p>Source: {html.escape(comparison.source)}. {numbers["measured_samples"]} of {numbers["samples"]} samples measured
(two per frame: exposure start and end). Release time (model t = 0) on the device clock:
{comparison.release_time_s:.6f} s. Overall RMS error {numbers["overall_rms_error_mm"]} mm.</p>
<h2>Error per material point</h2><table><tr><th>s (m)</th><th>RMS (mm)</th><th>max (mm)</th></tr>{rows}</table>
{fit_html}<ul>{notes}</ul>{figures}
<p>Per-sample table in metres (measured and model positions, errors, in-frame and model velocities): {links}</p>
{provenance}</body></html>
"""
    index = out / "index.html"
    index.write_text(page)
    return index
