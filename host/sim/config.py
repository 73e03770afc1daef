"""Configuration of a simulated rig: camera and motion plane, rope, scene and sensor, and the recording itself.

Each part is a frozen, slotted dataclass validated on construction; `SimConfig` composes them. The rope and the
time integrator are the ANCF model's own configuration types (`ropecam.host.model.config.RopeConfig` and
`SolverConfig`), so the simulator's ``[rope]`` and ``[solver]`` tables are exactly those of
``ropecam model simulate --config``. Presets (`ropecam.host.sim.presets`) are instances of `SimConfig`; a TOML file
can override any field of a preset (`merge_overrides`), with unknown keys refused.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from ropecam.host.model.config import RopeConfig, SolverConfig
from ropecam.shared.config import check_finite, check_in, check_positive, check_range, from_mapping
from ropecam.shared.errors import ConfigError

if TYPE_CHECKING:  # geometry imports OpenCV; kept out of `ropecam --help`
    from ropecam.host.calibration.geometry import CameraModel, PlanePose

__all__ = ["CameraSpec", "SceneSpec", "SensorSpec", "SimConfig", "merge_overrides"]

Polarity = Literal["bright", "dark"]


@dataclass(frozen=True, slots=True)
class CameraSpec:
    """Camera intrinsics, the motion plane's pose, frame rate and optical blur.

    Parameters
    ----------
    fx_px, fy_px, cx_px, cy_px
        Pinhole intrinsics (pixels).
    distortion
        OpenCV distortion coefficients (k1, k2, p1, p2, k3).
    width_px, height_px
        Image size.
    fps
        Frame rate (frames per second); frame k's exposure starts at ``first_exposure_s + k / fps``.
    plane_rvec
        OpenCV Rodrigues vector of the plane pose (``X_camera = R X_plane + t``), radians.
    plane_tvec_m
        Translation of that pose: the fixed end of the rope (plane origin) in camera coordinates, metres.
    psf_sigma_px
        Standard deviation of the lens blur (Gaussian point-spread function), pixels; the pixel's own area is
        added to it as a box of variance 1/12.
    readout_ms
        Rolling shutter: row r's exposure starts ``readout_ms * r / height_px`` after row 0's, milliseconds,
        at most the frame period (checked by `SimConfig`); 0 = global shutter.
    """

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    width_px: int
    height_px: int
    fps: float
    plane_tvec_m: tuple[float, float, float]
    plane_rvec: tuple[float, float, float] = (0.0, 0.0, 0.0)
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    psf_sigma_px: float = 0.4
    readout_ms: float = 0.0

    def __post_init__(self) -> None:
        for name in ("fx_px", "fy_px", "fps"):
            check_positive(f"camera.{name}", getattr(self, name))
        check_finite("camera.cx_px", self.cx_px)
        check_finite("camera.cy_px", self.cy_px)
        check_range("camera.width_px", self.width_px, 8, 16384)
        check_range("camera.height_px", self.height_px, 8, 16384)
        check_range("camera.psf_sigma_px", self.psf_sigma_px, 0.0, 5.0)
        check_range("camera.readout_ms", self.readout_ms, 0.0, 1000.0 / self.fps)
        if len(self.distortion) not in (4, 5, 8):
            raise ConfigError(f"camera.distortion must hold 4, 5 or 8 coefficients, got {list(self.distortion)}")
        for value in (*self.distortion, *self.plane_rvec, *self.plane_tvec_m):
            check_finite("camera.distortion/plane_rvec/plane_tvec_m entries", value)
        if self.plane_tvec_m[2] <= 0:
            raise ConfigError(
                f"camera.plane_tvec_m: the plane origin must lie in front (z > 0), got {self.plane_tvec_m}"
            )

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return (self.width_px, self.height_px)

    def camera_model(self) -> CameraModel:
        """Return the `CameraModel` (K, distortion, image size)."""
        from ropecam.host.calibration.geometry import CameraModel

        k = np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]])
        return CameraModel(k, np.array(self.distortion, dtype=np.float64), self.image_size)

    def plane_pose(self) -> PlanePose:
        """Return the motion plane's `PlanePose`."""
        from ropecam.host.calibration.geometry import PlanePose

        return PlanePose.from_rvec(self.plane_rvec, self.plane_tvec_m)

    @property
    def edge_sigma_px(self) -> float:
        """Total edge blur: lens blur and the pixel's box (variance 1/12) combined, pixels."""
        return math.sqrt(self.psf_sigma_px**2 + 1.0 / 12.0)


