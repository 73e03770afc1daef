"""Kernels of the Canny thresholds followed over a stream: the background's gradient magnitude sampled on a sparse
grid, a slice of the grid per frame, into a histogram whose median sets the thresholds (`EdgeThresholds.follow`).

The magnitude at a sample is the pipeline's own (`canny.detect_edges`): the frame smoothed by the separable
Gaussian `weights` (3x3 of smoothed values around the sample), then the 3x3 Sobel and its L2 norm. Samples stay
`len(weights) // 2 + 1` pixels inside the image, so no border is replicated.
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numba import float32, int64

from ropecam.device.pipeline._kernels._common import TWO, ZERO, f4_1d_ro
from ropecam.device.pipeline._kernels.tables import buffer1, buffer2, slot_frame, slot_frame_address, table_at
from ropecam.shared.jit import f4_2d, i4_1d, i4_1d_ro, kernel, u1_2d_ro

HIST_PER_UNIT: Final = 4
"""Histogram bins per unit of gradient magnitude (the median is read to 0.25 of the pipeline's magnitude scale,
where the thresholds are 2.5 and 4 times it: ~0.1 % at the lowest floor)."""


def _signature(frame_type: object) -> object:
    return int64(frame_type, f4_1d_ro, int64, int64, int64, f4_2d, i4_1d)


# Compiled for a read-only frame only: a writable frame (one a reader made) is taken through Numba's safe
# mutable-to-read-only conversion, at the dispatch cost of an exact match and with no view made per frame; a
# second, writable signature would cost its compilation again on every fresh install.
@kernel(_signature(u1_2d_ro))
def sample_gradient_histogram(frame, weights, row0, row_step, col_step, work, out_hist):
    """Add the gradient magnitude at the samples (rows ``row0, row0 + row_step, ...``, columns every `col_step`
    from the first one inside the margin) to `out_hist` (bin ``int(magnitude * HIST_PER_UNIT)``, the last bin
    holding everything above). `work` is scratch of at least (len(weights) + 2, 3). Returns the samples added
    (0 when the image is smaller than the stencil, -1 for a step < 1 or a scratch too small)."""
    radius = weights.shape[0] // 2
    rows = 2 * radius + 3
    if row_step < 1 or col_step < 1 or work.shape[0] < rows or work.shape[1] < 3:
        return -1
    height = frame.shape[0]
    width = frame.shape[1]
    margin = radius + 1
    bins = out_hist.shape[0]
    count = 0
    for r in range(max(row0, margin), height - margin, row_step):
        for c in range(margin, width - margin, col_step):
            # Horizontal smoothing of the rows r - 1 - radius .. r + 1 + radius at columns c - 1, c, c + 1 ...
            for k in range(rows):
                rr = r - 1 - radius + k
                for j in range(3):
                    acc = ZERO
                    for m in range(-radius, radius + 1):
                        acc += weights[m + radius] * frame[rr, c - 1 + j + m]
                    work[k, j] = acc
            # ... then vertical: s_ij at (r - 1 + i, c - 1 + j) is rows k = i .. i + 2 radius of the scratch.
            s00 = s01 = s02 = s10 = s12 = s20 = s21 = s22 = ZERO
            for m in range(2 * radius + 1):
                wm = weights[m]
                s00 += wm * work[m, 0]
                s01 += wm * work[m, 1]
                s02 += wm * work[m, 2]
                s10 += wm * work[m + 1, 0]
                s12 += wm * work[m + 1, 2]
                s20 += wm * work[m + 2, 0]
                s21 += wm * work[m + 2, 1]
                s22 += wm * work[m + 2, 2]
            gx = (s02 + TWO * s12 + s22) - (s00 + TWO * s10 + s20)
            gy = (s20 + TWO * s21 + s22) - (s00 + TWO * s01 + s02)
            mag = np.sqrt(gx * gx + gy * gy)
            b = int64(mag * float32(HIST_PER_UNIT))
            out_hist[min(b, bins - 1)] += 1
            count += 1
    return count


SAMPLE_BUFFERS: Final = (("frame_slot", np.int64, 1), ("weights", np.float32, 1), ("work", np.float32, 2),
                          ("hist", np.int32, 1))  # fmt: skip
"""The rows of `sample_slice`'s table: (name, dtype, dimensions), as `sample_gradient_histogram`'s arguments (the
frame slot's row: the slot's address, 1, height, width; `ropecam.device.pipeline._kernels.tables`)."""
_SAMPLE_FRAME, _SAMPLE_WEIGHTS, _SAMPLE_WORK, _SAMPLE_HIST = range(len(SAMPLE_BUFFERS))


@kernel(int64(int64, int64, int64, int64))
def sample_slice(table_address, row0, row_step, col_step):
    """`sample_gradient_histogram` of the frame in the frame slot, with the weights, scratch and histogram of the
    table at `table_address` (`SAMPLE_BUFFERS`): no array argument, so no Python allocation per call. Returns 0, or
    -2 (INVALID) when the slot holds no C-contiguous (height, width) frame (not the sample count: a Python int above
    256 is a new object)."""
    table = table_at(table_address, len(SAMPLE_BUFFERS))
    address = slot_frame_address(table, _SAMPLE_FRAME)
    if address == 0:
        return -2
    sampled = sample_gradient_histogram(
        slot_frame(table, _SAMPLE_FRAME, address), buffer1(table, _SAMPLE_WEIGHTS, np.float32), row0, row_step,
        col_step, buffer2(table, _SAMPLE_WORK, np.float32), buffer1(table, _SAMPLE_HIST, np.int32),
    )  # fmt: skip
    return min(sampled, 0)


@kernel(float32(i4_1d_ro))
def histogram_median(hist):
    """Return the median of the values a `sample_gradient_histogram` histogram holds (the middle of the median's
    bin, in magnitude units); -1 when it is empty."""
    total = int64(0)
    for b in range(hist.shape[0]):
        total += hist[b]
    if total == 0:
        return float32(-1.0)
    half = (total + 1) // 2
    seen = int64(0)
    for b in range(hist.shape[0]):
        seen += hist[b]
        if seen >= half:
            return float32((b + 0.5) / HIST_PER_UNIT)
    return float32((hist.shape[0] - 0.5) / HIST_PER_UNIT)


@kernel(float32(int64))
def sample_median(table_address):
    """`histogram_median` of the histogram of `sample_slice`'s table at `table_address` (no array argument: no
    Python allocation per call)."""
    return histogram_median(buffer1(table_at(table_address, len(SAMPLE_BUFFERS)), _SAMPLE_HIST, np.int32))
