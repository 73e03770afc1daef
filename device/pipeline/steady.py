"""SteadyFrame: a steady frame of the pipeline in one kernel call (`steady_frame`).

A frame is steady when the rope's width, polarity and fixed end have settled (`RopeTraits.settled`), Lc0 is
known, the last frame's contour was found and the split took its one-call path (`split_frame`) on it. Such a
frame is `band_stage`, `detect_and_trace`, `split_frame`, `count_revisits` and `track_frame` made from compiled
code, with the buffers passed as one table of their addresses (`Workspace.steady_table`), the frame through the
workspace's frame slot: this saves the dispatch of ~80 arguments (25-50 us per frame), and the call has no array
argument (each would cost a MemInfo of Python allocation). The kernel stops where the stages' Python would take
another turn; the pipeline goes on from there with the same state as after the same calls made one by one.

A steady frame makes no Python object (`tests/device/pipeline/test_allocations.py`): the counts and times the call
updates (the frame clock, the band's gap, the kept contour, the tracer's counts) are cells it writes
(`_kernels.cells`), which the stages read on demand; Python reads back only its small results (`results`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import RecordCells, array_layout_known
from ropecam.device.pipeline.checks import SelfChecks
from ropecam.device.pipeline.contour import ContourTracer
from ropecam.device.pipeline.edges import EdgeDetector
from ropecam.device.pipeline.finish import BROKEN_OUTLINE
from ropecam.device.pipeline.locate import RopeLocator
from ropecam.device.pipeline.split import BlurSplitter
from ropecam.device.pipeline.static_mask import StaticMask
from ropecam.device.pipeline.tracking import PointTracker
from ropecam.device.pipeline.traits import RopeTraits
from ropecam.device.pipeline.workspace import Workspace, steady_constants

__all__ = ["SteadyFrame"]

_OUT = RecordCells(np.zeros(1, K.STEADY_OUT)).slots
_MOTION_PX, _STATUS, _SWAP, _CONFIDENCE = _OUT["motion_px"], _OUT["status"], _OUT["swap"], _OUT["confidence"]
_STRETCH_BEGIN, _STRETCH_END = _OUT["stretch_begin"], _OUT["stretch_end"]
_CHECK, _PLACED, _REVISITS = _OUT["check"], _OUT["placed"], _OUT["revisits"]
"""The cells of the `K.STEADY_OUT` fields Python reads after a call (`SteadyFrame.results`, `revisits`)."""
_ARGS = RecordCells(np.zeros(1, K.STEADY_ARGS)).slots
_MEASURE, _PREDICT, _T_NS, _EXPOSURE_NS, _T_END_NS = (
    _ARGS["measure"], _ARGS["predict"], _ARGS["t_ns"], _ARGS["exposure_ns"], _ARGS["t_end_ns"]
)  # fmt: skip
_LAST_SWEEP_PX, _PREDICT_TIPS_NOW = _ARGS["last_sweep_px"], _ARGS["predict_tips_now"]
_CHECK_WIDTH_PX, _LEARNED_WIDTH_PX = _ARGS["check_width_px"], _ARGS["learned_width_px"]
"""The cells of the `K.STEADY_ARGS` fields `SteadyFrame.run` writes before a call."""


class SteadyFrame:
    """Make a steady frame in one `steady_frame` call; its arguments are made once per rope width and Lc0.

    Parameters
    ----------
    workspace
        The pipeline's buffers (the table holds their addresses: they cannot be replaced).
    margin_px
        The band's margin (px).
    edges, tracer, splitter, tracker, locator, traits, checks
        The pipeline's stages: the call does their kernels' work (the self-checks' prediction and checks too), and
        they take its results.
    static_mask
        The learned static mask, whose still scene withdraws a ``tip_masked`` verdict inside the call as
        `SelfChecks.check` does (None: the verdict stands, as `ResultFinisher` without a mask).
    """

    def __init__(
        self,
        workspace: Workspace,
        margin_px: int,
        edges: EdgeDetector,
        tracer: ContourTracer,
        splitter: BlurSplitter,
        tracker: PointTracker,
        locator: RopeLocator,
        traits: RopeTraits,
        checks: SelfChecks,
        static_mask: StaticMask | None = None,
    ) -> None:
        self.workspace, self.margin_px = workspace, margin_px
        self.static_mask = static_mask
        self.edges, self.tracer, self.splitter, self.tracker = edges, tracer, splitter, tracker
        self.locator, self.traits, self.checks = locator, traits, checks
        self._frame_call = splitter.frame_call
        self._motion, self._fixed_end = locator.motion, locator.fixed_end  # read every frame (`run`)
        self.out = workspace.steady_out
        """The last call's results (one `STEADY_OUT` record, read by name: ``out["points"]``)."""
        # Its small results read cell by cell (ints within CPython's cached -5..256, floats from its free list: no
        # allocation), the per-frame scalars written so (`run`): no NumPy scalar, no argument to type.
        out, frame_args = RecordCells(self.out), RecordCells(workspace.steady_args)
        self._out_ints, self._out_floats = out.ints, out.floats
        self._arg_ints, self._arg_floats = frame_args.ints, frame_args.floats
        self._slot = workspace.frame_slot
        self._bound: tuple[Any, ...] | None = None
        """(the split's steady key, the rope width's tables, Lc0, the table's address, the tracker's plane, the
        table, the constants, whether the static mask had learned its scene) of the last steady frame: its table
        holds the addresses of the workspace's buffers, of those tables, of the constants and of a copy of the
        plane."""
        self._plane = np.zeros(K.PLANE_PARAMS, np.float64)
        """The tracker's plane parameters as the table's writable row (zeros without a plane)."""

    def unbind(self) -> None:
        """Make the table again on the next `args` (a constant in it, such as a threshold, changed)."""
        self._bound = None

    def args(self) -> int | None:
        """`steady_frame`'s argument, the address of its table, when this frame can be one kernel call (the split
        took its one-call path on the last frame with the workspace's buffers, and Lc0 is settled, so `track_frame`
        runs); `run` writes the per-frame scalars into the table's ``args`` record. None otherwise."""
        call = self._frame_call.one_call_key()
        length0_px = self.tracker.length0_settled_px
        if call is None or length0_px < 0.0 or not array_layout_known():
            return None
        key, width_tables = call
        bound = self._bound
        plane = self.tracker.plane
        static = self.static_mask
        learned = static is not None and static.marked and static.frames > 0  # a bool: no object made
        if (
            bound is not None
            and bound[0] is key
            and bound[1] is width_tables
            and bound[2] == length0_px
            and bound[4] is plane
            and bound[7] is learned
        ):
            return bound[3]  # type: ignore[no-any-return]
        self._bound = None
        e, tracer, settled = self.edges, self.tracer, self.traits.settled
        if settled is None:
            return None
        # The split's one-call path was taken with what the pipeline passes it: the workspace's buffers, which
        # `steady_frame` passes it too.
        ours = (tracer.points, tracer.chain, e.gx, e.gy, e.mag, e.smooth, e, settled.fixed_rc)
        if not (
            all(k is o for k, o in zip(key[:8], ours, strict=True))
            and key[8] == settled.width_px
            and key[9] == settled.polarity
        ):
            return None
        gain, floor_px, floor_share = self.locator.motion.need_args
        height, width = e.shape
        still_dn, still_relative = static.still_range() if static is not None and learned else (-1.0, 0.0)
        constants = steady_constants(
            margin_px=self.margin_px, height=height, width=width, gain=gain, floor_px=floor_px,
            floor_share=floor_share, low=e.low, high=e.high, min_pixels=tracer.min_pixels, length0_px=length0_px,
            broken_outline=BROKEN_OUTLINE, on_plane=plane is not None, still_dn=still_dn,
            still_relative=still_relative, rope_width_px=float(width_tables.tables.width_px),
        )  # fmt: skip
        self._plane[:] = 0.0 if plane is None else plane
        table = self.workspace.steady_table(width_tables, self.checks.buffers, self._plane, constants)
        address = table.ctypes.data
        self._bound = (key, width_tables, length0_px, address, plane, table, constants, learned)
        return address

    def run(
        self,
        address: int,
        image: NDArray[np.uint8],
        t_ns: int,
        t_end_ns: int,
        exposure_ns: int,
        predict: bool,
    ) -> int:
        """Make the frame exposed from `t_ns` to `t_end_ns` (`exposure_ns`) in one `steady_frame` call on the table
        at `address` (from `args`); its results are in `out`, the frame's start in the frame clock, the time since
        the last contour's frame in the locator's `gap_ns`. With `predict` (`SelfChecks.due`) the call predicts the
        tips first (`SelfChecks.predict`'s kernel); it places the shapes it tracked on the tracker's plane and
        checks them as `ResultFinisher` would (``out["placed"]``, ``out["check"]``).

        Returns
        -------
        int
            Where the call stopped (STEADY_DONE, STEADY_AFTER_CONTOUR, STEADY_AFTER_SPLIT, STEADY_BROKEN,
            STEADY_AFTER_SHAPES).

        Raises
        ------
        RuntimeError
            The kernel refused its arguments.
        """
        ints, floats = self._arg_ints, self._arg_floats
        ints[_MEASURE] = self._motion.owed
        ints[_PREDICT] = self._fixed_end.known
        ints[_T_NS] = t_ns
        ints[_EXPOSURE_NS] = exposure_ns
        ints[_T_END_NS] = t_end_ns
        floats[_LAST_SWEEP_PX] = self.splitter.sweep_px  # `split_frame`'s last sweep
        ints[_PREDICT_TIPS_NOW] = predict
        floats[_CHECK_WIDTH_PX] = self.splitter.width  # the width the checks compare (`ResultFinisher.check`)
        floats[_LEARNED_WIDTH_PX] = self.traits.settled[0]  # type: ignore[index]  # `args` checked it
        self._slot.hold(image)
        try:
            stop: int = K.steady_frame(address)
        finally:
            self._slot.release()
        if stop < 0:
            raise RuntimeError(f"steady_frame refused its arguments (status {stop})")
        return stop

    def results(self) -> tuple[float, int, int, float, float, float, int, int]:
        """The last call's small results (motion_px, status, swap, confidence, stretch_begin, stretch_end, check,
        placed), as Python scalars."""
        ints, floats = self._out_ints, self._out_floats
        return (
            floats[_MOTION_PX], ints[_STATUS], ints[_SWAP], floats[_CONFIDENCE], floats[_STRETCH_BEGIN],
            floats[_STRETCH_END], ints[_CHECK], ints[_PLACED],
        )  # fmt: skip

    def revisits(self) -> int:
        """The last call's contour pixels walked twice (-1: not counted)."""
        return self._out_ints[_REVISITS]
