"""The shape kernels allocate nothing: under NUMBA_NRT_STATS=1 a call allocates once per array argument only."""

from __future__ import annotations

import json
import os
import subprocess
import sys

SNIPPET = """
import json
import numpy as np
from numba.core.runtime import rtsys
from ropecam.shared.protocol._kernels import (
    apply_corrections, chain_bytes, distances_to_polyline, fit_bspline, fit_spline_with_corrections, read_chain,
    relative_positions, sample_bspline, bspline_sample_table, sample_with_table, fit_work_size,
    write_spline_body,
)
pts = np.random.default_rng(0).random((50, 2)); t = np.linspace(0, 1, 50); out = np.empty(50)
w4 = np.empty(4); wn = np.empty((8, 8)); c = np.empty((8, 2)); o = np.empty((30, 2))
cq = np.zeros((6, 2), dtype=np.int64); origin = np.zeros(2, dtype=np.int64); index = np.empty(50, dtype=np.int64)
offsets = np.empty((50, 2), dtype=np.int64); stats = np.empty(2); s1 = np.empty((50, 2)); s2 = np.empty((50, 2))
c6 = np.empty((6, 2)); body = np.empty(512, dtype=np.uint8)
first = np.empty(50, dtype=np.int64); table = np.empty((50, 4)); bspline_sample_table(6, first, table)
changed = np.zeros(51, dtype=np.int64); work = np.empty(fit_work_size(50, 6))
calls = {
    "distances_to_polyline": (lambda: distances_to_polyline(pts, t, pts, 6, out), 4),
    "fit_bspline": (lambda: fit_bspline(pts, t, 6, w4, wn, c), 5),
    "sample_bspline": (lambda: sample_bspline(c, w4, o), 3),
    "relative_positions": (lambda: relative_positions(pts, out), 2),
    "bspline_sample_table": (lambda: bspline_sample_table(6, first, table), 2),
    "sample_with_table": (lambda: sample_with_table(c6, first, table, s1), 4),
    "chain_bytes": (lambda: chain_bytes(cq), 1),
    "fit_spline_with_corrections": (
        lambda: fit_spline_with_corrections(
            pts, t, 6, 8, 0.05, 3, origin, first, table, work, changed, cq, index, offsets, stats
        ),
        11,
    ),
    "write_spline_body": (lambda: write_spline_body(cq, origin.reshape(1, 2), index[:3], offsets[:3], body), 5),
    "read_chain": (lambda: read_chain(body, 0, 1 << 22, cq), 2),
    "apply_corrections": (lambda: apply_corrections(body, 0, 3, 1 << 22, 6, s1), 2),
}
result = {}
for name, (call, arrays) in calls.items():
    call()
    before = rtsys.get_allocation_stats().alloc
    call()
    result[name] = [rtsys.get_allocation_stats().alloc - before, arrays]
print(json.dumps(result))
"""


def test_kernels_allocate_only_their_argument_wrappers() -> None:
    env = {**os.environ, "NUMBA_NRT_STATS": "1"}
    env.pop("NUMBA_DISABLE_JIT", None)
    done = subprocess.run([sys.executable, "-c", SNIPPET], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    for name, (allocations, arrays) in json.loads(done.stdout.strip().splitlines()[-1]).items():
        assert allocations == arrays, name
