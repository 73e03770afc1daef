"""`tools/evaluate.py matrix` end to end on a tiny subset (the rig preset, two methods, four frames), its table
checked against an independent computation of one cell from the kept frame set."""

from __future__ import annotations

import csv
import itertools
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from subprocess import CompletedProcess

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline

TOOLS = Path(__file__).resolve().parents[2] / "tools"
FRAMES = 4

RunTool = Callable[..., CompletedProcess[str]]
"""The `run_tool_here` fixture (tests/tools/conftest.py)."""


def _dense(poly: np.ndarray, step_px: float = 0.005) -> np.ndarray:
    """Points every `step_px` along a polyline (an approximation of the curve, not the tool's projection)."""
    out = [poly[:1]]
    for a, b in itertools.pairwise(poly):
        n = max(int(np.ceil(np.linalg.norm(b - a) / step_px)), 1)
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def _even(poly: np.ndarray, count: int) -> np.ndarray:
    """`count` points evenly spaced in arc length along a polyline."""
    dense = _dense(poly)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    return dense[np.searchsorted(s, np.linspace(0.0, s[-1], count)).clip(0, len(dense) - 1)]


def _by_hand(folder: Path, method: str) -> dict[str, float]:
    fs = FrameSet(folder)
    truth = fs.truth()
    assert truth is not None
    length = fs.meta["rig"]["rope_length_m"]
    pipeline = Pipeline(PipelineConfig(method=method, rope_length_m=length, material_points_m=(length,)), fs.image_size)
    tips, curves, missing, flagged = [], [], 0, 0
    for position, record in enumerate(fs.records):
        result = pipeline.process(fs.read(position), position, record.t_ns, float(record.exposure_us))
        if result.begin is None or result.end is None:
            missing += 1
            continue
        flagged += result.status.name not in ("OK", "NO_BLUR")
        for ours_rc, true_uv in ((result.begin, truth["begin_px"][position]), (result.end, truth["end_px"][position])):
            ours = np.asarray(ours_rc, dtype=np.float64)[:, ::-1]
            tips.append(float(np.linalg.norm(ours[-1] - true_uv[-1])))
            dense = _dense(ours)
            samples = _even(true_uv, 100)
            curves.append(float(np.mean([np.min(np.linalg.norm(dense - p, axis=1)) for p in samples])))
    return {"tip_mean_px": float(np.mean(tips)), "tip_p95_px": float(np.percentile(tips, 95)),
            "curve_mean_px": float(np.mean(curves)), "missing_pct": 100.0 * missing / len(fs.records),
            "flagged_pct": 100.0 * flagged / len(fs.records)}  # fmt: skip


