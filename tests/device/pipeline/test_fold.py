"""A first shape that runs out along the rope and back (`folds_back`) is implausible, and its length does not
become the rope's Lc0 (`PointTracker.withdraw`)."""

from __future__ import annotations

import numpy as np
import pytest

from ropecam.device.pipeline.checks import folds_back
from ropecam.device.pipeline.tracking import PointTracker


def _line(start: tuple[float, float], stop: tuple[float, float], step_px: float = 2.0) -> np.ndarray:
    length = float(np.hypot(stop[0] - start[0], stop[1] - start[1]))
    t = np.linspace(0.0, 1.0, max(2, round(length / step_px) + 1))[:, None]
    return (np.array(start) + t * (np.array(stop) - np.array(start))).astype(np.float32)


def test_a_centreline_out_and_back_along_the_rope_folds_back() -> None:
    out = _line((80.0, 508.0), (87.0, 908.0))
    back = _line((87.6, 906.0), (82.0, 649.0))  # a side walked back, 1 px off the way out (simulated lab-hard)
    assert folds_back(np.concatenate([out, back]), 2.0)
    assert folds_back(np.concatenate([out, back]), None)


def test_a_centreline_that_loops_along_the_way_folds_back() -> None:
    """The rope's outline broken into loops (simulated lab-hard, fresh device, tuning seed, frame 20): the
    centreline crosses itself halfway and runs on; its tip lies on no earlier part."""
    out = _line((80.0, 508.0), (176.0, 584.0))
    loop = np.concatenate([_line((174.0, 588.0), (150.0, 590.0)), _line((148.0, 588.0), (140.0, 540.0))])
    on = _line((150.0, 560.0), (195.0, 631.0))  # crosses `out` near (150, 563)
    assert folds_back(np.concatenate([out, loop, on]), 3.4)


@pytest.mark.parametrize(
    "shape",
    [
        _line((80.0, 508.0), (87.0, 908.0)),  # straight
        np.concatenate([_line((10.0, 100.0), (210.0, 100.0)), _line((212.0, 102.0), (212.0, 140.0))]),  # a hook
        np.array([[10.0, 10.0], [12.0, 10.0]], np.float32),  # too short to tell
        _line((0.0, 0.0), (0.0, 300.0), 0.5),  # densely sampled
    ],
    ids=["straight", "hooked tip", "two points", "dense"],
)
def test_a_rope_that_does_not_lie_on_itself_does_not_fold(shape) -> None:
    assert not folds_back(shape, 2.0)


def test_withdrawn_lengths_do_not_settle_lc0() -> None:
    tracker = PointTracker((0.5,), 1.0, None, length0_frames=3)
    rope, folded = _line((0.0, 0.0), (0.0, 400.0)), _line((0.0, 0.0), (0.0, 800.0))
    tracker.track_shapes(rope, rope)
    tracker.track_shapes(rope, rope)
    assert tracker.lengths_seen == 2
    tracker.track_shapes(folded, folded)  # the third length settles Lc0 ...
    assert tracker.length0_settled_px == pytest.approx(400.0)
    tracker.withdraw(1)  # ... until the frame is found folded
    assert tracker.length0_settled_px == -1.0 and tracker.lengths_seen == 2
    tracker.track_shapes(rope, rope)
    assert tracker.length0_settled_px == pytest.approx(400.0)
    configured = PointTracker((0.5,), 1.0, 400.0)
    configured.withdraw(1)  # a configured Lc0 is never withdrawn
    assert configured.length0_settled_px == 400.0
