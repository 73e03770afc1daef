"""The lens blur read off a still rope's cross-section (`edge_profile`) recovers the blur it was rendered with."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticRope
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.edge_model import normal_cdf
from ropecam.device.pipeline.edge_profile import LensBlurEstimate, fit_bar_profile, read_cross_section
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.shared.errors import ConfigError

from .conftest import distance_to_polyline


def _unsharp(image: np.ndarray, gain: float, sigma_px: float) -> np.ndarray:
    """``image + gain (image - G * image)``, G a separable Gaussian of `sigma_px` (the border repeated)."""
    radius = math.ceil(4.0 * sigma_px)
    taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma_px) ** 2)
    taps /= taps.sum()
    blurred = image
    for axis in (0, 1):
        padded = np.pad(blurred, [(radius, radius) if a == axis else (0, 0) for a in (0, 1)], mode="edge")
        size = image.shape[axis]
        blurred = sum(w * np.take(padded, np.arange(k, k + size), axis=axis) for k, w in enumerate(taps))
    return image + gain * (image - blurred)


def _still_rope(
    lens_px: float, width_px: float, angle_deg: float, noise_dn: float, seed: int, sharpen: float = 0.0
) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """A straight still rope from (10.3, 60.6) at `angle_deg` from the image's rows, rendered as the simulator
    renders an edge (a Gaussian of the lens and the pixel's area, sqrt(lens^2 + 1/12)); and its two edges as a
    contour would give them (points on both sides, the fixed end's cap first)."""
    height, width = 120, 120
    fixed = (10.3, 60.6)
    theta = math.radians(angle_deg)
    along = np.array([math.cos(theta), math.sin(theta)])  # (row, col)
    across = np.array([-along[1], along[0]])
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)
    x = (rows - fixed[0]) * across[0] + (cols - fixed[1]) * across[1]
    t = (rows - fixed[0]) * along[0] + (cols - fixed[1]) * along[1]
    sigma = math.sqrt(lens_px**2 + 1.0 / 12.0)
    bar = normal_cdf((x + 0.5 * width_px) / sigma) - normal_cdf((x - 0.5 * width_px) / sigma)
    bar *= np.clip(t, 0.0, 1.0) * np.clip(95.0 - t, 0.0, 1.0)
    image = _unsharp(30.0 + 150.0 * bar, sharpen, 1.0) + np.random.default_rng(seed).normal(0.0, noise_dn, bar.shape)
    frame = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    s = np.arange(0.5, 95.0, 1.0)
    half = 0.5 * max(width_px, 2.0 * sigma)
    side_a = np.asarray(fixed) + s[:, None] * along + half * across
    side_b = np.asarray(fixed) + s[::-1, None] * along - half * across
    points = np.concatenate([side_a, side_b]).astype(np.float32)
    return frame, points, fixed


def test_the_bar_fit_recovers_width_and_blur_of_an_exact_profile() -> None:
    x = np.linspace(-6.0, 6.0, 400)
    values = 20.0 + 0.5 * x + 140.0 * (normal_cdf((x + 1.25) / 0.9) - normal_cdf((x - 1.25) / 0.9))
    fit = fit_bar_profile(x, values, 3.0)
    assert fit is not None
    assert fit.width_px == pytest.approx(2.5, abs=0.01)
    assert fit.sigma_px == pytest.approx(0.9, abs=0.01)
    assert fit.contrast == pytest.approx(140.0, rel=0.01)


@pytest.mark.parametrize("lens_px", [0.4, 1.2, 2.0])
@pytest.mark.parametrize("angle_deg", [7.0, 38.0])
def test_the_estimate_recovers_the_rendered_lens_blur(lens_px: float, angle_deg: float) -> None:
    estimate = LensBlurEstimate(readings=3)
    for seed in range(3):
        frame, points, fixed = _still_rope(lens_px, 2.5, angle_deg, 2.0, seed)
        spacing = 2.5 if lens_px < 1.0 else 2.0 * math.sqrt(lens_px**2 + 1.0 / 12.0)
        assert estimate.read(frame, points, len(points), fixed, spacing, 0.0) is not None
    assert estimate.done
    assert estimate.value is not None
    assert estimate.value.lens_blur_px == pytest.approx(lens_px, abs=0.12)
    assert estimate.value.sharpen_gain == 0.0  # none read: a plain blurred bar


@pytest.mark.parametrize("gain", [0.5, 1.0])
def test_the_estimate_reads_a_cameras_sharpening(gain: float) -> None:
    """An unsharp mask (sigma 1 px) after a 0.5 px lens blur: its share of the edge's variance (gain sigma^2)
    and the lens blur are recovered (the two trade off a little against each other)."""
    estimate = LensBlurEstimate(readings=3)
    for seed in range(3):
        frame, points, fixed = _still_rope(0.5, 2.5, 23.0, 1.0, seed, sharpen=gain)
        assert estimate.read(frame, points, len(points), fixed, 2.6, 0.0) is not None
    value = estimate.value
    assert value is not None
    assert value.sharpen_gain * value.sharpen_sigma_px**2 == pytest.approx(gain, rel=0.3)
    assert value.lens_blur_px == pytest.approx(0.5, abs=0.15)


def test_a_moving_rope_is_not_read() -> None:
    frame, points, fixed = _still_rope(1.0, 2.5, 20.0, 1.0, 0)
    estimate = LensBlurEstimate()
    # A tip sweep of 40 px moves the stretch near the fixed end by more than a pixel.
    assert estimate.read(frame, points, len(points), fixed, 3.0, 40.0) is None
    assert estimate.value is None


def test_one_edge_only_is_no_cross_section() -> None:
    frame, points, fixed = _still_rope(1.0, 2.5, 20.0, 1.0, 0)
    one_side = np.ascontiguousarray(points[: len(points) // 2])
    assert read_cross_section(frame, one_side, len(one_side), fixed, 3.0) is None


def _shape_error(result, frame) -> float:
    """The worse of a frame's two shapes' curve errors (px), in the better of the two time orders (the first
    frames' time order is a guess)."""
    pairs = ((result.begin, frame.begin_uv), (result.end, frame.end_uv))
    swapped = ((result.begin, frame.end_uv), (result.end, frame.begin_uv))
    return min(
        max(float(distance_to_polyline(ours[:, ::-1], truth).mean()) for ours, truth in pairs),
        max(float(distance_to_polyline(ours[:, ::-1], truth).mean()) for ours, truth in swapped),
    )


def test_the_pipeline_measures_the_blur_and_splits_with_it() -> None:
    """A rope under a 1.5 px lens blur, still on the first frames (released at the top of its swing): the
    pipeline measures the blur there, and its shapes of the moving rope that follows are as good as with the
    true blur given; with the blur assumed 0.5 px they lie 0.8-1 px off (the still rope's blurred edges read
    as a rope twice as wide, its low edge slope as a sweep; over a pixel before the rope's own contrast along the
    band, `contrast_gains`, whose readings under this blur differ from the frame's)."""
    rope = SyntheticRope(
        width=200, height=170, fixed_uv=(100.3, 12.6), length_px=140.0, diameter_px=2.5, blur_px=1.5,
        amplitude_rad=0.5, period_s=0.9, phase_rad=0.0, noise_dn=1.0, exposure_us=4000,
    )  # fmt: skip
    frames = list(rope.frames(12))
    errors = {}
    for name, lens_blur_px in (("measured", None), ("assumed", 0.5), ("true", 1.5)):
        pipeline = Pipeline(PipelineConfig(lens_blur_px=lens_blur_px), (rope.width, rope.height))
        errors[name] = []
        for frame in frames:
            result = pipeline.process(frame.image, frame.index, frame.t_ns, float(rope.exposure_us))
            assert result.begin is not None and result.end is not None
            errors[name].append(_shape_error(result, frame))
        if name == "measured":
            assert pipeline.splitter.blur_measured is not None
            assert pipeline.splitter.blur_measured.lens_blur_px == pytest.approx(1.5, abs=0.15)
            assert pipeline.splitter.model.lens_blur_px == pytest.approx(1.5, abs=0.15)
    measured, assumed, true = (np.asarray(errors[k]) for k in ("measured", "assumed", "true"))
    assert np.all(measured <= true + 0.1), (measured, true)  # the first readings' median moves a little
    assert np.mean(measured) <= np.mean(true) + 0.02
    assert np.all(assumed > true + 0.4), (assumed, true)


def test_the_pipeline_measures_a_cameras_sharpening_and_splits_with_it() -> None:
    """The rope of the blur test under a 0.5 px blur, then a camera's unsharp mask (gain 1, sigma 1 px): the
    pipeline reads the sharpening (its share of the edge's variance, gain sigma^2) and its shapes are as good as
    with the true edge profile given. (This rope sweeps more than its width from the second frame on, where the
    profile hardly matters; the matrix's sharpening rows show the gain where it reads the sweep from the edge
    slope: 0.27 -> 0.08 px tip mean at gain 1.)"""
    rope = SyntheticRope(
        width=200, height=170, fixed_uv=(100.3, 12.6), length_px=140.0, diameter_px=2.5, blur_px=0.5,
        amplitude_rad=0.5, period_s=0.9, phase_rad=0.0, noise_dn=0.0, exposure_us=4000,
    )  # fmt: skip
    rng = np.random.default_rng(3)
    frames = list(rope.frames(12))
    images = [
        np.clip(
            np.rint(_unsharp(f.image.astype(np.float64), 1.0, 1.0) + rng.normal(0.0, 1.0, f.image.shape)), 0, 255
        ).astype(np.uint8)
        for f in frames
    ]
    configs = {
        "measured": PipelineConfig(),
        "true": PipelineConfig(lens_blur_px=0.5, sharpen_gain=1.0, sharpen_sigma_px=1.0),
    }
    errors = {}
    for name, config in configs.items():
        pipeline = Pipeline(config, (rope.width, rope.height))
        errors[name] = []
        for frame, image in zip(frames, images, strict=True):
            result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
            assert result.begin is not None and result.end is not None
            errors[name].append(_shape_error(result, frame))
        if name == "measured":
            blur = pipeline.splitter.blur_measured
            assert blur is not None
            assert blur.sharpen_gain * blur.sharpen_sigma_px**2 == pytest.approx(1.0, rel=0.4)
    measured, true = (np.mean(errors[k]) for k in ("measured", "true"))
    assert measured <= true + 0.03, (measured, true)


def test_the_config_says_when_the_blur_is_measured() -> None:
    assert PipelineConfig().edge_blur_given is None  # measured
    assert PipelineConfig(rope_width_px=2.5).edge_blur_given == (0.5, 0.0, 1.0)  # the width's model is fixed
    given = PipelineConfig(lens_blur_px=0.7, sharpen_gain=0.8, sharpen_sigma_px=1.2)
    assert given.edge_blur_given == (0.7, 0.8, 1.2)
    with pytest.raises(ConfigError, match="sharpen_gain"):
        PipelineConfig(sharpen_gain=-1.0)


def test_a_decoded_frame_is_read_without_the_cameras_sharpening() -> None:
    """A 2 px dark rope on a bright plate (linear levels 12 and 150, lens blur 0.6 px) through a camera's gamma
    2.2 and then its unsharp mask (gain 0.8, sigma 1 px), as the simulated `lab-dark` is made; the pipeline
    decodes the frames (``gamma = 2.2``). In the decoded frame the mask's halos are no unsharp mask: read as one,
    the model expects steeper still edges than the frame shows, reads the slow rope's edges as sweeping and puts
    its two shapes on the band's edges (0.55-0.67 px off). The reading is the plain blurred bar's: no sharpening."""
    rope = SyntheticRope(
        width=200, height=170, fixed_uv=(100.3, 12.6), length_px=140.0, diameter_px=2.0, blur_px=0.6,
        amplitude_rad=0.5, period_s=1.8, phase_rad=0.0, noise_dn=0.0, exposure_us=1000, background=150.0,
        rope_level=12.0,
    )  # fmt: skip
    rng = np.random.default_rng(3)
    frames = list(rope.frames(12))
    images = []
    for frame in frames:
        code = 255.0 * (frame.image.astype(np.float64) / 255.0) ** (1.0 / 2.2)
        noisy = _unsharp(code, 0.8, 1.0) + rng.normal(0.0, 1.0, code.shape)
        images.append(np.clip(np.rint(noisy), 0, 255).astype(np.uint8))
    errors = {}
    for decoded in (True, False):
        pipeline = Pipeline(PipelineConfig(gamma=2.2), (rope.width, rope.height))
        estimate = pipeline.splitter.lens.estimate
        assert estimate is not None and estimate.decoded
        estimate.decoded = decoded  # False: read as before the rule
        errors[decoded] = []
        for frame, image in zip(frames, images, strict=True):
            result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
            assert result.begin is not None and result.end is not None
            errors[decoded].append(_shape_error(result, frame))
        blur = pipeline.splitter.blur_measured
        assert blur is not None
        if decoded:
            assert blur.sharpen_gain == 0.0
            assert 0.2 <= blur.lens_blur_px <= 0.8
        else:
            assert blur.sharpen_gain > 0.0
    assert np.mean(errors[True]) < 0.15, errors[True]
    assert np.mean(errors[False]) > np.mean(errors[True]) + 0.2, errors  # the rule is what makes the difference


def _decoded_dark_rope(blur_px: float, seed: int) -> tuple[SyntheticRope, list, list[np.ndarray]]:
    """A 2 px dark rope on a bright plate (linear 12 and 150) swinging from rest (period 0.4 s, 4 ms exposures:
    sweeps of 0-5 px), through a camera's gamma 2.2 and then its unsharp mask (0.8, sigma 1 px): `lab-dark`'s
    processing; 24 frames and their camera codes."""
    rope = SyntheticRope(
        width=200, height=170, fixed_uv=(100.3, 12.6), length_px=140.0, diameter_px=2.0, blur_px=blur_px,
        amplitude_rad=0.5, period_s=0.4, phase_rad=0.0, noise_dn=0.0, exposure_us=4000, background=150.0,
        rope_level=12.0,
    )  # fmt: skip
    rng = np.random.default_rng(seed)
    frames = list(rope.frames(24))
    images = []
    for frame in frames:
        code = 255.0 * (frame.image.astype(np.float64) / 255.0) ** (1.0 / 2.2)
        noisy = _unsharp(code, 0.8, 1.0) + rng.normal(0.0, 1.0, code.shape)
        images.append(np.clip(np.rint(noisy), 0, 255).astype(np.uint8))
    return rope, frames, images


def test_a_decoded_frames_blur_is_the_plain_bar_it_shows() -> None:
    """The decoded frame's halos steepen a dark rope's edges beyond what its lens blur makes: an edge model with
    the lens's blur (0.8 px rendered; 0.67 px is what a sharpened bar's fit read, its sharpening dropped, before
    this rule) expects gentler still edges than the frame shows, reads a sweep of a few pixels as a smaller one
    and pulls both shapes towards the band's middle (simulated `lab-dark`, tuning seed: 0.05-0.3 px inwards on
    every frame). The plain bar's fit reads the blur the frame shows, and the shapes are placed better."""
    rope, frames, images = _decoded_dark_rope(0.8, 3)
    errors = {}
    for given in (None, 0.67):
        pipeline = Pipeline(PipelineConfig(gamma=2.2, lens_blur_px=given), (rope.width, rope.height))
        errors[given] = []
        for frame, image in zip(frames, images, strict=True):
            result = pipeline.process(image, frame.index, frame.t_ns, float(rope.exposure_us))
            assert result.begin is not None and result.end is not None
            errors[given].append(_shape_error(result, frame))
        if given is None:
            blur = pipeline.splitter.blur_measured
            assert blur is not None and blur.sharpen_gain == 0.0
            assert blur.lens_blur_px < 0.6, blur  # steeper edges than the lens's 0.8 px
    assert np.mean(errors[None]) < 0.32, errors[None]
    assert np.mean(errors[0.67]) > np.mean(errors[None]) + 0.1, errors


def test_a_blur_reading_that_does_not_explain_the_edge_spacing_is_not_kept() -> None:
    """A rope that moves more than its tip sweep says widens the cross-section: the fit reads a 2.2 px bar under
    about 1 px of blur. Under that blur the contour's 3.1 px edge spacing (a 2 px rope's under the default blur) is
    the blur's own, a rope at the model's floor: the reading is dropped and the model stays. A still rope's reading,
    whose spacing its model turns into the bar the fit read, is kept."""
    from ropecam.device.pipeline.config import DEFAULT_LENS_BLUR_PX
    from ropecam.device.pipeline.edge_model import shared_model
    from ropecam.device.pipeline.edges import gaussian_weights
    from ropecam.device.pipeline.lens_blur import LensBlur

    weights = gaussian_weights(1.0).astype(np.float64)
    lens = LensBlur(weights, None)
    frame, points, fixed = _still_rope(1.0, 2.2, 20.0, 1.0, 0)
    assert not lens.read(frame, points, len(points), fixed, 3.1, 0.0)
    assert lens.estimate is not None and lens.estimate.read_values == []
    assert lens.model.lens_blur_px == DEFAULT_LENS_BLUR_PX
    # The same frame read without the check (the estimate alone) gives the wrong blur the check refuses.
    wrong = LensBlurEstimate().read(frame, points, len(points), fixed, 3.1, 0.0)
    assert wrong is not None and wrong.lens_blur_px > 0.8
    assert not lens.explains(wrong, 2.2, 3.1)

    frame, points, fixed = _still_rope(0.6, 2.2, 20.0, 1.0, 0)
    spacing = shared_model(weights, 0.6, 0.0, 1.0).edge_spacing(2.2)
    assert lens.read(frame, points, len(points), fixed, spacing, 0.0)
    assert len(lens.estimate.read_values) == 1
    assert lens.model.lens_blur_px == pytest.approx(0.6, abs=0.1)
