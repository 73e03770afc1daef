"""Zero Numba allocations per frame after warm-up (NUMBA_NRT_STATS=1, in a subprocess).

Passing a NumPy array into a compiled function costs one NRT MemInfo; that is the only NRT allocation allowed per
frame, so the test counts the array arguments of every kernel call (the arrays of a named group, `_kernels.groups`,
each) and asserts the NRT allocation count equals it (and that every allocation is freed).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import os
import subprocess
import sys
import textwrap
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus, PipelineResult
from ropecam.device.pipeline.split_axis import AxisPolylines
from ropecam.device.pipeline.workspace import SplitBuffers

SCRIPT = textwrap.dedent(
    """
    import json
    import sys
    import numpy as np
    from numba.core.runtime import rtsys
    from ropecam.device.pipeline import _kernels as K
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline

    def arrays(value):
        if isinstance(value, np.ndarray):
            return 1
        return sum(arrays(v) for v in value) if isinstance(value, tuple) else 0

    saved = np.load(sys.argv[1])  # the test's frames: (image, index, t_ns, exposure_us) each
    images = [image.copy() for image in saved["image"]]
    frames = list(zip(images, saved["index"].tolist(), saved["t_ns"].tolist(), saved["exposure_us"].tolist()))
    height, width = frames[0][0].shape
    report = {}
    # "steady": the frames after the width, polarity, fixed end and Lc0 are settled (one `steady_frame` call each)
    for method, warm in (("blur_split", 3), ("paper", 3), ("centerline", 3), ("steady", 20)):
        config = PipelineConfig(method="blur_split" if method == "steady" else method)
        pipeline = Pipeline(config, (width, height))
        for f in frames[:warm]:
            pipeline.process(*f)
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
            statuses.append(pipeline.process(*f).status.name)
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


def test_no_numba_allocations_per_frame_after_warm_up(tmp_path: Path) -> None:
    # Rendered here (the session renders these frames once, `synthetic_frames_rendered_once`), handed over in a file.
    rope = SyntheticRope(exposure_us=12000, amplitude_rad=0.7, period_s=0.9, diameter_px=3.0, phase_rad=1.2)
    frames = list(rope.frames(24))
    saved = tmp_path / "frames.npz"
    np.savez(
        saved,
        image=np.stack([f.image for f in frames]),
        index=np.array([f.index for f in frames]),
        t_ns=np.array([f.t_ns for f in frames], dtype=np.int64),
        exposure_us=np.array([f.exposure_us for f in frames], dtype=np.int64),
    )
    env = dict(os.environ, NUMBA_NRT_STATS="1")
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(saved)], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.strip().splitlines()[-1])
    for method, stats in report.items():
        # A steady frame's calls take no array argument (`steady_frame`, `sample_slice`: tables and a frame slot).
        assert (stats["array_args"] == 0) == (method == "steady"), (method, stats)
        assert stats["alloc"] == stats["array_args"], (method, stats)
        assert stats["free"] == stats["alloc"], (method, stats)
    assert set(report["blur_split"]["statuses"]) == {"OK"}
    assert set(report["steady"]["statuses"]) == {"OK"}
    assert "steady_frame" in report["steady"]["called"]


def _fields(result: PipelineResult) -> dict[str, object]:
    """Every field of `result` but its time, arrays copied (they are views valid until the next call)."""
    return {
        f.name: np.array(value) if isinstance(value, np.ndarray) else copy.copy(value)
        for f in dataclasses.fields(result)
        if f.name != "pipeline_us"
        for value in [getattr(result, f.name)]
    }