@dataclass(frozen=True, slots=True)
class SceneSpec:
    """What the camera looks at: the rope's look, levels, background, lighting fall-off and distractions.

    Parameters
    ----------
    render_diameter_m
        Diameter the rope is drawn with; None draws the physical diameter (``rope.diameter_m``). Presets choose it
        so the rope appears 1.5-4 px wide at their plane distance (a real 1 mm rope at 1.5 m is about 1 px wide);
        it does not enter the dynamics.
    polarity
        "bright": a bright rope on a dark background (the paper's black board); "dark": a dark rope on a bright one.
    rope_level_dn, background_level_dn
        Mean rope and background brightness before vignetting, in 8-bit digital numbers (None: from the polarity,
        bright 210 on 25, dark 35 on 200).
    background_variation
        Relative amplitude of the smooth background non-uniformity (a gradient and a broad bump), 0 = uniform.
    vignetting
        Relative brightness loss in the image corners (quadratic in the distance from the image centre), 0 = none.
    texture
        Relative amplitude of a fine, static background texture (blurred noise, about 2 px grain), 0 = none.
    rope_unevenness
        Relative amplitude of brightness variation along the rope (moves with the material), 0 = uniform.
    scratch
        Draw a static bright scratch across the swing region of the background.
    clamp
        Draw a clamp block over the fixed end (it hides the first few millimetres of rope).
    clamp_width_px
        Width of the clamp block, pixels (0 or 4-200); 0 = the plain block of `clamp` (8x the rope width, at
        least 12 px, uniform grey). A width > 0 draws a shaded metal block with a bolt head.
    rod_width_px
        Diameter of a rod holding the clamp, from the clamp to the image's top border, pixels (0-60; 0 = none;
        needs `clamp`).
    plate_edge
        Where the plate's right edge lies, as a fraction of the image width (0 or 0.5-0.99; 0 = the plate fills
        the image); it leans 2 degrees, its cut edge shows as a thin bright line, and beyond it is a wall 12 % of
        the rope's contrast brighter (darker) than the plate, lit unevenly.
    scratches
        Number of thin straight scratches on the plate (0-50), 16-100 px long, 3-10 % of the rope's contrast.
    dust
        Number of dust specks on the plate (0-2000): most 0.4-1.2 px in radius at 2-12 % of the rope's
        contrast, one in seven a fainter, out-of-focus 1.5-3 px blot.
    distractor
        Draw a second, static cable of the rope's width hanging from the top border to the bottom one, beside
        the swing.
    photo_dir
        Folder that a relative `rope_photo` is read from (relative paths: from the current directory).
    rope_photo
        Photograph of a real rope (path, relative to `photo_dir` unless absolute) whose brightness across and along
        its own centreline is painted along the simulated rope (`ropecam.host.sim.rope_photo`); "" = plain rope.
        Read when the frames are rendered; a missing file is a `ConfigError` naming this key and the path.
    rope_photo_contrast
        Scale of the photographed brightness variation, in [0, 2] (0: flat, 1: as photographed).
    plate_photo
        Photograph of a plain surface (path, relative to `photo_dir` unless absolute) whose rope-free part gives
        the plate its grain and smudges (`ropecam.host.sim.rope_photo.load_plate_texture`); "" = none.
    plate_photo_contrast
        Scale of that texture's relative variation, in [0, 20] (1: as photographed; a white table photographed
        at about 0.8 % standard deviation).
    flicker
        Relative amplitude a of the lamps' modulation, light x (1 + a sin(2 pi flicker_hz t)) with t on the
        model's clock, averaged over each row's exposure; in [0, 0.9], 0 = steady light.
    flicker_hz
        Frequency of that modulation, Hz, in [1, 1000] (100 for lamps on 50 Hz mains, 120 on 60 Hz).
    """

    render_diameter_m: float | None = None
    polarity: Polarity = "bright"
    rope_level_dn: float | None = None
    background_level_dn: float | None = None
    background_variation: float = 0.08
    vignetting: float = 0.2
    texture: float = 0.0
    rope_unevenness: float = 0.0
    scratch: bool = False
    clamp: bool = False
    clamp_width_px: float = 0.0
    rod_width_px: float = 0.0
    plate_edge: float = 0.0
    scratches: int = 0
    dust: int = 0
    distractor: bool = False
    photo_dir: str = "../shared/realdata"
    rope_photo: str = ""
    rope_photo_contrast: float = 1.0
    plate_photo: str = ""
    plate_photo_contrast: float = 1.0
    flicker: float = 0.0
    flicker_hz: float = 100.0

    def __post_init__(self) -> None:
        if self.render_diameter_m is not None:
            check_positive("scene.render_diameter_m", self.render_diameter_m)
        check_in("scene.polarity", self.polarity, ("bright", "dark"))
        for name in ("rope_level_dn", "background_level_dn"):
            value = getattr(self, name)
            if value is not None:
                check_range(f"scene.{name}", value, 0.0, 255.0)
        for name in ("background_variation", "vignetting", "texture", "rope_unevenness"):
            check_range(f"scene.{name}", getattr(self, name), 0.0, 0.9)
        if self.clamp_width_px != 0:
            check_range("scene.clamp_width_px", self.clamp_width_px, 4.0, 200.0)
        check_range("scene.rod_width_px", self.rod_width_px, 0.0, 60.0)
        if self.rod_width_px > 0 and not self.clamp:
            raise ConfigError(f"scene.rod_width_px = {self.rod_width_px} draws the clamp's rod: set scene.clamp = true")
        if self.plate_edge != 0:
            check_range("scene.plate_edge", self.plate_edge, 0.5, 0.99)
        check_range("scene.scratches", self.scratches, 0, 50)
        check_range("scene.dust", self.dust, 0, 2000)
        check_range("scene.rope_photo_contrast", self.rope_photo_contrast, 0.0, 2.0)
        check_range("scene.plate_photo_contrast", self.plate_photo_contrast, 0.0, 20.0)
        check_range("scene.flicker", self.flicker, 0.0, 0.9)
        check_range("scene.flicker_hz", self.flicker_hz, 1.0, 1000.0)
        # Linear levels: through a gamma curve 5 DN in the darks (3.5 -> 8.5) is still 18 output codes.
        if abs(self.rope_level - self.background_level) < 5:
            raise ConfigError(
                f"scene: rope level {self.rope_level} and background level {self.background_level} must differ "
                "by at least 5 DN (the rope would be invisible)"
            )

    @property
    def rope_photo_path(self) -> Path | None:
        """The rope photo's path (`rope_photo` joined to `photo_dir` when relative), or None for a plain rope."""
        if not self.rope_photo:
            return None
        return Path(self.photo_dir) / self.rope_photo

    @property
    def plate_photo_path(self) -> Path | None:
        """The plate photo's path (`plate_photo` joined to `photo_dir` when relative), or None."""
        return Path(self.photo_dir) / self.plate_photo if self.plate_photo else None

    @property
    def rope_level(self) -> float:
        """Rope brightness in DN (explicit or from the polarity)."""
        if self.rope_level_dn is not None:
            return float(self.rope_level_dn)
        return 210.0 if self.polarity == "bright" else 35.0

    @property
    def background_level(self) -> float:
        """Background brightness in DN (explicit or from the polarity)."""
        if self.background_level_dn is not None:
            return float(self.background_level_dn)
        return 25.0 if self.polarity == "bright" else 200.0


