"""The realism options of the simulator's scene configuration: one table for `ropecam simulate --help` and the docs.

Each row is (TOML key, unit, allowed values, meaning); the dataclasses in `ropecam.host.sim.config` validate them,
and tests/host/sim/test_options.py checks that every row is a real field and appears in docs/simulator.md.
"""

from __future__ import annotations

from typing import Final

__all__ = ["REALISM_OPTIONS"]

REALISM_OPTIONS: Final[tuple[tuple[str, str, str, str], ...]] = (
    ("scene.photo_dir", "path", "folder", "where relative rope_photo paths are read from (../shared/realdata)"),
    ("scene.rope_photo", "path", 'file or ""', "photo of a real rope painted along the rope (its braid, its shading)"),
    ("scene.rope_photo_contrast", "relative", "0-2", "scale of the photographed brightness variation (1: as shot)"),
    (
        "scene.plate_photo",
        "path",
        'file or ""',
        "photo of a plain surface: its rope-free grain and smudges on the plate",
    ),
    ("scene.plate_photo_contrast", "relative", "0-20", "scale of that texture (1: as shot, about 0.8 % std)"),
    ("scene.rope_unevenness", "relative", "0-0.9", "brightness variation along the rope, moving with it"),
    ("scene.clamp", "bool", "true/false", "a clamp over the fixed end, hiding the rope's first pixels"),
    ("scene.clamp_width_px", "px", "0 or 4-200", "width of a shaded metal clamp with two bolts (0: plain block)"),
    ("scene.rod_width_px", "px", "0-60", "rod holding the clamp, up to the image's top border (0: none)"),
    ("scene.plate_edge", "fraction of width", "0 or 0.5-0.99", "the plate's right edge in view, a wall beyond it"),
    ("scene.scratches", "count", "0-50", "faint thin scratches on the plate"),
    ("scene.dust", "count", "0-2000", "dust specks on the plate"),
    ("scene.distractor", "bool", "true/false", "a second, static cable hanging beside the swing"),
    ("scene.background_variation", "relative", "0-0.9", "illumination gradient and a broad bump over the plate"),
    ("scene.texture", "relative", "0-0.9", "fine static grain of the plate"),
    ("scene.vignetting", "relative", "0-0.9", "brightness lost in the image corners"),
    ("scene.flicker", "relative", "0-0.9", "lamp modulation amplitude: light x (1 + a sin(2 pi f t))"),
    ("scene.flicker_hz", "Hz", "1-1000", "lamp modulation frequency (100 on 50 Hz mains, 120 on 60 Hz)"),
    ("camera.psf_sigma_px", "px", "0-5", "lens blur, Gaussian sigma (the pixel's area is added)"),
    (
        "camera.readout_ms",
        "ms",
        "0 to the frame period",
        "rolling shutter: frame readout time (row r starts r / height of it after row 0)",
    ),
    ("sensor.read_noise_dn", "DN", "0-50", "read noise, linear light"),
    ("sensor.gain_dn_per_electron", "DN/e-", "0-10", "shot noise: variance = gain x signal"),
    ("sensor.gamma", "exponent", "1-3", "output curve: code = 255 (light/255)^(1/gamma)"),
    ("sensor.sharpen", "gain", "0-3", "unsharp-mask amount on the gamma-encoded image"),
    ("sensor.sharpen_sigma_px", "px", "0.3-5", "unsharp-mask Gaussian sigma"),
    ("sensor.jpeg_quality", "quality", "0 or 1-100", "JPEG/MJPEG round trip at this quality (0: none)"),
)
