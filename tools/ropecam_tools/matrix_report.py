"""The robustness matrix's outputs: Markdown tables, CSV and JSON of every figure, an HTML page with plots."""

from __future__ import annotations

import csv
import html
import json
import math
from pathlib import Path
from typing import Any

from ropecam_tools.matrix_design import IDEAL_PRESET, Scene

__all__ = ["rows_of", "sections", "write_outputs", "write_reports"]

COLUMNS = (
    ("tip_mean_px", "tip mean (px)", 2),
    ("tip_p95_px", "tip p95 (px)", 2),
    ("curve_mean_px", "centreline mean (px)", 2),
    ("material_mean_mm", "material pt (mm)", 2),
    ("missing_pct", "missing %", 0),
    ("flagged_pct", "flagged %", 0),
    ("silent_pct", "silent %", 0),
    ("order_right_pct", "order right %", 0),
    ("pipeline_ms", "ms/frame", 1),
)
SEG_POINTS = (
    ("start_begin", "start point, begin of exposure"),
    ("start_end", "start point, end of exposure"),
    ("tip_begin", "endpoint, begin of exposure"),
    ("tip_end", "endpoint, end of exposure"),
)
"""The paper's four segmentation points (its Table 4): each shape's fixed-end point and free end."""
PAPER_TABLE4 = {"start_begin": (0.8708, 4.9825), "start_end": (1.3870, 5.5254), "tip_begin": (1.4109, 1.7232),
                "tip_end": (1.9651, 6.4363)}  # fmt: skip
"""The paper's Table 4 (mean, max px): 200 real frames of its rig (1.5 m, 119 FPS, 4 ms) against manual labels."""
COLOURS = {"blur_split": "tab:orange", "paper": "tab:blue", "centerline": "tab:green"}
SCOPE = (
    "All figures are measured on simulated frame sets against the simulator's exact ground truth (the scene of each "
    "row is named); the paper's figures are against manual labels on real frames of its rig and are not the same "
    "measurement."
)


def rows_of(scenes: list[Scene], measured: dict[str, dict]) -> list[dict[str, Any]]:
    """One flat row per scene and method (scenes sharing a frame set share its figures)."""
    rows = []
    for scene in scenes:
        result = measured.get(scene.key)
        if result is None:
            continue
        for method, cell in result["methods"].items():
            row = {"section": scene.section, "scene": scene.label, "preset": scene.preset,
                   "exposure_ms": scene.exposure_ms, "factor": scene.factor, "value": scene.value,
                   "scene_key": scene.key, "method": method, **cell["summary"],
                   "method_wall_s": cell["wall_s"], "method_cpu_s": cell["cpu_s"],
                   "render_wall_s": result["timings"]["render_wall_s"]}  # fmt: skip
            if "setup" in result["timings"]:
                row["setup"] = result["timings"]["setup"]
            rows.append(row)
    return rows


def _fmt(value: Any, digits: int) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    return f"{value:.{digits}f}"


