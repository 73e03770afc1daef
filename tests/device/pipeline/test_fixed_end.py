"""The fixed end hidden inside a masked clamp (`hidden_end`): the rope's axis followed across the clamp."""

from __future__ import annotations

import numpy as np

from ropecam.device.pipeline.fixed_end import hidden_end


def _clamp_mask(shape: tuple[int, int], centre: tuple[int, int], half: tuple[int, int]) -> np.ndarray:
    """A clamp block's outline (3 px wide, as the learned mask marks an edge grown by a pixel) and two bolts'."""
    mask = np.zeros(shape, np.uint8)
    (r, c), (hr, hc) = centre, half
    mask[r - hr - 1 : r + hr + 2, c - hc - 1 : c + hc + 2] = 1
    mask[r - hr + 2 : r + hr - 1, c - hc + 2 : c + hc - 1] = 0
    rows, cols = np.mgrid[: shape[0], : shape[1]]
    for side in (-1, 1):
        d = np.hypot(rows - r, cols - (c + side * 0.55 * hc))
        mask[(d > 4.0) & (d < 7.0)] = 1  # a bolt head's edge
    return mask


def _rope_outline(r: float, c0: float, c1: float, width: float) -> np.ndarray:
    """The outline points (row, col) of a straight horizontal rope from column `c0` to `c1` at row `r`."""
    cols = np.arange(c0, c1, 0.5)
    upper = np.stack([np.full_like(cols, r - width / 2), cols], 1)
    lower = np.stack([np.full_like(cols, r + width / 2), cols[::-1]], 1)
    return np.concatenate([upper, lower]).astype(np.float32)


def test_a_rope_leaving_a_clamp_is_fixed_at_the_clamps_middle() -> None:
    """The rope leaves a 48 x 28 px clamp (with two bolts) at its right side: its end is put in the middle of the
    clamp along the rope, past the bolts, not where the rope is last seen."""
    mask = _clamp_mask((200, 300), (80, 100), (14, 24))
    points = _rope_outline(80.0, 126.0, 290.0, 2.5)
    end = np.array([80.0, 126.0], np.float32)
    found = hidden_end(end, points, 2.5, mask)
    assert np.hypot(*(found - np.array([80.0, 100.0]))) < 1.5


def test_an_end_away_from_the_mask_or_without_a_far_edge_is_kept() -> None:
    mask = _clamp_mask((200, 300), (80, 100), (14, 24))
    points = _rope_outline(80.0, 126.0, 290.0, 2.5)
    free = np.array([80.0, 289.5], np.float32)  # the free end: no mask next to it
    assert hidden_end(free, points, 2.5, mask) is free
    rod = np.zeros((200, 300), np.uint8)
    rod[76:85, :127] = 1  # a masked structure that runs to the image border: no far edge
    end = np.array([80.0, 126.0], np.float32)
    assert hidden_end(end, points, 2.5, rod) is end


def _outline(image: np.ndarray) -> np.ndarray:
    """The outer contour (row, col) float32 of the one blob in `image`."""
    import cv2

    contours, _ = cv2.findContours(image, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return contours[0][:, 0, ::-1].astype(np.float32)


def test_a_still_rope_joined_to_a_clamp_is_fixed_at_the_clamp_and_a_sweep_is_not() -> None:
    """A still rope's outline joined to a clamp block: the thick end is the fixed one (the narrower-end rule
    would take the free end). A sweeping rope's band (widening from a narrow fixed end) is left to that rule."""
    from ropecam.device.pipeline.fixed_end import _attached_structure

    image = np.zeros((120, 420), np.uint8)
    image[40:55, 18:43] = 1  # the clamp, 25 x 15 px
    image[46:49, 30:400] = 1  # the still rope, 3 px wide
    points = _outline(image)
    e1, e2 = int(np.argmin(points[:, 1])), int(np.argmax(points[:, 1]))
    assert _attached_structure(points, e1, e2, [points[e1], points[e2]], 3.0) == 0
    fan = np.zeros((120, 420), np.uint8)
    for col in range(30, 400):
        half = 1 + round(10 * (col - 30) / 370)  # the band widens to the swept tip
        fan[47 - half : 48 + half, col] = 1
    points = _outline(fan)
    e1, e2 = int(np.argmin(points[:, 1])), int(np.argmax(points[:, 1]))
    assert _attached_structure(points, e1, e2, [points[e1], points[e2]], 3.0) is None
