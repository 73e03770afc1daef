"""Zero Numba allocations per frame after warm-up (NUMBA_NRT_STATS=1, in a subprocess).

Passing a NumPy array into a compiled function costs one NRT MemInfo; that is the only NRT allocation allowed per
frame, so the test counts the array arguments of every kernel call (the arrays of a named group, `_kernels.groups`,
each) and asserts the NRT allocation count equals it (and that every allocation is freed).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent(
    """
    import json
    import numpy as np
    from numba.core.runtime import rtsys
    from ropecam.device.capture.synthetic import SyntheticRope
    from ropecam.device.pipeline import _kernels as K
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline

    def arrays(value):
        if isinstance(value, np.ndarray):
            return 1
        return sum(arrays(v) for v in value) if isinstance(value, tuple) else 0

    rope = SyntheticRope(exposure_us=12000, amplitude_rad=0.7, period_s=0.9, diameter_px=3.0, phase_rad=1.2)
    frames = list(rope.frames(24))
    report = {}
    # "steady": the frames after the width, polarity, fixed end and Lc0 are settled (one `steady_frame` call each)
    for method, warm in (("blur_split", 3), ("paper", 3), ("centerline", 3), ("steady", 20)):
        config = PipelineConfig(method="blur_split" if method == "steady" else method)
        pipeline = Pipeline(config, (rope.width, rope.height))
        for f in frames[:warm]:
            pipeline.process(f.image, f.index, f.t_ns, f.exposure_us)
        count = [0]
        called = set()
        originals = {}
        for name in dir(K):
            fn = getattr(K, name)
            if hasattr(fn, "py_func"):
                originals[name] = fn
                def wrapper(*args, _fn=fn, _name=name):
                    called.add(_name)
                    count[0] += arrays(args)
                    return _fn(*args)
                setattr(K, name, wrapper)
        before = rtsys.get_allocation_stats()
        statuses = []
        for f in frames[warm : warm + 4]:
            statuses.append(pipeline.process(f.image, f.index, f.t_ns, f.exposure_us).status.name)
        after = rtsys.get_allocation_stats()
        for name, fn in originals.items():
            setattr(K, name, fn)
        report[method] = {
            "alloc": after.alloc - before.alloc,
            "free": after.free - before.free,
            "array_args": count[0],
            "statuses": statuses,
            "called": sorted(called),
        }
    print(json.dumps(report))
    """
)


def test_no_numba_allocations_per_frame_after_warm_up() -> None:
    env = dict(os.environ, NUMBA_NRT_STATS="1")
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.strip().splitlines()[-1])
    for method, stats in report.items():
        assert stats["array_args"] > 0, method
        assert stats["alloc"] == stats["array_args"], (method, stats)
        assert stats["free"] == stats["alloc"], (method, stats)
    assert set(report["blur_split"]["statuses"]) == {"OK"}
    assert set(report["steady"]["statuses"]) == {"OK"}
    assert "steady_frame" in report["steady"]["called"]
