"""The blur splitter's steady path: once the rope's width, polarity and contrast are known, a frame's split is one
`split_frame` kernel call (`SplitSteady`, a part of `BlurSplitter`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.edges import EdgeDetector
from ropecam.device.pipeline.result import Method
from ropecam.device.pipeline.split_outcome import SplitOutcome

__all__ = ["SplitSteady"]

_SHAPES = 2
"""`split_frame`'s (and `split_shapes_packed`'s) return value when it made the two shapes."""
_BLUR_SPLIT = Method.BLUR_SPLIT


class SplitSteady:
    """The steady path of `BlurSplitter` (it reads the contour, buffers and state it stores; `consts` are its
    per-width constants)."""

    def _split_frame(
        self, edge_stage: EdgeDetector, frame: NDArray[np.uint8], consts: Any, fixed_rc: tuple[float, float]
    ) -> SplitOutcome | bool | None:
        """The steady-state split in one kernel call (`split_frame`): the same steps and results as `split`'s
        sequence once the width, polarity and contrast are known. Returns False when the kernel reports a full
        buffer (`split` then redoes the steps one by one)."""
        state = self.state
        # The fixed end, polarity and contrast are the same objects from frame to frame once settled.
        key = self._state_key
        if key is None or key[0] is not fixed_rc or key[1] is not self.polarity_used or key[2] != self._contrast_cache:
            self._state_key = (fixed_rc, self.polarity_used, self._contrast_cache)
            state[0], state[1] = self._fixed32
            state[2] = self.polarity_used
            state[3] = self._contrast_cache
        args = self._frame_args
        if args is None or args[0] is not consts or args[1] is not edge_stage or args[2] is not self._bound:
            # The same buffers every frame: the argument list is made once (the contour's count, the frame and
            # the edge stage's spans are set below).
            args = self._frame_args = [
                consts, edge_stage, self._bound, self._points, self._chain, self._mag_ro, self._gx, self._gy,
                frame, edge_stage.weights_ro, edge_stage.spans[0], edge_stage.spans[1],
                edge_stage.box_lo, edge_stage.box_hi, edge_stage.tmp, edge_stage.smooth, consts.frame_params,
                state, consts.curves, consts.table_ro, consts.sweep_index, self.lines, self.sides, self.scratch,
                self.turn, self.idx, self.seg, self.info,
            ]  # fmt: skip
        return self._run_frame(edge_stage, frame, fixed_rc, self._count)

    def _run_frame(
        self, edge_stage: EdgeDetector, frame: NDArray[np.uint8], fixed_rc: tuple[float, float], n: int
    ) -> SplitOutcome | bool | None:
        """`_split_frame` once its state and argument list are made: the call and its outcome."""
        state = self.state
        state[4] = self.sweep_px
        state[5] = n
        args = self._frame_args
        assert args is not None
        args[8] = frame  # `split_frame` takes a writable or a read-only frame
        args[10], args[11] = edge_stage.spans
        return self.frame_outcome(K.split_frame(*args[3:]), fixed_rc)

    def steady_call(self) -> tuple[tuple, Any] | None:
        """The steady path's key and the rope width's tables (`WidthConstants`) when the last `split` took that
        path: the next `split` with the arguments of the key (points, chain, gx, gy, mag, smooth, edge stage,
        fixed end, width, polarity) takes it again, with those tables. None when it would not. `steady_frame`
        makes that `split_frame` call from compiled code, then `adopt_frame` takes its results."""
        key, args = self._steady_key, self._frame_args
        if key is None or args is None:
            return None
        return key, args[0]

    def adopt_frame(self, status: int, n: int, fixed_rc: tuple[float, float]) -> SplitOutcome | bool | None:
        """Take the results of a `split_frame` call made inside `steady_frame` (with ``state[4]`` = `sweep_px`,
        ``state[5]`` = `n`, on the contour, frame and spans of the key of `steady_call`), as `split` would have
        after making it. Returns as `split`, or False when the kernel reported a full buffer: `split` then redoes
        the frame's split step by step (it makes the same `split_frame` call first, with the same result)."""
        self.failure = "contour found but no segmentation points"
        self._count = n
        return self.frame_outcome(status, fixed_rc)

    def frame_outcome(self, status: int, fixed_rc: tuple[float, float]) -> SplitOutcome | bool | None:
        """The outcome of the `split_frame` call that returned `status` (its `info`, `seg` and shapes are here)."""
        width_px = self._frame_args[0].tables.width_px  # type: ignore[index]  # made before any call
        if status == _SHAPES:  # the usual outcome first
            count_a, count_b, _, _, smoothed_a, smoothed_b, sweep = self.info.tolist()
            self.sweep_px = sweep
            return SplitOutcome(
                _BLUR_SPLIT, (self.side_a if smoothed_a else self.out_a)[: int(count_a)],
                (self.side_b if smoothed_b else self.out_b)[: int(count_b)], self.seg, width_px, sweep,
            )  # fmt: skip
        if status < 0 and status != K.NOT_FOUND:
            return False
        count_a, count_b, len_a, len_b, smoothed_a, smoothed_b, sweep = self.info.tolist()
        if sweep >= 0.0:
            self.sweep_px = sweep
        if status == K.SPLIT_STATIC:
            return self.static(fixed_rc)
        if status == K.NOT_FOUND:
            self.failure = f"the two shapes differ in length ({len_a:.0f} and {len_b:.0f} px): split rejected"
            return None
        shape_a = (self.side_a if smoothed_a else self.out_a)[: int(count_a)]
        shape_b = (self.side_b if smoothed_b else self.out_b)[: int(count_b)]
        return SplitOutcome(Method.BLUR_SPLIT, shape_a, shape_b, self.seg, width_px, sweep)
