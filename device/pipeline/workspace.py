"""The pipeline's workspace: every buffer the per-frame path writes, allocated once per image size, by name.

Each stage owns one group (a frozen dataclass of named arrays) and gets it when it is made; a stage made alone
makes its own. A group's arrays cannot be replaced (the dataclass is frozen, and the stages expose them as
read-only properties, `expose`), so the table of raw addresses that `steady_frame` reads (`Workspace.steady_table`)
stays valid as long as the workspace lives: the pipeline keeps both, and refuses to be copied or pickled.

Groups: `EdgeBuffers` (`EdgeDetector`), `ContourBuffers` (`ContourTracer`), `RoiBuffers` (the band and the
coarse search, `RopeLocator`), `FixedEndBuffers` (`FixedEndFinder`), `MotionBuffers` (`MotionModel`),
`OrderBuffers` (`TimeOrder`), `SplitBuffers` (`BlurSplitter`), `TrackBuffers` (`PointTracker`).
"""

from __future__ import annotations

import dataclasses
import operator
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NoReturn, TypeVar

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import FrameSlot, buffer_table, resident_zeros, ro, staggered_planes

__all__ = [
    "COARSE_BLOCK",
    "NEED_BINS",
    "ContourBuffers",
    "EdgeBuffers",
    "FixedEndBuffers",
    "MotionBuffers",
    "OrderBuffers",
    "RoiBuffers",
    "SplitBuffers",
    "TrackBuffers",
    "Workspace",
    "expose",
    "refuse_copies",
    "steady_constants",
]

COARSE_BLOCK = 4
"""Cell size (px) of the coarse search for the rope when there is no ROI."""
NEED_BINS = 16
"""Bins of the normalised distance from the fixed end over which the band prediction's error is measured."""
TRACK_WORK = 1024
"""Smallest length of `TrackBuffers.work` (a shape's segment lengths)."""

_T = TypeVar("_T")
_group = dataclass(frozen=True, slots=True, eq=False)


def refuse_copies(message: str) -> Callable[[type[_T]], type[_T]]:
    """Return a class decorator that makes `copy.copy`, `copy.deepcopy` and `pickle` of an instance raise
    `TypeError` with `message` (an owner of a workspace and its `steady_table`: a copy would share the raw
    addresses, and write into freed memory once the original is gone)."""

    def refuse(*_: object) -> NoReturn:
        raise TypeError(message)

    def decorate(cls: type[_T]) -> type[_T]:
        cls.__copy__ = refuse  # type: ignore[attr-defined]
        cls.__deepcopy__ = refuse  # type: ignore[attr-defined]
        cls.__reduce_ex__ = refuse  # type: ignore[assignment, method-assign]
        return cls

    return decorate


def expose(group: str, fields: type) -> Callable[[type[_T]], type[_T]]:
    """Return a class decorator that gives the class a read-only property per field of the dataclass `fields`,
    reading it from its attribute `group` (``stage.gx`` is ``stage.buffers.gx`` and cannot be assigned)."""

    def decorate(cls: type[_T]) -> type[_T]:
        for field in dataclasses.fields(fields):
            getter = operator.attrgetter(f"{group}.{field.name}")
            setattr(cls, field.name, property(getter, doc=f"``{group}.{field.name}`` (read only)."))
        return cls

    return decorate


