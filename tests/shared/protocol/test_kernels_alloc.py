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
from ropecam.shared.protocol._kernels import distances_to_polyline, fit_bspline, sample_bspline
pts = np.random.default_rng(0).random((50, 2)); t = np.linspace(0, 1, 50); out = np.empty(50)
w4 = np.empty(4); wn = np.empty((8, 8)); c = np.empty((8, 2)); o = np.empty((30, 2))
calls = {
    "distances_to_polyline": (lambda: distances_to_polyline(pts, t, pts, 6, out), 4),
    "fit_bspline": (lambda: fit_bspline(pts, t, 6, w4, wn, c), 5),
    "sample_bspline": (lambda: sample_bspline(c, w4, o), 3),
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
