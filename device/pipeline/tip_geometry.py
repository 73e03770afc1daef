"""The two split shapes' tips: their distance across the rope, and the correction of a slanted band end."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["correct_slant", "tip_lateral"]


def correct_slant(side_a: NDArray[np.float32], na: int, side_b: NDArray[np.float32], nb: int, gain_px: float) -> None:
    """Undo the bias of the half-level tips (the last points of the shapes `side_a`, `na` points, and `side_b`,
    `nb` points; moved in place) when the rope's end also moved along the rope (a whipping tip).

    Each tip read at its axis' half-level crossing lies ``gain_px * slope`` beyond its true end, the slope
    being the end track's along-per-across displacement seen from that shape (`BandEdgeModel.slant_gain`);
    seen from the other shape the slope has the other sign. The measured tips' along offset is therefore
    slope * (across - 2 gain): solved for the slope, both tips are moved back. Skipped when the tips are too
    close across (the slope would be ill-determined).
    """
    frame = _tip_frame(side_a, na, side_b, nb)
    if frame is None or not gain_px > 0:
        return
    u_r, u_c, d_r, d_c = frame
    along = d_r * u_r + d_c * u_c
    across = abs(d_r * u_c - d_c * u_r)
    if across - 2.0 * gain_px < 1.0:
        return
    shift = min(max(along / (across - 2.0 * gain_px), -1.5), 1.5) * gain_px
    side_a[na - 1, 0] -= shift * u_r
    side_a[na - 1, 1] -= shift * u_c
    side_b[nb - 1, 0] += shift * u_r
    side_b[nb - 1, 1] += shift * u_c


def _tip_frame(
    side_a: NDArray[np.float32], na: int, side_b: NDArray[np.float32], nb: int
) -> tuple[float, float, float, float] | None:
    """The mean tip direction (unit, from the last three points of both shapes) and the vector from tip A to
    tip B, as plain floats; None when a shape is too short or the direction undefined."""
    if na < 3 or nb < 3:
        return None
    (a3r, a3c), _, (a1r, a1c) = side_a[na - 3 : na].tolist()
    (b3r, b3c), _, (b1r, b1c) = side_b[nb - 3 : nb].tolist()
    u_r = a1r - a3r + b1r - b3r
    u_c = a1c - a3c + b1c - b3c
    norm = math.hypot(u_r, u_c)
    if norm <= 0.0:
        return None
    return u_r / norm, u_c / norm, b1r - a1r, b1c - a1c


def tip_lateral(side_a: NDArray[np.float32], na: int, side_b: NDArray[np.float32], nb: int) -> float:
    """Distance between the two fitted tips (the last points of `side_a`, `na` points, and `side_b`, `nb`
    points) across the rope (perpendicular to the mean tip direction)."""
    frame = _tip_frame(side_a, na, side_b, nb)
    if frame is None:
        return float("nan")
    u_r, u_c, d_r, d_c = frame
    return abs(d_r * u_c - d_c * u_r)