@_group
class EdgeBuffers:
    """`EdgeDetector`'s: the Gaussian `weights` (read-only), the span scratch, the five float planes (at
    different offsets within a page, `staggered_planes`), the edge map and list, the spans of `smooth_box` and
    the whole image's spans, and the static mask with each pixel's learned grey-level range (`StaticMask`)."""

    weights: NDArray[np.float32]
    work_spans: NDArray[np.int32]
    tmp: NDArray[np.float32]
    smooth: NDArray[np.float32]
    gx: NDArray[np.float32]
    gy: NDArray[np.float32]
    mag: NDArray[np.float32]
    edges: NDArray[np.uint8]
    stack: NDArray[np.int32]
    box_lo: NDArray[np.int32]
    box_hi: NDArray[np.int32]
    full_lo: NDArray[np.int32]
    full_hi: NDArray[np.int32]
    static_mask: NDArray[np.uint8]
    static_low: NDArray[np.uint8]
    static_high: NDArray[np.uint8]
    static_near: NDArray[np.uint8]
    planes: K.Planes
    """`smooth`, `gx`, `gy`, `mag` as the kernels' group (`detect_and_trace`, the split)."""
    static: K.Static
    """`static_mask`, `static_low`, `static_high`, `static_near` (the mask's summary, `mark_near_blocks`: all 1
    until `StaticMask` marks it) as `detect_and_trace`'s group."""
    work: K.EdgeWork
    """`work_spans`, `tmp`, `edges`, `stack` as `detect_and_trace`'s group."""

    @classmethod
    def make(cls, height: int, width: int, weights: NDArray[np.float32]) -> EdgeBuffers:
        """Allocate the buffers of an image of `height` x `width` px for the Gaussian `weights` (copied)."""
        tmp, smooth, gx, gy, mag = staggered_planes(5, (height, width), np.float32)
        work_spans, edges = np.zeros((4, height), np.int32), resident_zeros((height, width), np.uint8)
        stack = resident_zeros(height * width, np.int32)
        static = K.Static(
            np.zeros((height, width), np.uint8), np.full((height, width), 255, np.uint8),
            np.zeros((height, width), np.uint8), np.ones(K.near_blocks(height, width), np.uint8),
        )  # fmt: skip
        return cls(
            ro(np.array(weights, np.float32)), work_spans, tmp, smooth, gx, gy, mag, edges, stack,
            np.zeros(height, np.int32), np.zeros(height, np.int32), np.zeros(height, np.int32),
            np.full(height, width - 1, np.int32), *static, K.Planes(smooth, gx, gy, mag), static,
            K.EdgeWork(work_spans, tmp, edges, stack),
        )  # fmt: skip


@_group
class ContourBuffers:
    """`ContourTracer`'s: component labels and stack, the start pixel, the chain (pixels, codes, subpixel
    points; `capacity` each) and the trace's counts."""

    labels: NDArray[np.int32]
    stack: NDArray[np.int32]
    start: NDArray[np.int32]
    chain: NDArray[np.int32]
    codes: NDArray[np.int32]
    points: NDArray[np.float32]
    counts: NDArray[np.int32]
    group: K.Contour
    """The seven as the kernels' group (`trace_rope`, `detect_and_trace`)."""

    @classmethod
    def make(cls, height: int, width: int, capacity: int) -> ContourBuffers:
        """Allocate the buffers of an image of `height` x `width` px and contours of up to `capacity` points."""
        arrays = (
            resident_zeros((height, width), np.int32), resident_zeros(height * width, np.int32),
            np.zeros(2, np.int32), np.zeros((capacity, 2), np.int32), np.zeros(capacity, np.int32),
            np.zeros((capacity, 2), np.float32), np.zeros(K.TRACER_COUNTS, np.int32),
        )  # fmt: skip
        return cls(*arrays, K.Contour(*arrays))


