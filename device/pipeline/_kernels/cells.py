"""The per-frame counts and times of the pipeline's stages kept in int64 cells, and their arithmetic.

A Python int above 256 is a new object (32 bytes of Python allocation) wherever it is made: by arithmetic on such
ints (a frame's start minus the last one's) and by every read of one from a NumPy array. The counts and times a
steady frame updates (the frame clock's period, the band's time gap, the kept contour's point count, the frames
found in their band) therefore live in cells the kernels read and write (`steady_frame` reaches them through its
table); the stages read them on demand, as properties, off the steady path.
"""

from __future__ import annotations

from typing import Final, NamedTuple

import numba
from numba import int64, types, void

from ropecam.shared.jit import kernel

_i8_1d: Final = types.Array(types.int64, 1, "C")

AGE_PERIODS: Final = 4
"""The time order's history is dropped after this many frame periods (`clock_tick`'s ``max_age_ns``)."""

CLOCK_CELLS: Final = ("last_t_ns", "seen", "period_ns", "max_age_ns")
"""A stream's frame clock (`ropecam.device.pipeline.finish.FrameClock`): the start of the last frame (ns), 1 once a
frame was seen, the frame period (the shortest time between frame starts seen, ns; 0 until two frames were seen)
and `AGE_PERIODS` times it (the caller sets its value for an unknown period)."""
CLOCK: Final = NamedTuple("ClockCells", [(name, int) for name in CLOCK_CELLS])(*range(len(CLOCK_CELLS)))
"""The index of each of `CLOCK_CELLS` (``CLOCK.period_ns``)."""

LOCATE_CELLS: Final = (
    "prev_count", "prev_t_ns", "need_gap_ns", "gap_ns", "frames_roi", "frames_coarse", "frames_full", "roi_retries",
)  # fmt: skip
"""The rope locator's (`ropecam.device.pipeline.locate.RopeLocator`): the point count of the kept contour (0: none)
and its frame's start (ns), the time gap the band's error was last measured over, the gap from the kept contour's
frame to the last `steady_frame`'s (ns), and the frames found in their band, around the coarse search's cells and
in the whole frame, and the bands widened."""
LOCATE: Final = NamedTuple("LocateCells", [(name, int) for name in LOCATE_CELLS])(*range(len(LOCATE_CELLS)))
"""The index of each of `LOCATE_CELLS` (``LOCATE.prev_count``)."""


CONTOUR_POINTS: Final = 4
"""The cell of the contour tracer's ``counts`` (after the trace kernels' four: component pixels, ROI contacts, chain
pixels on the image border, edge pixels) that holds the point count of its last contour (0: none)."""
TRACER_COUNTS: Final = CONTOUR_POINTS + 1
"""The length of the contour tracer's ``counts``."""


@numba.njit(inline="always")
def clock_tick(clock, t_ns):  # type: ignore[no-untyped-def]
    """Take the start `t_ns` of a frame into the `CLOCK_CELLS` `clock`: a gap from the last start shorter than the
    period is the new period (and ``max_age_ns`` `AGE_PERIODS` times it)."""
    if clock[CLOCK.seen] != 0 and t_ns > clock[CLOCK.last_t_ns]:
        gap_ns = t_ns - clock[CLOCK.last_t_ns]
        if clock[CLOCK.period_ns] == 0 or gap_ns < clock[CLOCK.period_ns]:
            clock[CLOCK.period_ns] = gap_ns
            clock[CLOCK.max_age_ns] = AGE_PERIODS * gap_ns
    clock[CLOCK.last_t_ns] = t_ns
    clock[CLOCK.seen] = 1


@kernel(void(_i8_1d, int64))
def tick_clock(clock, t_ns):
    """`clock_tick` called from Python (a frame that is not one `steady_frame` call, which ticks it itself)."""
    if clock.shape[0] >= len(CLOCK_CELLS):
        clock_tick(clock, t_ns)
