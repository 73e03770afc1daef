"""The speed tools end to end on a few synthetic rig frames (subprocesses): they hook the pipeline's kernels and
stages by name, so a renamed or fused kernel silently breaks them unless they run. No timing is asserted."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parents[2] / "tools"


def _run(script: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(TOOLS / script), *args], capture_output=True, text=True, timeout=600, check=False
    )


@pytest.mark.slow
def test_bench_device_reports_the_ratio_and_no_allocations() -> None:
    done = _run("bench_device.py", "--frames", "3", "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.splitlines()[-1])
    assert report["frames"] == 3 and report["image_size"] == [1024, 544]
    assert report["statuses"] == {"OK": 3}
    assert report["pipeline_median_us"] > 0 and report["canny_median_us"] > 0
    assert math.isclose(report["ratio"], report["pipeline_median_us"] / report["canny_median_us"])
    assert report["roi_frames"] >= 3  # the timed frames are measured in their band
    assert report["nrt_extra_allocations_per_frame"] == 0 and report["nrt_leaked"] == 0


@pytest.mark.slow
def test_bench_roi_kernels_records_the_bands_and_replays_every_kernel() -> None:
    done = _run("bench_roi_kernels.py", "--frames", "5", "--repeat", "1")
    assert done.returncode == 0, done.stderr
    built = re.search(r"(\d+) edge-stage calls .* (\d+) bands built", done.stdout)
    assert built and int(built.group(1)) >= 2 and int(built.group(2)) >= 2, done.stdout
    times = dict(re.findall(r"^(.+?)\s+(\S+) us", done.stdout, re.MULTILINE))
    assert "band (band_stage)" in times and "edges (detect_edges)" in times, done.stdout
    assert all(math.isfinite(float(value)) and float(value) > 0 for value in times.values()), times


@pytest.mark.slow
def test_bench_trace_replays_the_bands_and_times_the_trace_parts() -> None:
    done = _run("bench_trace.py", "--frames", "4", "--repeat", "1", "--parts")
    assert done.returncode == 0, done.stderr
    times = dict(re.findall(r"^  (\S.*?)\s+(\S+) us$", done.stdout, re.MULTILINE))
    parts = ("first_listed + trace_closed", "keep_traced", "refine_inner", "trace_rope")
    assert all(name in times for name in parts), done.stdout
    assert all(math.isfinite(float(times[name])) and float(times[name]) > 0 for name in parts), times
