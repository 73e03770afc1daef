"""SplitFrameCall: a frame's blur split in one kernel call (`split_frame`), once the rope's width, polarity and
contrast are known."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.edges import EdgeDetector
from ropecam.device.pipeline.width_tables import WidthTables
from ropecam.device.pipeline.workspace import SplitBuffers

__all__ = ["SplitFrameCall"]

_STATE = K.FRAME_STATE


class SplitFrameCall:
    """Make a frame's blur split in one `split_frame` call: the same steps and results as `BlurSplitter.split`'s
    sequence once the width, polarity and contrast are known.

    Owns the kernel's per-frame inputs (``state``: fixed end, polarity, contrast, last sweep, point count), its
    argument list (made once per width tables, edge stage and contour buffers) and the `key` of the last split
    that took this path: the next split with the same arguments takes it again without preparing anything.

    Parameters
    ----------
    buffers
        The split's buffers (`SplitBuffers`: the kernel's `state`, scratch and outputs).
    """

    def __init__(self, buffers: SplitBuffers) -> None:
        self.buffers = buffers
        self.key: tuple[Any, ...] | None = None
        """(points, chain, gx, gy, mag, smooth, edge stage, fixed end, width, polarity) of the last split that
        took this path from a given width and polarity; None when the next one is not to take it directly."""
        self._args: list[Any] | None = None
        """`split_frame`'s arguments after three keys: the width tables, the edge stage, the contour's views."""
        self._state_key: tuple[tuple[float, float], np.float32, float, float] | None = None
        self.width_px = 0.0
        """The rope width (px) of the width tables of the last `bind`."""

    def matches(
        self,
        points: NDArray[np.float32],
        chain: NDArray[np.int32],
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        mag: NDArray[np.float32],
        smooth: NDArray[np.float32],
        edge_stage: EdgeDetector | None,
        fixed_rc: tuple[float, float],
        width_px: float | None,
        polarity: float,
    ) -> bool:
        """Whether a split of these arguments (`BlurSplitter.split`'s) is to take this path directly: the same
        contour buffers, planes, edge stage and fixed end (the same objects), width and polarity as the `key`."""
        key = self.key
        return (
            key is not None
            and points is key[0]
            and chain is key[1]
            and gx is key[2]
            and gy is key[3]
            and mag is key[4]
            and smooth is key[5]
            and edge_stage is key[6]
            and fixed_rc is key[7]
            and width_px == key[8]
            and polarity == key[9]
        )

    @property
    def tables(self) -> WidthTables:
        """The width tables of the last call (made before any)."""
        return self._args[0]  # type: ignore[index, no-any-return]

    def bind(
        self,
        tables: WidthTables,
        edge_stage: EdgeDetector,
        views: tuple[NDArray[Any], ...],
        fixed_rc: tuple[float, float],
        fixed32: tuple[np.float32, np.float32],
        polarity: np.float32,
        contrast: float,
        decision_contrast: float,
    ) -> None:
        """Set the kernel's inputs for a contour whose read-only `views` are (points, chain, gx, gy, mag) (the
        planes those of `edge_stage`), split with `tables`, about the fixed end `fixed_rc` (`fixed32` its float32
        pair), with `polarity` and `contrast` (`decision_contrast` the split/static decision's,
        `BandMeasure.decision_contrast`). The fixed end, polarity and contrast are the same objects from
        frame to frame once settled, and so are the buffers: both are set only when one of them changes."""
        state = self.buffers.state
        key = self._state_key
        if (
            key is None
            or key[0] is not fixed_rc
            or key[1] is not polarity
            or key[2] != contrast
            or key[3] != decision_contrast
        ):
            self._state_key = (fixed_rc, polarity, contrast, decision_contrast)
            state[_STATE.fixed_r], state[_STATE.fixed_c] = fixed32
            state[_STATE.polarity] = polarity
            state[_STATE.contrast] = contrast
            state[_STATE.decision_contrast] = decision_contrast
        self.width_px = tables.tables.width_px
        args = self._args
        if args is None or args[0] is not tables or args[1] is not edge_stage or args[2] is not views:
            b = self.buffers
            self._args = [
                tables, edge_stage, views, views[0], views[1], edge_stage.planes, edge_stage.edges,
                edge_stage.weights_ro, edge_stage.spans[0], edge_stage.spans[1], edge_stage.box_lo, edge_stage.box_hi,
                edge_stage.tmp, tables.group, tables.sweep_index, b.state, b.group,
            ]  # fmt: skip

    def call(self, edge_stage: EdgeDetector, frame: NDArray[np.uint8], sweep_px: float, n: int) -> int:
        """Split the `n`-point contour of `frame` (in the spans of `edge_stage`'s last detection) after a frame
        whose sweep was `sweep_px`; returns `split_frame`'s status (its outputs are in the buffers)."""
        state = self.buffers.state
        state[_STATE.last_sweep_px] = sweep_px
        state[_STATE.n] = n
        args = self._args
        assert args is not None
        args[6] = frame  # `split_frame` takes a writable or a read-only frame
        args[8], args[9] = edge_stage.spans
        return int(K.split_frame(*args[3:]))

    def one_call_key(self) -> tuple[tuple[Any, ...], WidthTables] | None:
        """The key and the width tables when the last split took this path (the pipeline's `SteadyFrame` makes
        the same `split_frame` call inside `steady_frame`); None when the next split would not."""
        if self.key is None or self._args is None:
            return None
        return self.key, self._args[0]