def test_a_reused_result_record_gets_the_fields_of_a_new_one() -> None:
    """`Pipeline.process(..., out=record)` fills the one record with what a new record would get, every field of
    every frame, through steady frames, a bad frame, a frame of unknown exposure and a search without a band."""
    rope = SyntheticRope(exposure_us=4000, amplitude_rad=0.6, period_s=0.9, diameter_px=3.0, fps=119.0)
    frames = [(f.image, f.index, f.t_ns, float(f.exposure_us)) for f in rope.frames(26)]
    frames[20] = (frames[20][0][:, :-1], *frames[20][1:])  # the wrong size: BAD_FRAME, the band forgotten
    frames[23] = (*frames[23][:3], 0.0)  # exposure unknown
    new, reused = (Pipeline(PipelineConfig(), (rope.width, rope.height)) for _ in range(2))
    record = PipelineResult(0, 0, 0, FrameStatus.BAD_FRAME)
    statuses = set()
    for image, index, t_ns, exposure_us in frames:
        expected = _fields(new.process(image, index, t_ns, exposure_us))
        assert reused.process(image, index, t_ns, exposure_us, out=record) is record
        got = _fields(record)
        assert got.keys() == expected.keys()
        for name, value in expected.items():
            if isinstance(value, dict):  # the quality record: nan where a measure was not made
                assert list(got[name]) == list(value), (index, name)
                np.testing.assert_array_equal(list(got[name].values()), list(value.values()), f"{index}: {name}")
            elif isinstance(value, np.ndarray):
                np.testing.assert_array_equal(got[name], value, err_msg=f"frame {index}: {name}")
            else:
                assert got[name] == value, (index, name)
        statuses.add(record.status)
    assert {FrameStatus.OK, FrameStatus.BAD_FRAME} <= statuses


@pytest.mark.jit_only  # without JIT the kernels are Python, which allocates
def test_the_steady_kernel_calls_allocate_no_python_memory(monkeypatch: pytest.MonkeyPatch) -> None:
    """`steady_frame` and the followed thresholds' `sample_slice` take no array argument (the frame through the
    workspace's `FrameSlot`, the buffers through a table): their calls allocate no Python memory (`tracemalloc`'s
    peak around each call; an array argument costs Numba's wrapper a 48-byte MemInfo from CPython's allocator).
    Nor does the split's step that takes `steady_frame`'s shapes again (`BlurSplitter.adopt_frame`, its views of
    those point counts made: no bound method or int made per frame). The whole steady frame: below."""
    peaks: dict[str, list[int]] = {"steady_frame": [], "sample_slice": [], "adopt_frame": []}

    def measured(real: Callable[..., object], name: str) -> Callable[..., object]:

        def call(*args: object) -> object:
            # Read twice: the first reading's own int (`start`, 32 B) is made after it; the second rebinds it (a
            # no-op call measured after one reading shows 32 B, after two 0).
            start = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            start = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            value = real(*args)
            peaks[name].append(tracemalloc.get_traced_memory()[1] - start)
            return value

        return call

    rope = SyntheticRope(exposure_us=4000, amplitude_rad=0.6, period_s=0.9, diameter_px=3.0, fps=119.0)
    # Rendered before tracing starts: the renderer's NumPy temporaries are not what is measured (the peaks are taken
    # around the kernel calls only), and traced they cost ~8x their time.
    frames = list(rope.frames(24))
    for name in ("steady_frame", "sample_slice"):
        monkeypatch.setattr(K, name, measured(getattr(K, name), name))
    tracemalloc.start()
    try:
        # The first measured call allocates 144 B once (not per pipeline: the interpreter's and Numba's first call
        # through this wrapper): a first pipeline makes it, its figures are dropped.
        first = Pipeline(PipelineConfig(threshold_sample_every=1), (rope.width, rope.height))
        for f in frames[:18]:  # its last frames are steady
            first.process(f.image, f.index, f.t_ns, f.exposure_us)
        assert all(peaks[name] for name in ("steady_frame", "sample_slice")), peaks
        for values in peaks.values():
            values.clear()
        pipeline = Pipeline(PipelineConfig(threshold_sample_every=1), (rope.width, rope.height))
        for f in frames:
            assert pipeline.process(f.image, f.index, f.t_ns, f.exposure_us).status is FrameStatus.OK
        # Its first two calls take the dispatcher's argument tuples from CPython's allocator (the pipeline's argument
        # tables hold tuples of that size: their free list is empty; `test_a_steady_frame_allocates_no_python_memory`).
        del peaks["steady_frame"][:2]
        # The last frame's split taken again, its shapes' views made by the first time.
        _, status, *_ = pipeline._steady.results()
        adopt = measured(pipeline.splitter.adopt_frame, "adopt_frame")
        fixed_rc = pipeline.traits.settled.fixed_rc  # type: ignore[union-attr]
        for _ in range(5):
            assert adopt(status, fixed_rc) is pipeline.splitter._shapes_outcome
    finally:
        tracemalloc.stop()
    assert all(len(values) >= 5 for values in peaks.values()), peaks
    assert peaks == {name: [0] * len(values) for name, values in peaks.items()}


