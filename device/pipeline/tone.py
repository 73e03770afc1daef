"""The camera's gamma undone before the edges: the edge model (`edge_model`) describes a rope's blurred band in
linear light, and a camera's output curve bends it.

A camera that encodes ``code = 255 (light / 255) ** (1 / gamma)`` brightens every partly covered pixel of a bright
rope on a dark plate: the band's edges move outwards, a 2 mm rope reads 2.7 px wide instead of 1.95 and the tips of
a blurred band land too far apart. Measured on the simulated `lab` preset (gamma 2.2, 60 frames, tuning seed, the
set-up config with the true width): tip mean 0.49 px as the camera gives it, 0.33 px with the same scene rendered
linear. `ToneCurve` maps each frame back through the curve's inverse (a 256-entry table, one pass over the frame)
before anything else reads it; ``gamma = 1`` (the default: most machine-vision cameras have the curve off) skips it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._views import FrameSlot, array_layout_known, buffer_table

__all__ = ["ToneCurve"]


class ToneCurve:
    """The inverse of a camera's gamma curve, applied to frames of one size into one buffer.

    `take` takes each frame of a stream: its kernel (`K.take_frame`) reads the frame through a slot and the table
    and buffer through a table of their addresses, so that the call has no array argument (each costs Numba's
    wrapper a 48-byte MemInfo of Python allocation) and checks the frame's size and layout without making Python
    ints of its shape.
    """

    __slots__ = ("_address", "_buffers", "_mapped", "_out", "_slot", "gamma", "table")

    def __init__(self, gamma: float, shape: tuple[int, int]) -> None:
        """`gamma` >= 1 (1: linear, nothing to undo), frames of `shape` (height, width)."""
        self.gamma = float(gamma)
        codes = np.arange(256, dtype=np.float64) / 255.0
        self.table = np.round(255.0 * codes**self.gamma).astype(np.uint8)
        """Code -> linear light (0-255, rounded)."""
        self._out = np.zeros(shape, np.uint8)
        self._mapped = self.gamma != 1.0
        self._slot = FrameSlot(*shape)
        self._buffers = buffer_table({"frame_slot": self._slot, "table": self.table, "out": self._out}, K.TONE_BUFFERS)
        self._address = int(self._buffers.ctypes.data) if array_layout_known() else 0

    def take(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8] | None:
        """Return the uint8 `frame` in linear light as `apply` does when it is a C-contiguous array of the curve's
        shape; None for any other frame (nothing done)."""
        if not self._address:  # NumPy's array layout is not the one the kernel reads: as arguments
            if frame.shape != self._out.shape or not frame.flags.c_contiguous:
                return None
            return self.apply(frame)
        self._slot.hold(frame)
        try:
            taken = K.take_frame(self._address, self._mapped)
        finally:
            self._slot.release()
        if taken == K.FRAME_AS_GIVEN:
            return frame
        return self._out if taken == K.FRAME_MAPPED else None

    def apply(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """Return `frame` in linear light: `frame` itself when the curve is linear, else this curve's buffer (valid
        until the next call). `frame` has the shape the curve was made for."""
        if self.gamma == 1.0:
            return frame
        if K.apply_table(frame, self.table, self._out) != 0:
            raise ValueError(f"frame of shape {frame.shape} for a tone curve of frames {self._out.shape}")
        return self._out