@dataclass(frozen=True, slots=True)
class SensorSpec:
    """The sensor and the camera's own processing: noise in linear light, gamma, sharpening, 8 bits, JPEG.

    The order is that of a camera: read and shot noise on the linear light, the gamma curve, unsharp-mask
    sharpening, rounding and clipping to 8 bits, then the JPEG/MJPEG round trip.

    Parameters
    ----------
    read_noise_dn
        Standard deviation of the signal-independent noise, DN (linear).
    gain_dn_per_electron
        Conversion gain; shot noise has variance ``gain * signal`` (DN^2). 0 switches shot noise off.
    gamma
        Exponent of the output curve: code = 255 (light / 255)^(1 / gamma), in [1, 3]; 1 = linear.
    sharpen
        Unsharp-mask amount in [0, 3]: code + sharpen * (code - GaussianBlur(code, sharpen_sigma_px)); 0 = none.
    sharpen_sigma_px
        Standard deviation of the unsharp mask's Gaussian, pixels, in [0.3, 5].
    jpeg_quality
        JPEG quality (1-100) of a JPEG/MJPEG round trip of every frame (OpenCV's encoder); 0 = none.
    """

    read_noise_dn: float = 1.5
    gain_dn_per_electron: float = 0.05
    gamma: float = 1.0
    sharpen: float = 0.0
    sharpen_sigma_px: float = 1.0
    jpeg_quality: int = 0

    def __post_init__(self) -> None:
        check_range("sensor.read_noise_dn", self.read_noise_dn, 0.0, 50.0)
        check_range("sensor.gain_dn_per_electron", self.gain_dn_per_electron, 0.0, 10.0)
        check_range("sensor.gamma", self.gamma, 1.0, 3.0)
        check_range("sensor.sharpen", self.sharpen, 0.0, 3.0)
        check_range("sensor.sharpen_sigma_px", self.sharpen_sigma_px, 0.3, 5.0)
        check_range("sensor.jpeg_quality", self.jpeg_quality, 0, 100)