def _steady_peaks(
    monkeypatch: pytest.MonkeyPatch, frames: list[tuple[np.ndarray, int, int, float]], config: PipelineConfig,
    size: tuple[int, int],
) -> tuple[Pipeline, dict[int, int], set[FrameStatus]]:  # fmt: skip
    """Run `frames` through a first pipeline to find the steady frames (one `steady_frame` call that made, ordered
    and checked the frame's shapes), then through a second one with a reused result record; return the first
    pipeline, `tracemalloc`'s peak over `Pipeline.process` of each measured steady frame of the second, and their
    statuses."""
    stops: list[int] = []
    real = K.steady_frame

    def counted(*args: object) -> int:
        stops.append(stop := real(*args))
        return stop

    monkeypatch.setattr(K, "steady_frame", counted)
    first = Pipeline(config, size)
    steady = []
    for image, index, t_ns, exposure_us in frames:
        calls = len(stops)
        first.process(image, index, t_ns, exposure_us)
        if len(stops) > calls and stops[-1] == K.STEADY_DONE:
            steady.append(index)
    monkeypatch.setattr(K, "steady_frame", real)
    # The first steady frame makes the call's argument table (once per rope width, Lc0 and thresholds); in the next
    # two the kernel's dispatcher takes its argument tuples from CPython's allocator (a new pipeline's argument
    # tables hold tuples of that size: its free list is empty). The first pipeline's frames ran every line of the
    # steady path (CPython 3.11 specialises a line's tuple unpacking after its first runs: until then each makes an
    # iterator).
    measured = steady[3:]
    assert len(measured) >= 8, steady
    pipeline = Pipeline(config, size)
    record = PipelineResult(0, 0, 0, FrameStatus.BAD_FRAME)
    peaks, statuses = {}, set()
    tracemalloc.start()
    try:
        for image, index, t_ns, exposure_us in frames:
            # Read twice: the first reading's own int is made after it, the second rebinds it.
            start = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            start = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            pipeline.process(image, index, t_ns, exposure_us, out=record)
            peak = tracemalloc.get_traced_memory()[1]
            if index in measured:
                peaks[index] = peak - start
                statuses.add(record.status)
    finally:
        tracemalloc.stop()
    return first, peaks, statuses


@pytest.mark.jit_only  # without JIT the kernels are Python, which allocates
@pytest.mark.parametrize("gamma", [1.0, 2.2])
def test_a_steady_frame_allocates_no_python_memory(monkeypatch: pytest.MonkeyPatch, gamma: float) -> None:
    """A steady frame (one `steady_frame` call that made, ordered and checked the frame's shapes) with a reused
    result record makes no Python object: `tracemalloc`'s peak over `Pipeline.process` is 0 bytes on every one,
    with a camera's gamma undone (`ToneCurve`) and a followed-threshold cycle's end among them. On a 320 px wide
    frame whose contour has more points than 256 (ints up to 256 are CPython's cached ones, any other is made): its
    shape read, a count read from a cell or a time subtracted in Python would show."""
    rope = SyntheticRope(exposure_us=4000, amplitude_rad=0.6, period_s=0.9, diameter_px=3.0, fps=119.0)
    frames = [(f.image, f.index, f.t_ns, float(f.exposure_us)) for f in rope.frames(32)]
    if gamma != 1.0:  # as the camera encodes them (`ToneCurve` maps them back)
        encode = np.round(255.0 * (np.arange(256) / 255.0) ** (1.0 / gamma)).astype(np.uint8)
        frames = [(encode[image], *rest) for image, *rest in frames]
    config = PipelineConfig(gamma=gamma, threshold_update_frames=2, threshold_sample_every=1)
    first, peaks, statuses = _steady_peaks(monkeypatch, frames, config, (rope.width, rope.height))
    assert first.tracer.count > 256  # the contour's point count is an int CPython makes
    assert statuses == {FrameStatus.OK}
    assert first.thresholds.following  # its cycles ended on these frames (every 2nd)
    assert peaks == dict.fromkeys(peaks, 0)


