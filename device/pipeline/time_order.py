"""TimeOrder: which of a frame's two shapes is the rope at the start of the exposure, by continuity of the tip."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K

__all__ = ["TimeOrder"]

_DEFAULT_PERIOD_NS = 25_000_000
"""Frame period assumed before two frames have been seen (40 FPS)."""


class TimeOrder:
    """Put the two shapes of each frame in time order by continuity with the previous frames.

    The tips of the last three frames (two time samples each: start and end of the exposure) give a least-squares
    constant-acceleration fit of the tip's path (constant velocity from one frame); it predicts the tip at this
    frame's start and end, and the pairing of the two shapes with those predictions that fits better wins. A
    swinging rope reverses every half period: across the gap between frames (several exposures long at low frame
    rates) a constant velocity overshoots there, a constant acceleration does not. The logic is the kernel
    `order_shapes`; this class holds its state arrays.
    """

    __slots__ = ("_out", "hist_rc", "hist_t", "state")

    def __init__(self) -> None:
        self.hist_t = np.zeros(K.HISTORY, np.int64)
        self.hist_rc = np.zeros((K.HISTORY, 2), np.float64)
        self.state = np.zeros(3, np.int64)  # samples held, history ordered, rejects in a row
        self._out = np.zeros(1, np.float64)

    def clear(self) -> None:
        """Forget the history (the next split frame starts it again, with confidence 0.5)."""
        self.state[0] = 0
        self.state[1] = 0

    @property
    def samples(self) -> list[tuple[int, tuple[float, float]]]:
        """The remembered tip samples (t_ns, (row, col)), oldest first (for inspection and tests)."""
        count = int(self.state[0])
        return [
            (int(t), (float(r), float(c))) for t, (r, c) in zip(self.hist_t[:count], self.hist_rc[:count], strict=True)
        ]

    def order(
        self, a: NDArray[np.float32], b: NDArray[np.float32], t_ns: int, t_end_ns: int | None, period_ns: int | None
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], float]:
        """Return (begin, end, confidence) for the shapes `a` and `b` (the same array for a single shape) of the
        frame exposed from `t_ns` to `t_end_ns` (ns; None or not later: exposure unknown, no order, confidence
        0.5, nothing remembered). A history older than four frame periods (`period_ns`, None: unknown) is
        dropped first.

        Raises
        ------
        ValueError
            When a shape has no point.
        """
        if t_end_ns is None or t_end_ns <= t_ns:
            # Exposure unknown: the two shapes carry the same time, nothing can say which came first, and their
            # tips would put two different positions at one time into the history.
            return a, b, (1.0 if a is b else 0.5)
        single = a is b
        # The kernel takes writable arrays (the splitter's buffers); a read-only shape is copied (never per frame).
        ka = a if a.flags.writeable else a.copy()
        kb = ka if single else (b if b.flags.writeable else b.copy())
        swap = K.order_shapes(
            ka, kb, np.int32(single), t_ns, t_end_ns, 4 * (period_ns or _DEFAULT_PERIOD_NS),
            self.hist_t, self.hist_rc, self.state, self._out,
        )  # fmt: skip
        if swap < 0:
            raise ValueError(f"cannot order shapes of {len(a)} and {len(b)} points")
        confidence = float(self._out[0])
        return (b, a, confidence) if swap else (a, b, confidence)
