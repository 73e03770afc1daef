"""tools/evaluate.py harris and accuracy end to end on a few synthetic frames (subprocesses)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from subprocess import CompletedProcess

import pytest

RunTool = Callable[..., CompletedProcess[str]]
"""The `run_tool` fixture (tests/tools/conftest.py)."""


@pytest.mark.slow
def test_harris_scores_harris_and_the_segmentation_points(run_tool: RunTool, tmp_path: Path) -> None:
    figure = tmp_path / "fig7.png"
    done = run_tool("evaluate.py", "harris", "--exposures-ms", "12", "--frames", "3", "--json", "--plot", str(figure))
    assert done.returncode == 0, done.stderr
    rows = {row["detector"]: row for row in map(json.loads, done.stdout.splitlines())}
    assert set(rows) == {"harris", "paper", "blur_split"}
    for row in rows.values():
        assert row["frames"] == 3 and row["exposure_ms"] == 12.0
        assert 0.0 <= row["detected"] <= 1.0
    # The paper's Fig. 7: Harris marks many points along the edges, the segmentation two per frame near the tips.
    assert rows["harris"]["points_per_frame"] > 10 * rows["paper"]["points_per_frame"]
    assert rows["paper"]["points_per_frame"] <= 2.0
    assert rows["harris"]["precision"] < 0.2 < rows["paper"]["precision"]
    assert rows["paper"]["dist_mean_px"] < 3.0
    assert figure.stat().st_size > 10_000 and figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_accuracy_prints_every_method_and_exposure_and_plots(run_tool: RunTool, tmp_path: Path) -> None:
    figure = tmp_path / "fig11.png"
    done = run_tool("evaluate.py", "accuracy", "--exposures-ms", "2", "12", "--frames", "3", "--plot", str(figure))
    assert done.returncode == 0, done.stderr
    lines = [line.split() for line in done.stdout.splitlines()[2:]]
    assert {(line[1], line[2]) for line in lines} == {
        (e, m) for e in ("2.0", "12.0") for m in ("blur_split", "paper", "centerline")
    }
    assert figure.stat().st_size > 10_000


def test_tools_refuse_bad_arguments(run_tool_here: RunTool) -> None:
    done = run_tool_here("evaluate.py", "harris", "--frames", "0")
    assert done.returncode == 2 and "harris: error: --frames must be >= 1, got 0" in done.stderr, done.stderr
    done = run_tool_here("evaluate.py", "accuracy", "--methods", "nonsense")
    assert done.returncode == 2 and "invalid choice" in done.stderr


@pytest.mark.slow
def test_e2e_compares_what_the_daemon_measured_with_the_offline_pipeline(
    run_tool: RunTool, run_tool_here: RunTool, rig_frames: Path
) -> None:
    done = run_tool("evaluate.py", "e2e", "--frameset", str(rig_frames), "--fps", "30", "--start-s", "0.1",
                    "--transports", "udp", "--json")  # fmt: skip
    row = json.loads(done.stdout.splitlines()[-1])
    # Which frames a fresh daemon skips depends on the machine's speed; what it measured never does: every result
    # that arrived equals the offline pipeline's over the same frames, and every frame is accounted for.
    assert row["exit_code"] == 0 and row["sequence_gaps"] == 0, done.stderr
    assert row["received"] == row["equal_to_offline"] >= 1
    assert row["received"] + row["skipped_at_start"] + row["skipped_after_start"] == row["frames"] == 12
    assert done.returncode == (0 if row["skipped_after_start"] == 0 else 1), done.stderr
    too_short = run_tool_here("evaluate.py", "e2e", "--frameset", str(rig_frames), "--fps", "30", "--start-s", "1")
    assert too_short.returncode == 2 and "12 frames last no longer than --start-s 1 s at 30 FPS" in too_short.stderr