@pytest.mark.jit_only  # without JIT the kernels are Python, which allocates
def test_a_steady_frame_on_a_dusty_plate_allocates_no_python_memory(
    monkeypatch: pytest.MonkeyPatch, swinging_rope: SyntheticRope, dusty_frames: list[tuple[object, np.ndarray]]
) -> None:
    """On a dusty plate the learned static mask reaches every free tip (`tip_masked`), a verdict the frame
    disproves (the rope at the tips, the learned plate beyond them: `tip_end_seen`). `steady_frame` withdraws it
    itself, as `SelfChecks.check` does, so such a frame stays on the steady path: OK and 0 bytes of Python
    allocation (it ran the Python checks before, 384-738 B per frame)."""
    rope = swinging_rope
    frames = [(image, f.index, f.t_ns, float(rope.exposure_us)) for f, image in dusty_frames]  # type: ignore[attr-defined]
    config = PipelineConfig(static_frames=6)
    _, peaks, statuses = _steady_peaks(monkeypatch, frames, config, (rope.width, rope.height))
    assert statuses == {FrameStatus.OK}
    # The first split after a one-shape frame (here frame 28, after the turning point's static frame 27) may report
    # the band's middle line instead (`after_still`): the static centreline made in Python, which allocates
    # (~0.9-1.3 KB). That is not the withdrawal measured here; it is left out.
    probe = Pipeline(config, (rope.width, rope.height))
    after_one_shape = set()
    for frame in frames:
        result = probe.process(*frame)
        if result.begin is not None and result.begin is result.end:
            after_one_shape.add(frame[1] + 1)
    peaks = {index: peak for index, peak in peaks.items() if index not in after_one_shape}
    assert len(peaks) >= 8, peaks
    # Every measured frame is one whose verdict was withdrawn: without the learned scene it stands.
    blind = Pipeline(config, (rope.width, rope.height))
    blind._finisher.static_mask = blind._steady.static_mask = None
    reasons = {f[1]: blind.process(*f).reason for f in frames}
    assert {reasons[index] for index in peaks} == {"tip_masked"}
    assert peaks == dict.fromkeys(peaks, 0)


def test_a_shape_count_makes_the_views_of_its_neighbours_once() -> None:
    """`AxisPolylines.shape`: a point count without a view makes the views of the counts near it on the four rows,
    so that the next frames' shapes (a rope's counts move by a few points) take theirs without allocating; a count
    given as the float a kernel wrote finds the same view."""
    axis = AxisPolylines(SplitBuffers.make(1000), 2.0, 0.0, 1.0)
    first = axis.shape(0, 204.0)
    assert first.shape == (204, 2) and first.base is not None
    assert axis.shape(0, 204) is first
    calls = [(1, 184.0), (2, 207.0), (3, 229.0), (0, 179.0)]  # within an eighth of 204
    views: list[object] = [None] * len(calls)
    peaks = [-1] * len(calls)
    tracemalloc.start()
    try:
        for i in range(len(calls)):
            row, count = calls[i]
            start = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            start = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            views[i] = axis.shape(row, count)
            peaks[i] = tracemalloc.get_traced_memory()[1] - start
    finally:
        tracemalloc.stop()
    assert peaks == [0] * len(calls)
    assert [v.shape[0] for v in views] == [184, 207, 229, 179]  # type: ignore[attr-defined]
    assert axis.shape(3, 900.0).shape == (900, 2)  # far from any: made then
