"""Plots of the robustness matrix (small matplotlib PNGs): presets, each factor, the paper's Fig. 9/11 and Table 4."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ropecam_tools.matrix_design import FACTORS

__all__ = ["make_plots"]

COLOURS = {"blur_split": "tab:orange", "paper": "tab:blue", "centerline": "tab:green"}
DPI = 80
SEG_POINTS = (("start_begin", "start, begin"), ("start_end", "start, end"), ("tip_begin", "tip, begin"),
              ("tip_end", "tip, end"))  # fmt: skip


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _plain_log(ax: Any) -> None:
    """Log y axis with plain numbers (0.5, 1, 3) rather than powers of ten."""
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

    ax.set_yscale("log")
    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 3.0)))
    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.yaxis.set_minor_formatter(NullFormatter())


def _floor(values: list[float]) -> list[float]:
    """Log axes: NaN stays NaN, zero becomes 0.01."""
    return [v if math.isnan(v) else max(v, 0.01) for v in values]


def _methods(rows: list[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(r["method"] for r in rows))


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in text).strip("_")


def _bars(path: Path, rows: list[dict[str, Any]], title: str) -> None:
    plt = _plt()
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    methods = _methods(rows)
    fig, (ax_tip, ax_bad) = plt.subplots(1, 2, figsize=(11, 3.6))
    x = np.arange(len(scenes))
    width = 0.8 / max(len(methods), 1)
    for number, method in enumerate(methods):
        got = {r["scene"]: r for r in rows if r["method"] == method}
        tip = _floor([got[s]["tip_p95_px"] if s in got else math.nan for s in scenes])
        bad = [got[s]["silent_pct"] + got[s]["missing_pct"] if s in got else math.nan for s in scenes]
        shift = (number - (len(methods) - 1) / 2) * width
        ax_tip.bar(x + shift, tip, width, color=COLOURS.get(method), label=method)
        ax_bad.bar(x + shift, bad, width, color=COLOURS.get(method), label=method)
    _plain_log(ax_tip)
    ax_tip.axhline(3.0, color="k", lw=0.8, ls="--")
    ax_tip.set_ylabel("tip error p95 (px)")
    ax_bad.set_ylabel("silent + missing (% of frames)")
    ax_bad.set_ylim(0, 100)
    for ax in (ax_tip, ax_bad):
        ax.set_xticks(x, scenes, rotation=30, ha="right", fontsize=8)
        ax.grid(True, axis="y", alpha=0.3)
    ax_tip.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _factor(path: Path, rows: list[dict[str, Any]], name: str, unit: str) -> None:
    plt = _plt()
    values = list(dict.fromkeys(repr(r["value"]) for r in rows))
    labels = [r["value"] for r in rows if r["method"] == rows[0]["method"]]
    numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in labels)
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.0))
    for method in _methods(rows):
        got = {repr(r["value"]): r for r in rows if r["method"] == method}
        xs = [got[v]["value"] for v in values if v in got] if numeric else list(range(len(values)))
        order = np.argsort(xs) if numeric else np.arange(len(xs))
        series = [got[v] for v in values if v in got]
        series = [series[i] for i in order]
        xs = [xs[i] for i in order]
        colour = COLOURS.get(method)
        axes[0].plot(xs, _floor([r["tip_p95_px"] for r in series]), "o-", color=colour, label=method)
        axes[1].plot(xs, _floor([r["curve_mean_px"] for r in series]), "o-", color=colour, label=method)
        axes[2].plot(xs, [r["silent_pct"] for r in series], "o-", color=colour, label=f"{method} silent")
        axes[2].plot(xs, [r["missing_pct"] for r in series], "x:", color=colour, label=f"{method} missing")
    for ax, ylabel, limit in ((axes[0], "tip p95 (px)", 3.0), (axes[1], "centreline mean (px)", 1.0)):
        _plain_log(ax)
        ax.axhline(limit, color="k", lw=0.8, ls="--")
        ax.set_ylabel(ylabel)
    axes[2].set_ylabel("% of frames")
    axes[2].set_ylim(-2, 102)
    for ax in axes:
        ax.set_xlabel(f"{name} ({unit})" if unit else name)
        ax.grid(True, alpha=0.3)
        if not numeric:
            ax.set_xticks(range(len(values)), [str(v) for v in labels])
    axes[0].legend(fontsize=7)
    axes[2].legend(fontsize=6, ncol=2)
    fig.suptitle(f"{name}: ideal scene (rig preset, clean) with only this factor changed", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _overview(path: Path, rows: list[dict[str, Any]], key: str, ylabel: str, log: bool, limit: float | None) -> None:
    """One small panel per factor: `key` against the factor's value, one line per method."""
    plt = _plt()
    names = list(dict.fromkeys(r["factor"] for r in rows))
    columns = 4
    lines = math.ceil(len(names) / columns)
    fig, axes = plt.subplots(lines, columns, figsize=(11, 2.0 * lines), squeeze=False)
    units = {f.name: f.unit for f in FACTORS}
    for ax, name in zip(axes.flat, names, strict=False):
        got = [r for r in rows if r["factor"] == name]
        values = list(dict.fromkeys(repr(r["value"]) for r in got))
        shown = [next(r["value"] for r in got if repr(r["value"]) == v) for v in values]
        numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in shown)
        order = sorted(range(len(values)), key=lambda i: shown[i]) if numeric else list(range(len(values)))
        for method in _methods(got):
            by_value = {repr(r["value"]): r for r in got if r["method"] == method}
            xs = [shown[i] if numeric else i for i in order]
            ys = [by_value[values[i]][key] if values[i] in by_value else math.nan for i in order]
            ax.plot(xs, _floor(ys) if log else ys, "o-", ms=3, color=COLOURS.get(method), label=method)
        if not numeric:
            ax.set_xticks(range(len(values)), [str(shown[i]) for i in order], fontsize=7)
        if log:
            _plain_log(ax)
        if limit is not None:
            ax.axhline(limit, color="k", lw=0.7, ls="--")
        unit = units.get(name, "")
        ax.set_title(f"{name} ({unit})" if unit else name, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    for ax in list(axes.flat)[len(names) :]:
        ax.set_visible(False)
    axes[0][0].legend(fontsize=6)
    fig.suptitle(f"{ylabel}: ideal scene (rig preset, clean) with one factor changed", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _paper_tips(path: Path, rows: list[dict[str, Any]], scene: str) -> None:
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6), sharey=True)
    methods = _methods(rows)
    for number, method in enumerate(methods):
        got = sorted((r for r in rows if r["method"] == method), key=lambda r: r["exposure_ms"])
        x = np.array([r["exposure_ms"] for r in got]) + 0.2 * (number - (len(methods) - 1) / 2)
        for ax, which in zip(axes, ("tip_begin", "tip_end"), strict=True):
            mean = np.array(_floor([r[f"{which}_mean_px"] for r in got]))
            top = np.array(_floor([r[f"{which}_max_px"] for r in got]))
            ax.errorbar(x, mean, yerr=[np.zeros_like(mean), np.maximum(top - mean, 0)], marker="o", capsize=3,
                        color=COLOURS.get(method), label=method)  # fmt: skip
    for ax, title in zip(axes, ("tip at the start of the exposure", "tip at the end of the exposure"), strict=True):
        ax.set_yscale("log")
        ax.set_xlabel("exposure time (ms)")
        ax.set_title(title, fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("tip error (px): mean, bar to max")
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{scene} (simulated, exact truth): tip error against exposure (cf. the paper's Fig. 9/11)",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _paper_points(path: Path, rows: list[dict[str, Any]], scene: str) -> None:
    plt = _plt()
    exposures = sorted({r["exposure_ms"] for r in rows})
    methods = _methods(rows)
    fig, axes = plt.subplots(1, len(exposures), figsize=(3.0 * len(exposures), 3.2), sharey=True, squeeze=False)
    x = np.arange(len(SEG_POINTS))
    width = 0.8 / max(len(methods), 1)
    for ax, exposure in zip(axes[0], exposures, strict=True):
        for number, method in enumerate(methods):
            got = [r for r in rows if r["method"] == method and r["exposure_ms"] == exposure]
            if not got:
                continue
            mean = _floor([got[0][f"{k}_mean_px"] for k, _ in SEG_POINTS])
            ax.bar(x + (number - (len(methods) - 1) / 2) * width, mean, width, color=COLOURS.get(method),
                   label=method)  # fmt: skip
        ax.set_yscale("log")
        ax.set_title(f"{exposure:g} ms", fontsize=9)
        ax.set_xticks(x, [label for _, label in SEG_POINTS], rotation=30, ha="right", fontsize=8)
        ax.grid(True, axis="y", alpha=0.3)
    axes[0][0].set_ylabel("mean error (px)")
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"{scene} (simulated): segmentation-point errors (cf. the paper's Table 4, real frames)",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def make_plots(folder: Path, rows: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """Write the plots of `rows` into `folder`; return (file name, caption) pairs."""
    folder.mkdir(parents=True, exist_ok=True)
    made = []
    presets = [r for r in rows if r["section"] == "presets"]
    if presets:
        _bars(folder / "presets.png", presets, "Presets (simulated): tip p95 and failed frames per method")
        made.append(("presets.png", "Presets: tip error p95 (dashed: 3 px) and silent + missing frames"))
    units = {f.name: f.unit for f in FACTORS}
    for name in dict.fromkeys(r["factor"] for r in rows if r["section"] == "factors"):
        name_file = f"factor_{_slug(name)}.png"
        _factor(folder / name_file, [r for r in rows if r["section"] == "factors" and r["factor"] == name], name,
                units.get(name, ""))  # fmt: skip
        made.append((name_file, f"Factor {name}: tip p95, centreline error, silent and missing frames"))
    factors = [r for r in rows if r["section"] == "factors"]
    if factors:
        _overview(folder / "factors_tip.png", factors, "tip_p95_px", "tip error p95 (px)", True, 3.0)
        made.append(("factors_tip.png", "All factors: tip error p95 (px; dashed: 3 px)"))
        _overview(folder / "factors_silent.png", factors, "silent_pct", "silent failures (% of frames)", False, None)
        made.append(("factors_silent.png", "All factors: silent failures (% of frames)"))
        _overview(folder / "factors_missing.png", factors, "missing_pct", "missing (% of frames)", False, None)
        made.append(("factors_missing.png", "All factors: frames without shapes (%)"))
    pairs = [r for r in rows if r["section"] == "pairs"]
    if pairs:
        _bars(folder / "pairs.png", pairs, "Held-out pairs of factors (validation set)")
        made.append(("pairs.png", "Held-out pairs: tip error p95 and silent + missing frames"))
    paper = [r for r in rows if r["section"] == "paper"]
    for family in dict.fromkeys(r["preset"] for r in paper):
        got = [r for r in paper if r["preset"] == family]
        scene = family if family == "paper" else f"{family} through the paper's camera"
        _paper_tips(folder / f"paper_tips_{_slug(family)}.png", got, scene)
        made.append((f"paper_tips_{_slug(family)}.png", f"{scene}: tip error against exposure (cf. Fig. 9/11)"))
        _paper_points(folder / f"paper_points_{_slug(family)}.png", got, scene)
        made.append((f"paper_points_{_slug(family)}.png", f"{scene}: segmentation-point errors (cf. Table 4)"))
    return made
