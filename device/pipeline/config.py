"""Configuration of the rope pipeline (the ``[pipeline]`` table of ``device.toml``)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Literal

from ropecam.device.pipeline.checks import ChecksConfig
from ropecam.shared.config import check_in, check_positive, check_range
from ropecam.shared.errors import ConfigError

if TYPE_CHECKING:
    from ropecam.shared.plane import PlaneCalibration

__all__ = ["DEFAULT_LENS_BLUR_PX", "METHODS", "PipelineConfig"]

METHODS = ("blur_split", "paper", "centerline", "static")
DEFAULT_LENS_BLUR_PX = 0.5
"""The lens blur (px) the edge model assumes where it is neither given nor measured yet."""


@dataclass(frozen=True, slots=True)
class PipelineConfig:
    """Settings of edge detection, contour splitting and material point tracking.

    Parameters
    ----------
    method
        ``blur_split`` (default: subpixel edges, modelled inward offset, continuity ordering), ``paper`` (the
        paper's literal operator and Table 1 scoring on the integer chain) or ``centerline`` (centreline of the
        blurred region, one shape per frame) or ``static`` (always the static centreline: still scenes, photos).
    polarity
        ``bright`` rope on a dark background, ``dark`` rope on a bright one, or ``auto`` (decided per frame from
        the gradients along the contour).
    tip_cap
        Shape of the rope's free end: ``flat`` (default: a cut rope or cable ends where its axis ends) or
        ``round`` (the band's edge runs half a width beyond the axis end).
    smooth_sigma_px
        Gaussian smoothing before the Sobel gradient (0 disables it).
    gamma
        The camera's output curve, ``code = 255 (light / 255) ** (1 / gamma)`` (1: linear, the default; many cameras
        encode with 2.2 unless their gamma control is off): each frame is mapped back to linear light before its
        edges (`ropecam.device.pipeline.tone`), as the edge model assumes.
    lens_blur_px
        The camera's own blur (lens, focus; Gaussian sigma in px, the pixel's area apart) of the model of the
        blurred band's edge (`ropecam.device.pipeline.edge_model`). Not given: measured on the first frames from
        the rope's cross-section near the fixed end (`ropecam.device.pipeline.edge_profile`; 0.5 px until then),
        unless `rope_width_px` is given (the configured width is converted to an edge spacing with the model, so
        the model must not change: then 0.5 px). ``ropecam-device setup`` writes the measured value.
    sharpen_gain, sharpen_sigma_px
        The camera's sharpening (an unsharp mask ``p + gain (p - G * p)``, G a Gaussian of `sharpen_sigma_px`) of
        the edge model, with a given `lens_blur_px` (measured with it otherwise; setup writes them).
    canny_low, canny_high
        Hysteresis thresholds on the L2 Sobel magnitude of the smoothed image (grey levels x 8 per pixel).
    min_contour_px
        Smallest edge component accepted as a rope.
    roi_margin_px
        Half-width of the band processed around the previous contour (plus the previous frame's sweep).
    fixed_end_uv
        The fixed end (u, v) in pixels; found automatically over the first frames when not given.
    rope_width_px
        Rope diameter in pixels (the rope's, not its blurred edges' spacing: the edge model converts); estimated
        from the image when not given.
    rope_length_m
        Unstretched rope length; material points are given in metres of it.
    length0_px
        Unstretched rope length in pixels (Lc0); the median of the first `length0_frames` shapes when not given.
    length0_frames
        Number of shapes whose median length becomes Lc0.
    material_points_m
        Arc lengths (metres of unstretched rope from the fixed end) of the tracked material points.
    static_ratio
        Below this ratio of tip sweep to rope width the blur cannot be split: the centreline fallback is used
        (unless the body's own sweep reaches it: a whip's tip turning while a wave sweeps the body).
    corner_scale_px
        Chord length (contour points) of the turning angle used to find the segmentation points.
    paper_endpoint_radius_px
        Threshold T of the paper's Feature 3 (px; the paper prints 15).
    paper_endpoint_radius_scaled
        ``true``: T = max(`paper_endpoint_radius_px`, band width at the tip + rope width), since the segmentation
        points lie up to a band width (rope width + sweep) from the centreline's free end; ``false``: T as given.
    output_step_px
        Spacing of the output polylines.
    output_smoothing_px
        Half-width (pixels of arc length) of the smoothing of the output polylines: a local quadratic fit along the
        rope (LOESS) that removes pixel-scale measurement wiggles a real rope does not have, without shrinking the
        ends or flattening bends much longer than the window. 0 disables it. Larger values cost accuracy where
        the rope bends sharply (tight loops, a kink at a clamp).
    max_contour
        Capacity of the contour buffers (points).
    threshold_frames
        Frames on whose gradient magnitude the Canny thresholds are measured (`EdgeThresholds`: 2.5 and 4 times
        the median magnitude, at least 4 and 10, at most `canny_low` and `canny_high`); 0: `canny_low` and
        `canny_high` as given.
    threshold_update_frames
        After the first `threshold_frames`, the thresholds follow the frames slowly (a lamp warming up, a cloud,
        flicker, a gain change): every `threshold_sample_every`-th frame samples a slice of a sparse grid (~2048
        samples) of the gradient magnitude, and after `threshold_update_frames` slices the grid's median is
        averaged into the noise level (weight 0.25); the thresholds are set again when they move by more than 5 %.
        0: measured once.
    threshold_sample_every
        The frames between two slices of the followed thresholds' grid (1: a slice every frame). A slice costs
        ~30-45 us on a 1024x544 frame; the cycle is `threshold_update_frames` x `threshold_sample_every` frames.
    static_frames
        Frames over which the static mask is learned (each pixel's range of grey levels; pixels that stay within
        the noise are static structures: clamp, rod, plate edge, scratches, dust), whose edges are then dropped
        while they look as learned (only still pixels on an edge of the learned scene: the plain plate stays free).
        0: no learned mask. The rope must swing during these frames. The mask is marked on the next frame.
    static_margin_dn
        Grey levels beyond a static pixel's learned range at which it counts as changed (the rope is there).
    static_relative
        Part of a pixel's grey level that its learned range may span (flicker, shot noise) and still be static.
    static_mask_png
        A mask image of the frames' size (non-zero: never the rope; edges there are dropped from the first
        frame), or "" for none.
    background_png
        The static background (a 16-bit PNG of linear light x 256, written by ``ropecam-device setup`` for a
        textured background), or "" for none: its texture is divided out of each frame before the edges
        (`ropecam.device.pipeline.background`).
    plane_file
        A plane calibration (``plane.yaml`` of ``ropecam calibrate plane``, read by the application with
        `ropecam.shared.plane.read_plane_file`): the fixed end is then its origin projected into the image (unless
        `fixed_end_uv` is given) and material points are placed by arc length on the plane. None: no calibration.
    checks
        The self-checks' thresholds (the ``[pipeline.checks]`` table, `ChecksConfig`).
    """

    method: Literal["blur_split", "paper", "centerline", "static"] = "blur_split"
    polarity: Literal["auto", "bright", "dark"] = "auto"
    tip_cap: Literal["round", "flat"] = "flat"
    smooth_sigma_px: float = 1.0
    gamma: float = 1.0
    lens_blur_px: float | None = None
    sharpen_gain: float = 0.0
    sharpen_sigma_px: float = 1.0
    canny_low: float = 20.0
    canny_high: float = 50.0
    min_contour_px: int = 40
    roi_margin_px: int = 4
    fixed_end_uv: tuple[float, float] | None = None
    rope_width_px: float | None = None
    rope_length_m: float = 1.0
    length0_px: float | None = None
    length0_frames: int = 5
    material_points_m: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0)
    static_ratio: float = 0.6
    corner_scale_px: int = 3
    paper_endpoint_radius_px: float = 15.0
    paper_endpoint_radius_scaled: bool = True
    output_step_px: float = 2.0
    output_smoothing_px: float = 24.0
    max_contour: int = 40_000
    threshold_frames: int = 1
    threshold_update_frames: int = 16
    threshold_sample_every: int = 4
    static_frames: int = 10
    static_margin_dn: int = 3
    static_relative: float = 0.1
    static_mask_png: str = ""
    background_png: str = ""
    plane_file: str | None = None
    checks: ChecksConfig = field(default_factory=ChecksConfig)

    @property
    def edge_blur_given(self) -> tuple[float, float, float] | None:
        """The edge model's (lens blur, sharpening gain, its sigma) when they are not to be measured (given, or
        `DEFAULT_LENS_BLUR_PX` and no sharpening when only `rope_width_px` is given); None: measure them."""
        if self.lens_blur_px is None:
            return None if self.rope_width_px is None else (DEFAULT_LENS_BLUR_PX, 0.0, 1.0)
        return (self.lens_blur_px, self.sharpen_gain, self.sharpen_sigma_px)

    def on_plane(self, plane: PlaneCalibration, image_size: tuple[int, int]) -> PipelineConfig:
        """Return this config for frames of `image_size` (width, height) on the calibrated `plane`: the fixed end
        the plane origin projected into the image, unless `fixed_end_uv` gives it.

        Raises
        ------
        ConfigError
            The plane was calibrated at another image size, or its origin projects outside the image.
        """
        width, height = image_size
        if tuple(plane.image_size) != (width, height):
            raise ConfigError(
                f"{plane.source}: calibrated for {plane.image_size[0]}x{plane.image_size[1]} images, the frames "
                f"are {width}x{height}; expected a plane calibration of this camera at this resolution"
            )
        plane.check_image((width, height))
        return self if self.fixed_end_uv is not None else replace(self, fixed_end_uv=plane.origin_uv())

    def __post_init__(self) -> None:
        check_in("method", self.method, METHODS)
        check_in("polarity", self.polarity, ("auto", "bright", "dark"))
        check_in("tip_cap", self.tip_cap, ("round", "flat"))
        check_range("smooth_sigma_px", self.smooth_sigma_px, 0.0, 5.0)
        check_range("gamma", self.gamma, 1.0, 3.0)
        if self.lens_blur_px is not None:
            check_range("lens_blur_px", self.lens_blur_px, 0.0, 5.0)
        check_range("sharpen_gain", self.sharpen_gain, 0.0, 5.0)
        check_range("sharpen_sigma_px", self.sharpen_sigma_px, 0.3, 4.0)
        check_positive("canny_low", self.canny_low)
        check_positive("canny_high", self.canny_high)
        if self.canny_high < self.canny_low:
            raise ConfigError(f"canny_high must be >= canny_low, got {self.canny_high} < {self.canny_low}")
        check_range("min_contour_px", self.min_contour_px, 4, 1_000_000)
        check_range("roi_margin_px", self.roi_margin_px, 2, 1000)
        if self.fixed_end_uv is not None:
            for value in self.fixed_end_uv:
                check_range("fixed_end_uv", value, -1e6, 1e6)
        if self.rope_width_px is not None:
            check_range("rope_width_px", self.rope_width_px, 0.1, 500.0)
        check_positive("rope_length_m", self.rope_length_m)
        if self.length0_px is not None:
            check_positive("length0_px", self.length0_px)
        check_range("length0_frames", self.length0_frames, 1, 10_000)
        for value in self.material_points_m:
            check_range("material_points_m", value, 0.0, self.rope_length_m)
        check_range("static_ratio", self.static_ratio, 0.0, 100.0)
        check_range("corner_scale_px", self.corner_scale_px, 1, 50)
        check_positive("paper_endpoint_radius_px", self.paper_endpoint_radius_px)
        if not isinstance(self.paper_endpoint_radius_scaled, bool):
            raise ConfigError(
                f"paper_endpoint_radius_scaled must be true or false, got {self.paper_endpoint_radius_scaled!r}"
            )
        check_range("output_step_px", self.output_step_px, 0.25, 100.0)
        check_range("output_smoothing_px", self.output_smoothing_px, 0.0, 200.0)
        check_range("max_contour", self.max_contour, 100, 10_000_000)
        check_range("threshold_frames", self.threshold_frames, 0, 10_000)
        check_range("threshold_update_frames", self.threshold_update_frames, 0, 100_000)
        check_range("threshold_sample_every", self.threshold_sample_every, 1, 10_000)
        check_range("static_frames", self.static_frames, 0, 10_000)
        check_range("static_margin_dn", self.static_margin_dn, 0, 255)
        check_range("static_relative", self.static_relative, 0.0, 1.0)
        if not isinstance(self.static_mask_png, str):
            raise ConfigError(f'static_mask_png must be a file path or "", got {self.static_mask_png!r}')
        if not isinstance(self.background_png, str):
            raise ConfigError(f'background_png must be a file path or "", got {self.background_png!r}')
        if self.plane_file is not None and (not isinstance(self.plane_file, str) or not self.plane_file):
            raise ConfigError(f"plane_file must be the path of a plane.yaml, got {self.plane_file!r}")
        if not isinstance(self.checks, ChecksConfig):
            raise ConfigError(f"checks must be a ChecksConfig ([pipeline.checks] table), got {self.checks!r}")