def _table(rows: list[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    header = ["scene", "method", *(title for _, title, _ in COLUMNS)]
    body = [[r["scene"], r["method"], *(_fmt(r[key], d) for key, _, d in COLUMNS)] for r in rows]
    return header, body


def _seg_table(rows: list[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    header = ["scene", "method", *(f"{title}: mean / max (px)" for _, title in SEG_POINTS)]
    body = [[r["scene"], r["method"], *(f"{_fmt(r[f'{k}_mean_px'], 2)} / {_fmt(r[f'{k}_max_px'], 2)}"
                                        for k, _ in SEG_POINTS)] for r in rows]  # fmt: skip
    body.append(["paper's rig, real frames, manual labels (its Table 4)", "paper (published)",
                 *(f"{PAPER_TABLE4[k][0]:.2f} / {PAPER_TABLE4[k][1]:.2f}" for k, _ in SEG_POINTS)])  # fmt: skip
    return header, body


def _md(header: list[str], body: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in body]
    return "\n".join(lines)


def _html_table(header: list[str], body: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    cells = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in body)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{cells}</tbody></table>"


def sections(rows: list[dict[str, Any]], run_info: dict[str, Any]) -> list[tuple[str, str, Any]]:
    """The report's parts in order: (title, text, table) with table (header, body) or None."""
    by = {s: [r for r in rows if r["section"] == s] for s in ("presets", "factors", "pairs", "paper")}
    parts: list[tuple[str, str, Any]] = []
    if by["presets"]:
        parts.append(("Presets", "Each simulator preset as it renders by default (its own exposure times).",
                      _table(by["presets"])))  # fmt: skip
    if by["factors"]:
        text = (f"The ideal scene (preset `{IDEAL_PRESET}` without background non-uniformity, vignetting, texture or "
                "noise: a bright 2.5 px rope, 185 DN over a 25 DN plate, 4 ms at 119 FPS) with one factor changed at a "
                "time; each factor's first row is the ideal scene.")  # fmt: skip
        parts.append(("One factor at a time", text, _table(by["factors"])))
    if by["pairs"]:
        parts.append(("Held-out pairs (validation set only)", "Two factors at once on the ideal scene.",
                      _table(by["pairs"])))  # fmt: skip
    if by["paper"]:
        text = (
            "The `paper` preset at the paper's exposure times (1, 5, 9, 15 ms at 30 FPS, 800x512), and each lab "
            "preset's look through the paper's camera, rope and timing (`ropecam simulate PRESET --paper-exposures`): "
            "tip error against exposure for each method (cf. the paper's Fig. 9 and Fig. 11, which are on the "
            "paper's own simulation, whose rope and camera the `paper` preset has)."
        )
        parts.append(("Paper exposures: tip error (Fig. 9/11)", text, _table(by["paper"])))
        text = (
            "Error of each shape's two end points (start point = fixed end, endpoint = free tip), the paper's four "
            "segmentation points (its Table 4), on the same renders. The paper's row is its real rig (1.5 m, "
            "119 FPS, 4 ms) against manual labels: a different scene and a different reference, shown for scale only."
        )
        parts.append(("Segmentation points (the paper's Table 4)", text, _seg_table(by["paper"])))
    return parts


def _markdown(parts: list[tuple[str, str, Any]], run_info: dict[str, Any], plots: list[tuple[str, str]]) -> str:
    out = [f"# Robustness matrix: seed set `{run_info['seed_set']}`, {run_info['frames_per_cell']} frames per cell",
           "", SCOPE, "", _run_line(run_info), ""]  # fmt: skip
    for title, text, table in parts:
        out += [f"## {title}", "", text, "", _md(*table), ""]
    if plots:
        out += ["## Plots", ""] + [f"![{caption}](plots/{name})" for name, caption in plots] + [""]
    return "\n".join(out)


def _run_line(run_info: dict[str, Any]) -> str:
    left = "; ".join(f"{f['name']} ({f['reason']})" for f in run_info["factors_left_out"])
    note = f" Factors left out: {left}." if left else ""
    failed = "; ".join(f"{f['scene']}: {f['error']}" for f in run_info.get("failed_scenes", []))
    note += f" Scenes that failed to render or measure: {failed}." if failed else ""
    setup = run_info.get("setup", "none")
    if setup != "none":
        note += (f" Plane calibration: `--plane {run_info.get('plane', 'lab')}`; setup: `--setup {setup}` (the lab "
                 "scenes are measured with the device.toml `ropecam-device setup` wrote from the cell's own frames; "
                 "what it decided is in matrix.json, `setup` of each row).")  # fmt: skip
    load = ", ".join(f"{x:.1f}" for x in run_info["load_average"])
    return (f"Seed {run_info['seed']}, motion from {run_info['first_exposure_s']:g} s after the release; "
            f"{run_info['workers']} worker(s); whole run {run_info['wall_s'] / 60:.1f} min wall, "
            f"{run_info['cpu_s'] / 60:.1f} min CPU on {run_info['cpus']} cores (load average at the end {load})."
            f"{note}")  # fmt: skip


def write_outputs(
    out: Path, scenes: list[Scene], measured: dict[str, dict], run_info: dict[str, Any], plots: bool = True
) -> list[Path]:
    """Write matrix.json (every figure, per-frame errors, timings), then the reports of `write_reports`."""
    payload = {"run": run_info, "rows": rows_of(scenes, measured),
               "frames": {key: {m: c["frames"] for m, c in r["methods"].items()} for key, r in measured.items()},
               "timings": {key: r["timings"] for key, r in measured.items()}}  # fmt: skip
    json_path = out / "matrix.json"
    json_path.write_text(json.dumps(payload, indent=1, default=str) + "\n", encoding="utf-8")
    return [*write_reports(out, payload["rows"], run_info, plots), json_path]


def write_reports(out: Path, rows: list[dict[str, Any]], run_info: dict[str, Any], plots: bool = True) -> list[Path]:
    """Write matrix.csv, matrix.md and (with `plots`) index.html and plots/*.png into `out` from the rows."""
    csv_path = out / "matrix.csv"
    nested = ("setup", "statuses")  # written as JSON; "setup" only on the rows of set-up scenes
    fields = list(dict.fromkeys(k for row in rows for k in row if k not in nested))
    fields += [k for k in nested if any(k in row for row in rows)]
    with csv_path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        for row in rows:
            writer.writerow({**row, **{k: json.dumps(row[k], default=str) for k in nested if k in row}})
    parts = sections(rows, run_info)
    made: list[tuple[str, str]] = []
    if plots:
        from ropecam_tools.matrix_plots import make_plots

        made = make_plots(out / "plots", rows)
    md_path = out / "matrix.md"
    md_path.write_text(_markdown(parts, run_info, made), encoding="utf-8")
    paths = [md_path, csv_path]
    if plots:
        html_path = out / "index.html"
        body = [f"<h1>Robustness matrix: seed set {html.escape(run_info['seed_set'])}, "
                f"{run_info['frames_per_cell']} frames per cell</h1>", f"<p>{html.escape(SCOPE)}</p>",
                f"<p>{html.escape(_run_line(run_info))}</p>"]  # fmt: skip
        for name, caption in made:
            body.append(f"<figure><img src='plots/{name}' alt='{html.escape(caption)}'>"
                        f"<figcaption>{html.escape(caption)}</figcaption></figure>")  # fmt: skip
        for title, text, table in parts:
            body += [f"<h2>{html.escape(title)}</h2>", f"<p>{html.escape(text)}</p>", _html_table(*table)]
        style = ("body{font-family:sans-serif;max-width:1400px;margin:auto}table{border-collapse:collapse;font-size:"
                 "12px}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}td:first-child{text-align:left}"
                 "img{max-width:100%}")  # fmt: skip
        html_path.write_text(f"<!doctype html><html><head><meta charset='utf-8'><title>ropecam robustness matrix"
                             f"</title><style>{style}</style></head><body>{''.join(body)}</body></html>\n",
                             encoding="utf-8")  # fmt: skip
        paths.insert(0, html_path)
    return paths
