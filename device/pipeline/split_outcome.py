"""The result of one `BlurSplitter.split`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline.result import Method

__all__ = ["SplitOutcome"]


@dataclass(slots=True)
class SplitOutcome:
    """The shapes found in one contour (views into the splitter's buffers, valid until its next call).

    `shape_a` and `shape_b` run from the fixed end to the tip; for single-shape methods they are the same array.
    They are not yet in time order: the pipeline decides which one is the start of the exposure.
    """

    method: Method
    shape_a: NDArray[np.float32]
    shape_b: NDArray[np.float32]
    segmentation_points: NDArray[np.float32] | None
    width_px: float
    sweep_px: float
