"""LensBlur: the band edge model the blur split uses, and the camera blur behind it, given or read from the image.

The split turns edge positions into the rope's positions with a band edge model (`BandEdgeModel`) of the camera's
lens blur and sharpening. Given in the config (`lens_blur_px`), that blur is used as it is; otherwise it is read
on the first frames of the blur split from the rope's own cross-section (`LensBlurEstimate`, in
`edge_profile.py`), and the model follows the readings' median.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline.config import DEFAULT_LENS_BLUR_PX
from ropecam.device.pipeline.edge_model import BandEdgeModel, shared_model
from ropecam.device.pipeline.edge_profile import EdgeBlur, LensBlurEstimate

__all__ = ["BLUR_TOLERANCE_PX", "WIDTH_AGREEMENT", "WIDTH_AGREEMENT_FLOOR_PX", "LensBlur"]

BLUR_TOLERANCE_PX = 0.1
"""The measured lens blur (px) or sharpening variance (px^2) replaces the model in use only beyond this change."""
WIDTH_AGREEMENT = 0.3
WIDTH_AGREEMENT_FLOOR_PX = 0.5
"""A frame's blur reading counts only when the rope width its edge model gives for the contour's edge spacing lies
within ``WIDTH_AGREEMENT`` x the bar width the same fit read off the cross-section, or within
``WIDTH_AGREEMENT_FLOOR_PX`` (`LensBlur.explains`). A rope moving more than its frame's tip sweep says (a
flexible rope's root swinging ahead of its tip) widens the profile: the fit takes the motion for lens blur, and
under that blur the still rope's edge spacing is the blur's own (simulated `lab-rolling`, tuning seed 4, 30 frames from
0.25 s: readings 0.86-0.94 px, the fit's bar 1.9-2.3 px, the model's rope for spacing 3.1 px 0.3-1.1 px; the rope
width then fell to the model's floor, 0.3 px, and the split returned empty shapes, every later frame `length`).
Readings of a still rope agree within 0.32 px (simulated `lab` from the release: 0.47-0.63 px, bar 2.1-2.2 px,
model 1.85-2.26 px)."""


class LensBlur:
    """Choose the band edge model of the split: from the given camera blur, or from the blur read on the first
    frames (`LensBlurEstimate`), `DEFAULT_LENS_BLUR_PX` until the first reading.

    Owns the model in use (`model`), the estimate while it reads (`estimate`) and what it measured (`measured`).
    Whoever derived something from the model makes it again when `use` or `read` returns True (`BlurSplitter`:
    its tables per width, its contrast, its one-call split's arguments).

    Parameters
    ----------
    weights
        The edge detector's Gaussian smoothing weights (float64; the model's own smoothing).
    lens_blur_px
        The camera blur (Gaussian sigma, px); None: read from the first frames.
    sharpen_gain, sharpen_sigma_px
        The camera's sharpening (unsharp mask) with a given `lens_blur_px` (ignored without one).
    read
        Whether to read the blur from the first frames when it is not given (the blur split's method only).
    """

    def __init__(
        self,
        weights: NDArray[np.float64],
        lens_blur_px: float | None,
        sharpen_gain: float = 0.0,
        sharpen_sigma_px: float = 1.0,
        read: bool = True,
    ) -> None:
        given = lens_blur_px is not None
        blur = EdgeBlur(lens_blur_px if given else DEFAULT_LENS_BLUR_PX, sharpen_gain if given else 0.0,
                        sharpen_sigma_px if given else 1.0)  # fmt: skip
        self.weights = weights
        self.model: BandEdgeModel = shared_model(weights, *blur)
        """The band edge model in use (its tables are built once per process: `shared_model`)."""
        self.estimate = None if given or not read else LensBlurEstimate()
        """The blur being read on the first frames (None: given, measured, or not read)."""
        self.measured: EdgeBlur | None = None
        """The lens blur and sharpening the first frames measured (None: given, or not measured yet)."""
        self._decoded = False
        self.model.rope_width(3.0)  # its width table (~20 ms) now, not on the first frames

    @property
    def value(self) -> EdgeBlur | None:
        """The lens blur and sharpening the first frames measured, or read so far (None: given, or none read)."""
        if self.measured is not None or self.estimate is None:
            return self.measured
        return self.estimate.value

    @property
    def decoded(self) -> bool:
        """Whether the frames are decoded through the camera's gamma before they are read
        (`LensBlurEstimate.decoded`: the camera's sharpening is then not read as an unsharp mask)."""
        return self._decoded

    @decoded.setter
    def decoded(self, value: bool) -> None:
        self._decoded = bool(value)
        if self.estimate is not None:
            self.estimate.decoded = self._decoded

    def restart(self) -> bool:
        """Read the blur again from the next frames, when it is read rather than given (the first readings were
        taken across a clamp's edges: `BlurSplitter.restart`); return whether the edge model changed (back to
        `DEFAULT_LENS_BLUR_PX` until the first new reading)."""
        if self.measured is None and self.estimate is None:
            return False
        self.estimate = LensBlurEstimate(decoded=self._decoded)
        self.measured = None
        return self.use(EdgeBlur(DEFAULT_LENS_BLUR_PX, 0.0, 1.0))

    def explains(self, blur: EdgeBlur, bar_width_px: float, edge_width_px: float) -> bool:
        """Whether the edge model of `blur` (rounded as `use` rounds it) turns the contour's edge spacing
        `edge_width_px` into a rope as wide as the bar the blur was read with (`bar_width_px`), within
        `WIDTH_AGREEMENT` (or `WIDTH_AGREEMENT_FLOOR_PX`)."""
        model = shared_model(self.weights, *_rounded(blur))
        gap = abs(model.rope_width(edge_width_px) - bar_width_px)
        return gap <= max(WIDTH_AGREEMENT * bar_width_px, WIDTH_AGREEMENT_FLOOR_PX)

    def use(self, blur: EdgeBlur, tolerance_px: float = 0.0) -> bool:
        """Use the edge model of `blur` (the lens blur rounded to 0.05 px, the sharpening to 0.1, so that
        pipelines share the models' tables: `shared_model`), unless the lens blur and the sharpening's variance
        (gain x sigma^2, px^2) of the model in use are within `tolerance_px` of it; return whether the model
        changed."""
        lens, gain, radius = _rounded(blur)
        model = self.model
        if (lens, gain, radius) == (model.lens_blur_px, model.sharpen_gain, model.sharpen_sigma_px):
            return False
        if (
            abs(lens - model.lens_blur_px) <= tolerance_px
            and abs(gain * radius**2 - model.sharpen_gain * model.sharpen_sigma_px**2) <= tolerance_px
        ):
            return False
        self.model = shared_model(self.weights, lens, gain, radius)
        return True

    def read(
        self,
        frame: NDArray[np.uint8],
        points: NDArray[np.float32],
        n: int,
        fixed_rc: tuple[float, float],
        edge_width_px: float,
        tip_sweep_px: float,
    ) -> bool:
        """Read the blur on one frame (`LensBlurEstimate.read`: its contour's `n` `points`, fixed end, the rope's
        edge spacing and the frame's tip sweep) while it is being measured; return whether the edge model
        changed (the frame is then to be split again)."""
        estimate = self.estimate
        if (
            estimate is None
            or estimate.read(frame, points, n, fixed_rc, edge_width_px, tip_sweep_px, self.explains) is None
        ):
            return False
        value = estimate.value
        assert value is not None
        if estimate.done:
            self.estimate = None
            self.measured = value
        # Each new model costs its tables (30-60 ms on the first frames): the readings' median changes it only
        # when it moves by more than `BLUR_TOLERANCE_PX` (below that the shapes move by < 0.02 px).
        return self.use(value, 0.0 if len(estimate.read_values) == 1 else BLUR_TOLERANCE_PX)


def _rounded(blur: EdgeBlur) -> tuple[float, float, float]:
    """The lens blur rounded to 0.05 px, the sharpening's gain and sigma to 0.1 (sigma 1 without sharpening): the
    edge model's key (`shared_model`)."""
    gain = round(max(float(blur.sharpen_gain), 0.0) * 10.0) / 10.0
    radius = round(float(blur.sharpen_sigma_px) * 10.0) / 10.0 if gain > 0.0 else 1.0
    return round(max(float(blur.lens_blur_px), 0.0) * 20.0) / 20.0, gain, radius