@pytest.mark.slow
def test_matrix_table_matches_an_independent_computation(tmp_path: Path) -> None:
    out = tmp_path / "m"
    done = subprocess.run(
        [sys.executable, str(TOOLS / "evaluate.py"), "matrix", "--out", str(out), "--only", "presets", "--preset",
         "rig", "--method", "blur_split", "centerline", "--frames", str(FRAMES), "--workers", "1", "--keep-frames"],
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "[2/2 cells" in done.stderr
    with (out / "matrix.csv").open(newline="") as handle:
        rows = {row["method"]: row for row in csv.DictReader(handle)}
    assert set(rows) == {"blur_split", "centerline"} and rows["centerline"]["scene"] == "rig"
    folders = list((out / "framesets").iterdir())
    assert len(folders) == 1
    expected = _by_hand(folders[0], "centerline")
    row = rows["centerline"]
    assert int(row["frames"]) == FRAMES
    for key, value in expected.items():
        assert float(row[key]) == pytest.approx(value, abs=0.01), key
    table = (out / "matrix.md").read_text()
    assert f"| rig | centerline | {expected['tip_mean_px']:.2f} | {expected['tip_p95_px']:.2f} |" in table
    report = json.loads((out / "matrix.json").read_text())
    assert report["run"]["frames_per_cell"] == FRAMES and len(report["rows"]) == 2
    assert "plots/presets.png" in (out / "index.html").read_text() and (out / "plots" / "presets.png").is_file()


def test_matrix_refuses_an_unknown_factor(run_tool_here: RunTool, tmp_path: Path) -> None:
    done = run_tool_here("evaluate.py", "matrix", "--out", str(tmp_path / "m"), "--factor", "nosuch")
    assert done.returncode != 0
    assert "unknown factor(s) ['nosuch']" in done.stderr and "texture" in done.stderr
    assert not (tmp_path / "m").exists()


def test_matrix_list_names_every_factor_and_leaves_out_what_it_cannot_render(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, str(TOOLS / "evaluate.py"), "matrix", "--list", "--photo-dir", str(tmp_path / "none")],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    rows = [line for line in done.stdout.splitlines() if line.startswith("| ") and "`" in line]
    names = {row.split("|")[1].strip() for row in rows}
    assert {"texture", "contrast", "read noise", "PSF", "rope width", "clamp", "gamma", "JPEG quality"} <= names
    assert "rope photo texture (left out here)" in names  # no photographs in the given folder
    assert "Held-out pairs (validation set only)" in done.stdout


def _scenes(expression: str) -> object:
    """The JSON value of `expression`, evaluated in a fresh interpreter (the simulator's presets imported there,
    not in the test process) with ``presets`` (every preset's dict) and ``build_scenes`` in scope."""
    code = (
        "import json, sys; sys.path.insert(0, sys.argv[1])\n"
        "from ropecam.host.sim.presets import PRESETS, preset\n"
        "from ropecam_tools.matrix_design import build_scenes\n"
        "presets = {name: preset(name).to_dict() for name in PRESETS}\n"
        f"print(json.dumps({expression}))\n"
    )
    done = subprocess.run([sys.executable, "-c", code, str(TOOLS)], capture_output=True, text=True, timeout=120,
                          check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_the_tuning_set_has_a_late_swing_the_validation_set_does_not() -> None:
    """The tuning set renders `lab` also from 1 s after the release (the whipping, crossing late swing); the
    validation set keeps its definition (other seed, motion from 0.25 s, no late-swing row)."""
    scenes = _scenes(
        "{s: [(c.label, c.overrides['first_exposure_s'], c.overrides['seed'])\n"
        "     for c in build_scenes(presets, s, only=('presets',), preset_names=('lab', 'rig'))[0]]\n"
        " for s in ('tuning', 'validation')}"
    )
    assert scenes["tuning"] == [["rig", 0.0, 0], ["lab", 0.0, 0], ["lab late swing", 1.0, 0]]
    assert scenes["validation"] == [["rig", 0.25, 7919], ["lab", 0.25, 7919]]


def test_a_one_point_shape_is_scored_by_its_distance(monkeypatch: pytest.MonkeyPatch) -> None:
    # a rejected frame's shape may be one point; the matrix once failed the whole scene on it (`lab-dark`)
    monkeypatch.syspath_prepend(str(TOOLS))
    from ropecam_tools.truth_metrics import point_to_polyline

    points = np.array([[0.0, 0.0], [3.0, 4.0]])
    assert point_to_polyline(points, np.array([[0.0, 0.0]])) == pytest.approx([0.0, 5.0])
    assert point_to_polyline(points, np.array([[0.0, 0.0], [0.0, 4.0]])) == pytest.approx([0.0, 3.0])


def test_matrix_renders_another_seed_and_start_on_the_tuning_side_only(tmp_path: Path) -> None:
    """``--seed`` and ``--first-exposure-s`` replace the tuning set's seed and start (a rope already swinging when
    the stream starts); with the validation set, or its seed, they are refused."""
    scenes = _scenes(
        "[(c.label, c.overrides['first_exposure_s'], c.overrides['seed'])\n"
        " for c in build_scenes(presets, 'tuning', only=('factors',), factor_names=('clamp',), seed=3,\n"
        "                       first_exposure_s=0.3)[0]]"
    )
    assert scenes == [["clamp = off", 0.3, 3], ["clamp = on", 0.3, 3]]
    for extra in (["--seed-set", "validation", "--seed", "3"], ["--seed", "7919"], ["--first-exposure-s", "-1"]):
        done = subprocess.run(
            [sys.executable, str(TOOLS / "evaluate.py"), "matrix", "--out", str(tmp_path / "m"), *extra],
            capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip
        assert done.returncode != 0 and "matrix: " in done.stderr, (extra, done.stderr)
        assert not (tmp_path / "m").exists()