@dataclass(frozen=True, slots=True)
class SimConfig:
    """One simulated recording: the rig and how many frames, which exposures, from when.

    Parameters
    ----------
    preset
        Name of the preset this configuration came from (recorded in the metadata).
    camera
        Camera, motion plane and frame rate.
    rope
        The rope, its support and environment: the ANCF model's configuration.
    solver
        The ANCF model's discretisation and time integration. Its `duration_s` is a minimum: the model is solved
        at least until the last exposure ends (see `model_solver`).
    scene, sensor
        What the camera sees and how the sensor records it.
    frames
        Number of frames per exposure time.
    exposure_ms
        Exposure times; one frame set per value.
    first_exposure_s
        Start of frame 0's exposure, seconds after the release (the model's t = 0).
    seed
        Seed of every random choice (background, texture, scratch, rope brightness, noise).
    """

    preset: str
    camera: CameraSpec
    rope: RopeConfig
    solver: SolverConfig = field(default_factory=SolverConfig)
    scene: SceneSpec = field(default_factory=SceneSpec)
    sensor: SensorSpec = field(default_factory=SensorSpec)
    frames: int = 60
    exposure_ms: tuple[float, ...] = (4.0,)
    first_exposure_s: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        check_range("frames", self.frames, 1, 1_000_000)
        if not self.exposure_ms:
            raise ConfigError("exposure_ms must hold at least one exposure time")
        period_ms = 1000.0 / self.camera.fps
        for value in self.exposure_ms:
            check_range("exposure_ms", value, 0.001, period_ms)
        if len(set(self.exposure_ms)) != len(self.exposure_ms):
            raise ConfigError(f"exposure_ms has duplicates: {list(self.exposure_ms)}")
        check_range("first_exposure_s", self.first_exposure_s, 0.0, 3600.0)
        check_range("seed", self.seed, 0, 2**63 - 1)
        if self.scene.clamp and self.rope.fixed_end_motion.active:
            raise ConfigError(
                "scene.clamp draws a static clamp at the plane origin, but rope.fixed_end_motion moves the fixed "
                "end: switch one of them off"
            )

    @property
    def duration_s(self) -> float:
        """Model time needed: up to the end of the last frame's longest exposure (of its last row)."""
        last_begin_s = self.first_exposure_s + (self.frames - 1) / self.camera.fps
        return last_begin_s + max(self.exposure_ms) / 1000.0 + self.camera.readout_ms / 1000.0

    @property
    def render_diameter_m(self) -> float:
        """Diameter the rope is drawn with: ``scene.render_diameter_m``, else the physical ``rope.diameter_m``."""
        if self.scene.render_diameter_m is not None:
            return self.scene.render_diameter_m
        return self.rope.diameter_m

    def model_solver(self) -> SolverConfig:
        """Return the solver configuration the simulator runs: `solver` with `duration_s` extended if needed.

        The model runs for ``solver.duration_s`` or until two output samples past the end of the last exposure,
        whichever is later, so that every exposure lies inside the trajectory.
        """
        steps = math.ceil(self.duration_s / self.solver.output_every_s + 1e-9) + 2
        needed_s = steps * self.solver.output_every_s
        if needed_s <= self.solver.duration_s:
            return self.solver
        return dataclasses.replace(self.solver, duration_s=needed_s)

    def to_dict(self) -> dict[str, Any]:
        """Return the configuration as plain JSON/TOML-compatible data."""
        return _plain(dataclasses.asdict(self))


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    return value


def _deep_merge(base: dict[str, Any], update: Mapping[str, Any]) -> dict[str, Any]:
    merged = dict(base)
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(merged.get(key), dict):
            merged[key] = _deep_merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def merge_overrides(config: SimConfig, overrides: Mapping[str, Any], where: str = "overrides") -> SimConfig:
    """Return `config` with the (nested) keys of `overrides` replaced, validated like a TOML file.

    Parameters
    ----------
    config
        The base configuration (usually a preset).
    overrides
        Mapping with any of the top-level keys of `SimConfig` and tables ``camera``, ``rope`` (with its
        ``fixed_end_motion`` sub-table), ``solver``, ``scene``, ``sensor`` holding any of their fields.
    where
        Name for error messages (the file name).

    Raises
    ------
    ConfigError
        An unknown key, a wrong type or a value out of range (the message names `where` and the key).
    """
    merged = _deep_merge(config.to_dict(), overrides)
    return from_mapping(SimConfig, merged, where=where)