@_group
class RoiBuffers:
    """Where the rope is searched: the row spans `lo`/`hi` of the band, the spans a widening adds
    (`grow_lo`/`grow_hi`), the last contour moved by the prediction (`moved`; `no_moved` for the widening's bands,
    whose moved points are not kept), the coarse search's cell sums, labels and stack and the locator's counts and
    times (`cells`, `K.LOCATE_CELLS`)."""

    lo: NDArray[np.int32]
    hi: NDArray[np.int32]
    grow_lo: NDArray[np.int32]
    grow_hi: NDArray[np.int32]
    moved: NDArray[np.float32]
    no_moved: NDArray[np.float32]
    coarse_sums: NDArray[np.int32]
    coarse_labels: NDArray[np.int32]
    coarse_stack: NDArray[np.int32]
    cells: NDArray[np.int64]
    band: K.Band
    """`lo`, `hi`, `moved` as `band_stage`'s group."""

    @classmethod
    def make(cls, height: int, width: int, capacity: int) -> RoiBuffers:
        """Allocate the buffers of an image of `height` x `width` px and contours of up to `capacity` points."""
        cells = (max(1, height // COARSE_BLOCK), max(1, width // COARSE_BLOCK))
        lo, hi, moved = np.zeros(height, np.int32), np.zeros(height, np.int32), np.zeros((capacity, 2), np.float32)
        return cls(
            lo, hi, np.zeros(height, np.int32), np.zeros(height, np.int32), moved, np.zeros((0, 2), np.float32),
            resident_zeros(cells, np.int32), resident_zeros(cells, np.int32),
            resident_zeros(max(cells[0] * cells[1], width), np.int32), np.zeros(len(K.LOCATE_CELLS), np.int64),
            K.Band(lo, hi, moved),
        )  # fmt: skip


@_group
class FixedEndBuffers:
    """`FixedEndFinder`'s: the fixed end (row, col) and the turning angles of the contour it is found on."""

    fixed: NDArray[np.float32]
    turn: NDArray[np.float32]

    @classmethod
    def make(cls, capacity: int) -> FixedEndBuffers:
        """Allocate the buffers for contours of up to `capacity` points."""
        return cls(np.zeros(2, np.float32), np.zeros(capacity, np.float32))


@_group
class MotionBuffers:
    """`MotionModel`'s (see there): its `state`, `log`, the band prediction's error `need` and `profile`, and
    what the last band was built with (`band`, one `BAND_STATE` record)."""

    state: NDArray[np.int64]
    log: NDArray[np.float64]
    need: NDArray[np.float64]
    profile: NDArray[np.float64]
    band: NDArray[np.void]
    group: K.Motion
    """The five as the kernels' group."""

    @classmethod
    def make(cls) -> MotionBuffers:
        """Allocate the buffers (their size does not depend on the image)."""
        arrays = (
            np.zeros(K.MOTION_FRAMES + 2, np.int64), np.zeros((K.MOTION_FRAMES + 1, 2), np.float64),
            np.zeros((2, NEED_BINS), np.float64), np.full(NEED_BINS, np.inf), np.zeros(1, K.BAND_STATE),
        )  # fmt: skip
        return cls(*arrays, K.Motion(*arrays))


@_group
class OrderBuffers:
    """`TimeOrder`'s (see there): sample times and counters (`state`), sample tips (`hist_rc`), and
    `uncross_shapes`' previous end shape (`prev_end`) and scratch (`splice`)."""

    state: NDArray[np.int64]
    hist_rc: NDArray[np.float64]
    prev_end: NDArray[np.float32]
    splice: NDArray[np.float32]
    group: K.Order
    """The four as the kernels' group."""

    @classmethod
    def make(cls, capacity: int = TRACK_WORK) -> OrderBuffers:
        """Allocate the buffers for shapes of up to `capacity` points (a longer shape is not uncrossed)."""
        arrays = (
            np.zeros(K.ORDER_STATE_SIZE, np.int64), np.zeros((K.HISTORY, 2), np.float64),
            np.zeros((capacity, 2), np.float32), np.zeros((3, 2 * capacity, 2), np.float32),
        )  # fmt: skip
        return cls(*arrays, K.Order(*arrays))


@_group
class SplitBuffers:
    """`BlurSplitter`'s: ``scratch`` (3, capacity) float64 (arc, distance from the fixed end, slope work),
    ``lines`` (3, capacity) float32 (work, the sweeps of side A and side B), ``sides`` (4, capacity, 2) (side A,
    side B, out A, out B), the turning angles, the segmentation indices, the measured widths, the two
    segmentation points (``seg``), `split_frame`'s `info` and `state` (`FRAME_STATES`)."""

    scratch: NDArray[np.float64]
    lines: NDArray[np.float32]
    sides: NDArray[np.float32]
    turn: NDArray[np.float32]
    idx: NDArray[np.int32]
    dist: NDArray[np.float32]
    seg: NDArray[np.float32]
    info: NDArray[np.float64]
    state: NDArray[np.float64]
    group: K.SplitWork
    """`lines`, `sides`, `scratch`, `turn`, `idx`, `seg`, `info` as the split kernels' group."""

    @classmethod
    def make(cls, capacity: int) -> SplitBuffers:
        """Allocate the buffers for contours of up to `capacity` points."""
        scratch, lines = np.zeros((3, capacity), np.float64), np.zeros((3, capacity), np.float32)
        sides, turn, idx = np.zeros((4, capacity, 2), np.float32), np.zeros(capacity, np.float32), np.zeros(4, np.int32)
        seg, info = np.zeros((2, 2), np.float32), np.zeros(K.FRAME_INFO, np.float64)
        return cls(
            scratch, lines, sides, turn, idx, np.zeros(capacity, np.float32), seg, info,
            np.zeros(len(K.FRAME_STATES), np.float64), K.SplitWork(lines, sides, scratch, turn, idx, seg, info),
        )  # fmt: skip


@_group
class TrackBuffers:
    """`PointTracker`'s: the material points' arc fractions (read-only), their positions on both shapes
    (``out``, (2, points, 2)), the shapes' lengths and the segment lengths of a shape (``work``)."""

    fraction: NDArray[np.float64]
    out: NDArray[np.float32]
    lengths_px: NDArray[np.float64]
    work: NDArray[np.float64]
    group: K.Track
    """The four as the kernels' group (its ``fraction`` the writable array `fraction` views: the kernels only
    read it)."""

    @classmethod
    def make(cls, fraction: NDArray[np.float64], capacity: int) -> TrackBuffers:
        """Allocate the buffers for material points at arc `fraction` (of the rope's length) on shapes of up to
        `capacity` points (a rolling shutter's placement on the plane needs `K.ROLLING_WORK` values per point of
        both shapes, whose points together are at most the contour's `capacity`)."""
        fraction = np.array(fraction, np.float64)
        out = np.zeros((2, len(fraction), 2), np.float32)
        lengths_px = np.zeros(2, np.float64)
        work = np.zeros(max(TRACK_WORK, K.ROLLING_WORK * capacity), np.float64)
        return cls(ro(fraction), out, lengths_px, work, K.Track(fraction, out, lengths_px, work))


@_group
class Workspace:
    """Every buffer of one pipeline, by stage (see the module's docstring), the steady frame's results
    (``steady_out``, one `STEADY_OUT` record) and per-frame scalars (``steady_args``, one `STEADY_ARGS` record), the
    slot that holds the frame while a kernel reads it through a table (``frame_slot``: `steady_frame`) and the frame
    clock's cells (``clock``, `K.CLOCK_CELLS`: `FrameClock`)."""

    edges: EdgeBuffers
    contour: ContourBuffers
    roi: RoiBuffers
    fixed_end: FixedEndBuffers
    motion: MotionBuffers
    order: OrderBuffers
    split: SplitBuffers
    track: TrackBuffers
    steady_out: NDArray[np.void]
    steady_args: NDArray[np.void]
    frame_slot: FrameSlot
    clock: NDArray[np.int64]

    @classmethod
    def make(
        cls, height: int, width: int, capacity: int, weights: NDArray[np.float32], fraction: NDArray[np.float64]
    ) -> Workspace:
        """Allocate the buffers of a pipeline for frames of `height` x `width` px, contours of up to `capacity`
        points, the Gaussian smoothing's `weights` and material points at arc `fraction`."""
        return cls(
            EdgeBuffers.make(height, width, weights), ContourBuffers.make(height, width, capacity),
            RoiBuffers.make(height, width, capacity), FixedEndBuffers.make(capacity), MotionBuffers.make(),
            OrderBuffers.make(capacity), SplitBuffers.make(capacity), TrackBuffers.make(fraction, capacity),
            np.zeros(1, K.STEADY_OUT), np.zeros(1, K.STEADY_ARGS), FrameSlot(height, width),
            np.zeros(len(K.CLOCK_CELLS), np.int64),
        )  # fmt: skip

    def steady_table(
        self,
        width: Any,
        checks: tuple[NDArray[Any], NDArray[Any], NDArray[Any]],
        plane: NDArray[np.float64],
        constants: NDArray[np.void],
    ) -> NDArray[np.int64]:
        """Return `steady_frame`'s table of this workspace's buffers, the rope width's tables `width`
        (`ropecam.device.pipeline.width_tables.WidthTables`: ``width_scalars``, ``curves``, ``table_ro``,
        ``sweep_index``), the self-checks' `checks` (`SelfChecks.buffers`: predicted, thresholds, measures), the
        `plane` parameters (`plane_params`' values in writable memory), the `constants` (`steady_constants`), the
        results ``steady_out``, the per-frame scalars ``steady_args``, the ``frame_slot`` and the clock's and
        locator's cells, by the names of `STEADY_BUFFERS`. Its raw addresses are valid while this workspace,
        `width`, the checks' arrays, `plane` and `constants` live: the caller keeps them with it."""
        e, c, r, m, s, t = self.edges, self.contour, self.roi, self.motion, self.split, self.track
        return buffer_table(
            {
                # band_stage's
                "prev_points": c.points, "fixed": self.fixed_end.fixed, "motion_state": m.state,
                "motion_log": m.log, "need_hist": m.need, "profile": m.profile, "band_state": m.band, "lo": r.lo,
                "hi": r.hi, "moved": r.moved,
                # detect_and_trace's
                "weights": e.weights, "static_mask": e.static_mask, "static_low": e.static_low,
                "static_high": e.static_high, "static_near": e.static_near, "work_spans": e.work_spans, "tmp": e.tmp,
                "smooth": e.smooth, "gx": e.gx, "gy": e.gy, "mag": e.mag, "edges": e.edges, "edge_stack": e.stack,
                "labels": c.labels, "stack": c.stack, "start": c.start, "chain": c.chain, "codes": c.codes,
                "points": c.points, "counts": c.counts,
                # split_frame's
                "box_lo": e.box_lo, "box_hi": e.box_hi, "width_scalars": width.width_scalars, "split_state": s.state,
                "curves": width.curves, "table": width.table_ro, "sweep_index": width.sweep_index, "lines": s.lines,
                "sides": s.sides, "scratch": s.scratch, "turn": s.turn, "idx": s.idx, "out_seg": s.seg,
                "split_info": s.info,
                # track_frame's
                "order_state": self.order.state, "hist_rc": self.order.hist_rc,
                "prev_end": self.order.prev_end, "splice": self.order.splice, "fraction": t.fraction,
                "out_points": t.out, "out_lengths": t.lengths_px, "work_seg": t.work,
                # predict_tips' and check_frame's
                "predicted": checks[0], "check_thresholds": checks[1], "check_quality": checks[2],
                # place_on_plane's
                "plane": plane,
                # steady_frame's own
                "frame_slot": self.frame_slot, "constants": constants, "out": self.steady_out,
                "args": self.steady_args,
                # the frame clock's and the locator's cells
                "clock": self.clock, "locate": r.cells,
            },
            K.STEADY_BUFFERS,
        )  # fmt: skip


def steady_constants(**values: float) -> NDArray[np.void]:
    """Return `steady_frame`'s ``constants`` (one `STEADY_CONSTANTS` record, a read-only view) from their values by
    name.

    Raises
    ------
    ValueError
        A name missing or not one of `STEADY_CONSTANTS`.
    """
    names = K.STEADY_CONSTANTS.names
    if set(values) != set(names):
        raise ValueError(f"steady constants missing: {sorted(set(names) - set(values))}, unknown: "
                         f"{sorted(set(values) - set(names))}")  # fmt: skip
    record = np.zeros(1, K.STEADY_CONSTANTS)
    for name in names:
        record[name] = values[name]
    return ro(record)  # in writable memory: `buffer_table` takes it
