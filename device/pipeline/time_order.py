"""TimeOrder: which of a frame's two shapes is the rope at the start of the exposure, by continuity of the tip."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline.workspace import OrderBuffers, expose

__all__ = ["DEFAULT_PERIOD_NS", "TimeOrder"]

DEFAULT_PERIOD_NS = 25_000_000
"""Frame period assumed before two frames have been seen (40 FPS)."""


@expose("buffers", OrderBuffers)
class TimeOrder:
    """Put the two shapes of each frame in time order by continuity with the previous frames.

    The tips of the last three frames (two time samples each: start and end of the exposure) give a least-squares
    constant-acceleration fit of the tip's path (constant velocity from one frame); it predicts the tip at this
    frame's start and end, and the pairing of the two shapes with those predictions that fits better wins. A
    swinging rope reverses every half period: across the gap between frames (several exposures long at low frame
    rates) a constant velocity overshoots there, a constant acceleration does not. The logic is the kernel
    `order_shapes`; this class holds its state arrays.
    """

    __slots__ = ("buffers",)

    def __init__(self, buffers: OrderBuffers | None = None) -> None:
        self.buffers = buffers if buffers is not None else OrderBuffers.make()
        """(each also a read-only attribute) ``state``: sample times (ns), then [samples held, history ordered
        (0/1), rejects in a row] (`K.ORDER_*`); ``hist_rc``: sample tips (row, col)."""

    def clear(self) -> None:
        """Forget the history (the next split frame starts it again, with confidence 0.5)."""
        self.state[K.ORDER_COUNT] = 0
        self.state[K.ORDER_ORDERED] = 0

    @property
    def samples(self) -> list[tuple[int, tuple[float, float]]]:
        """The remembered tip samples (t_ns, (row, col)), oldest first (for inspection and tests)."""
        count = int(self.state[K.ORDER_COUNT])
        times, tips = self.state[:count].tolist(), self.hist_rc[:count].tolist()
        return [(t, (r, c)) for t, (r, c) in zip(times, tips, strict=True)]

    def order(
        self, a: NDArray[np.float32], b: NDArray[np.float32], t_ns: int, t_end_ns: int | None, period_ns: int | None
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], float]:
        """Return (begin, end, confidence) for the shapes `a` and `b` (float32 (n, 2), fixed end first; the same
        array for a single shape) of the frame exposed from `t_ns` to `t_end_ns` (ns; None or not later: exposure
        unknown, no order, confidence 0.5, nothing remembered). A history older than four frame periods
        (`period_ns`, None: unknown) is dropped first.

        Raises
        ------
        ValueError
            When a shape has no point.
        """
        if t_end_ns is None or t_end_ns <= t_ns:
            # Exposure unknown: the two shapes carry the same time, nothing can say which came first, and their
            # tips would put two different positions at one time into the history.
            return a, b, (1.0 if a is b else 0.5)
        max_age_ns = 4 * (period_ns or DEFAULT_PERIOD_NS)
        try:
            swap, confidence = K.order_shapes(a, b, a is b, t_ns, t_end_ns, max_age_ns, self.state, self.hist_rc)
        except TypeError:
            # Not the splitter's writable float32 buffers (a read-only or other array): order copies of them.
            ka = np.array(a, np.float32)
            kb = ka if a is b else np.array(b, np.float32)
            swap, confidence = K.order_shapes(ka, kb, a is b, t_ns, t_end_ns, max_age_ns, self.state, self.hist_rc)
        if swap < 0:
            raise ValueError(f"cannot order shapes of {len(a)} and {len(b)} points")
        return (b, a, confidence) if swap else (a, b, confidence)
