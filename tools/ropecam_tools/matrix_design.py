"""The robustness matrix as data: the ideal scene, the factor rows, the held-out pairs, the seed sets, the cells.

A *scene* is a simulator configuration (a preset plus overrides of its TOML keys) at one exposure time; a *cell* is
one scene measured by one method. Three sections:

* ``presets``: every preset of `ropecam.host.sim.presets.PRESETS`, at each of its exposure times (in the tuning
  set `LATE_SWING_PRESETS` also from 1 s after the release: a ``late swing`` row);
* ``factors``: one `Factor` at a time across its values, every other key at the ideal scene (`IDEAL`); the first
  value of each row is the ideal scene's own;
* ``paper``: the paper-exposure renders (1, 5, 9, 15 ms at 30 FPS, 800x512) of `PAPER_PRESETS`, for the paper's
  Fig. 9/11 and its segmentation-point table.

A factor row names a dotted key of the simulator's configuration (``scene.texture``); a row whose key the simulator
on this branch does not have is left out and listed as unavailable, so rows for new simulator options can be written
before the options exist. The ``validation`` seed set renders other seeds and another stretch of the motion, and adds
`PAIRS` (two factors at once), which the ``tuning`` set never shows.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["FACTORS", "IDEAL", "PAIRS", "SEED_SETS", "Factor", "Scene", "build_scenes"]

METHODS = ("blur_split", "paper", "centerline")
"""The measured methods: the default, the paper's literal method, the centreline of the blurred region."""
SECTIONS = ("presets", "factors", "paper")
IDEAL_PRESET = "rig"
IDEAL: dict[str, Any] = {
    "scene": {"background_variation": 0.0, "vignetting": 0.0, "texture": 0.0, "rope_unevenness": 0.0},
    "sensor": {"read_noise_dn": 0.0, "gain_dn_per_electron": 0.0},
}
"""The ideal scene: the ``rig`` preset (bright 2.5 px rope on a 25 DN plate, 185 DN contrast, global shutter, 4 ms
at 119 FPS) without background non-uniformity, vignetting, texture or noise."""
PAPER_PRESETS = ("paper", "lab", "lab-dark", "lab-mjpeg", "lab-rolling", "lab-hard")
"""Presets rendered at the paper's exposures: ``paper`` itself, the others through `with_paper_timing` (their look
through the paper's camera, rope and timing)."""
PAPER_EXPOSURES_MS = (1.0, 5.0, 9.0, 15.0)


@dataclass(frozen=True)
class SeedSet:
    """Render seeds and the stretch of the motion used by a seed set.

    ``late_swing_s``: the presets of `LATE_SWING_PRESETS` are also rendered from this time after the release (a
    ``late swing`` row each; None: not).
    """

    name: str
    seed: int
    first_exposure_s: float
    pairs: bool
    purpose: str
    late_swing_s: float | None = None


LATE_SWING_PRESETS = ("lab",)
"""Presets with a ``late swing`` row in the tuning set: their motion from 1 s after the release, where the rope
whips (tips moving along their own axis, start and end shapes that cross), which the cells from the release never
show."""
SEED_SETS = {
    "tuning": SeedSet(
        "tuning", 0, 0.0, False, "the simulator's default seed, motion from the release (and a late swing from "
        "1 s): tune on it", late_swing_s=1.0,
    ),
    "validation": SeedSet(
        "validation", 7919, 0.25, True, "another seed and the motion from 0.25 s after the release, plus held-out "
        "pairs of factors: never tune on it"
    ),
}  # fmt: skip


def _width_setting(value_px: float, base: dict[str, Any]) -> float:
    """Rope width in pixels at the fixed end's depth -> ``scene.render_diameter_m``."""
    camera = base["camera"]
    return round(value_px * camera["plane_tvec_m"][2] / camera["fx_px"], 7)


def _contrast_setting(value_dn: float, base: dict[str, Any]) -> float:
    """Rope-minus-plate contrast (DN) -> ``scene.rope_level_dn`` over the ideal bright scene's 25 DN plate."""
    return 25.0 + value_dn


def _jpeg_setting(value: Any, base: dict[str, Any]) -> int:
    """JPEG quality shown as "off" or 1-100 -> ``sensor.jpeg_quality`` (0: no round trip)."""
    return 0 if value == "off" else int(value)


REALDATA = Path(__file__).resolve().parents[2].parent / "shared" / "realdata"
"""Default folder of the real photographs handed to the project (``../shared/realdata`` beside the repository)."""


@dataclass(frozen=True)
class Factor:
    """One row of the factor section: a simulator key varied across its values.

    Attributes
    ----------
    name
        Row name in the tables (also accepted by ``--factor``).
    key
        Dotted key of the simulator configuration (as in a ``--config`` TOML file), e.g. ``scene.texture``.
    values
        The values measured, the ideal scene's first.
    unit
        Unit of the values as shown.
    stated_range
        The simulator's accepted range of the key (for the docs).
    meaning
        What the value is, in words.
    setting
        Maps a shown value to the key's value, given the base configuration as a dict (None: the same).
    extra
        Further dotted keys set with every value but the first (the ideal scene's), e.g. ``scene.clamp = true``
        for the clamp's size.
    photos
        The row paints a photographed rope: ``scene.photo_dir`` is set to the matrix's photo folder.
    """

    name: str
    key: str
    values: tuple[Any, ...]
    unit: str
    stated_range: str
    meaning: str
    setting: Callable[[Any, dict[str, Any]], Any] | None = None
    extra: tuple[tuple[str, Any], ...] = ()
    photos: bool = False

    def overrides(self, value: Any, base: dict[str, Any], photo_dir: Path = REALDATA) -> dict[str, Any]:
        """Return the nested overrides that set this factor to `value` (shown units)."""
        if value == self.values[0] and self.extra:
            return {}
        target = value if self.setting is None else self.setting(value, base)
        out = _nested(self.key, target)
        for key, extra in self.extra:
            out = _merge(out, _nested(key, extra))
        if self.photos:
            out = _merge(out, {"scene": {"photo_dir": str(photo_dir)}})
        return out

    @property
    def keys(self) -> tuple[str, ...]:
        """Every simulator key the row needs."""
        return (self.key, *(key for key, _ in self.extra))


def _nested(key: str, value: Any) -> dict[str, Any]:
    parts = key.split(".")
    out: dict[str, Any] = {parts[-1]: value}
    for part in reversed(parts[:-1]):
        out = {part: out}
    return out


FACTORS: tuple[Factor, ...] = (
    Factor("texture", "scene.texture", (0.0, 0.05, 0.1, 0.2, 0.3), "rel.", "0-0.9",
           "fine static background texture (blurred noise, 2 px grain), relative amplitude"),
    Factor("rope unevenness", "scene.rope_unevenness", (0.0, 0.15, 0.3, 0.5), "rel.", "0-0.9",
           "brightness variation along the rope, moving with the material, relative amplitude"),
    Factor("contrast", "scene.rope_level_dn", (185.0, 100.0, 56.0, 30.0, 15.0), "DN", ">= 10 DN",
           "rope level minus plate level (plate 25 DN)", _contrast_setting),
    Factor("read noise", "sensor.read_noise_dn", (0.0, 1.5, 3.0, 6.0, 10.0), "DN", "0-50 DN",
           "standard deviation of the signal-independent sensor noise"),
    Factor("shot noise", "sensor.gain_dn_per_electron", (0.0, 0.05, 0.2, 0.5), "DN/e-", "0-10",
           "conversion gain: photon noise variance = gain x signal"),
    Factor("PSF", "camera.psf_sigma_px", (0.4, 0.8, 1.2, 2.0), "px", "0-5 px",
           "lens blur, Gaussian sigma"),
    Factor("rope width", "scene.render_diameter_m", (2.5, 1.5, 1.0, 4.0), "px", "> 0",
           "drawn rope diameter at the fixed end's depth", _width_setting),
    Factor("background variation", "scene.background_variation", (0.0, 0.1, 0.2, 0.4), "rel.", "0-0.9",
           "smooth plate non-uniformity (gradient and broad bump), relative amplitude"),
    Factor("vignetting", "scene.vignetting", (0.0, 0.2, 0.4), "rel.", "0-0.9",
           "brightness loss in the image corners"),
    Factor("polarity", "scene.polarity", ("bright", "dark"), "", "bright, dark",
           "bright rope on a dark plate, or dark on bright"),
    Factor("clamp", "scene.clamp", (False, True), "", "off, on", "a clamp block over the fixed end"),
    Factor("scratch", "scene.scratch", (False, True), "", "off, on", "a static bright scratch on the plate"),
    Factor("rope photo texture", "scene.rope_photo_contrast", (0.0, 0.5, 1.0, 2.0), "rel.", "0-2",
           "brightness across and along a real braided rope (trackdlo_rope/rope.png), scaled; 0: plain rope",
           extra=(("scene.rope_photo", "trackdlo_rope/rope.png"),), photos=True),
    Factor("gamma", "sensor.gamma", (1.0, 1.8, 2.2, 2.6), "", "1-3", "output code = 255 (light/255)^(1/gamma)"),
    Factor("sharpening", "sensor.sharpen", (0.0, 0.5, 1.0, 2.0), "gain", "0-3",
           "unsharp-mask amount on the encoded image (sigma 1 px)"),
    Factor("JPEG quality", "sensor.jpeg_quality", ("off", 95, 85, 70, 50), "", "0 (off) or 1-100",
           "JPEG/MJPEG round trip of every frame at this quality", _jpeg_setting),
    Factor("flicker", "scene.flicker", (0.0, 0.1, 0.2, 0.4), "rel.", "0-0.9",
           "lamp brightness modulation amplitude at 100 Hz (50 Hz mains)"),
    Factor("readout time", "camera.readout_ms", (0.0, 2.0, 4.0, 7.0), "ms", "0 to the frame period (8.4 ms)",
           "rolling shutter: the last row starts this much after the first; 0: global shutter"),
    Factor("clamp size", "scene.clamp_width_px", (0.0, 12.0, 24.0, 48.0), "px", "0 or 4-200 px",
           "width of a clamp block over the fixed end; 0: no clamp", extra=(("scene.clamp", True),)),
    Factor("clamp rod", "scene.rod_width_px", (0.0, 4.0, 10.0), "px", "0-60 px",
           "width of the rod holding the clamp, to the top border; 0: no rod", extra=(("scene.clamp", True),)),
    Factor("plate edge", "scene.plate_edge", (0.0, 0.9, 0.7), "of width", "0 or 0.5-0.99",
           "the plate's right edge in view at this fraction of the width; 0: plate fills the image"),
    Factor("scratches", "scene.scratches", (0, 5, 20), "", "0-50", "thin faint scratches on the plate"),
    Factor("dust", "scene.dust", (0, 200, 1000), "", "0-2000", "dust specks on the plate"),
    Factor("distractor", "scene.distractor", (False, True), "", "off, on", "a second, static rope-like cable"),
)  # fmt: skip

PAIRS: tuple[tuple[tuple[str, Any], tuple[str, Any]], ...] = (
    (("texture", 0.2), ("read noise", 3.0)),
    (("contrast", 56.0), ("read noise", 3.0)),
    (("contrast", 56.0), ("clamp", True)),
    (("PSF", 1.2), ("rope width", 1.5)),
    (("rope unevenness", 0.3), ("background variation", 0.2)),
    (("polarity", "dark"), ("texture", 0.1)),
)
"""Held-out combinations of two factors, measured only in the validation set."""


@dataclass(frozen=True)
class Scene:
    """One rendered frame set of the matrix.

    Attributes
    ----------
    section
        ``presets``, ``factors``, ``paper`` or ``pairs``.
    label
        Row label (``lab``, ``texture = 0.3``, ``paper 9 ms``).
    preset
        The simulator preset the scene starts from.
    overrides
        Nested overrides of the preset's keys (the ideal scene's and the factor's, or none).
    exposure_ms
        Exposure time.
    key
        Identifier of what is rendered: a hash of the full configuration and the exposure (scenes of the same
        configuration share one frame set).
    factor, value
        The factor row and its shown value (``factors`` and ``pairs`` sections), else None.
    paper_timing
        Render the preset through the paper's camera and timing (`ropecam.host.sim.presets.with_paper_timing`).
    """

    section: str
    label: str
    preset: str
    overrides: dict[str, Any] = field(hash=False)
    exposure_ms: float
    key: str
    factor: str | None = None
    value: Any = None
    paper_timing: bool = False

    @property
    def folder(self) -> str:
        """Folder name of the scene's frame set."""
        slug = "".join(c if c.isalnum() else "-" for c in self.label).strip("-")
        return f"{slug}-{self.key}"


def _key(config: dict[str, Any], exposure_ms: float) -> str:
    text = json.dumps([config, exposure_ms], sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def _merge(base: dict[str, Any], update: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in update.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def _has_key(config: dict[str, Any], key: str) -> bool:
    node: Any = config
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def available_factors(base: dict[str, Any], photo_dir: Path) -> tuple[list[Factor], list[tuple[Factor, str]]]:
    """Split `FACTORS` into those the simulator can render and those it cannot, with the reason."""
    have, missing = [], []
    for factor in FACTORS:
        absent = [key for key in factor.keys if not _has_key(base, key)]
        if absent:
            missing.append((factor, f"the simulator has no key {', '.join(absent)}"))
        elif factor.photos and not photo_dir.is_dir():
            missing.append((factor, f"no photo folder {photo_dir} (give --photo-dir)"))
        else:
            have.append(factor)
    return have, missing


def _format(value: Any) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def factor_label(factor: Factor, value: Any) -> str:
    """Row label of a factor value, e.g. ``texture = 0.3 rel.``."""
    unit = f" {factor.unit}" if factor.unit else ""
    return f"{factor.name} = {_format(value)}{unit}"


def build_scenes(
    presets: dict[str, Any],
    seed_set: str,
    only: tuple[str, ...] = SECTIONS,
    factor_names: tuple[str, ...] | None = None,
    preset_names: tuple[str, ...] | None = None,
    photo_dir: Path = REALDATA,
    paper_timed: dict[str, Any] | None = None,
    preset_set: dict[str, Any] | None = None,
    seed: int | None = None,
    first_exposure_s: float | None = None,
) -> tuple[list[Scene], list[tuple[Factor, str]]]:
    """Return the matrix's scenes and the factor rows left out (with the reason: a key the simulator lacks).

    Parameters
    ----------
    presets
        Preset name -> its configuration as a dict (`SimConfig.to_dict()`).
    seed_set
        ``tuning`` or ``validation`` (`SEED_SETS`).
    only
        Sections to build (``pairs`` come with ``factors`` in the validation set).
    factor_names, preset_names
        Restrict the factor rows, and the presets and paper sections, to these names (None: all).
    photo_dir
        Folder of the real photographs, for the rows and presets that paint a photographed rope.
    paper_timed
        Preset name -> its configuration through the paper's camera and timing, as a dict (for the paper section;
        ``paper`` itself is taken from `presets`).
    preset_set
        Dotted simulator keys -> values set on every scene of the presets and paper sections (``--set``), e.g.
        ``{"scene.clamp": False}``; their rows are labelled with them.
    seed, first_exposure_s
        Render with this seed and from this time after the release (s) instead of the seed set's (None: the set's;
        the late-swing rows keep their start): another stretch of the motion, e.g. a rope already swinging when
        the stream starts, rendered on the tuning side.

    Raises
    ------
    ValueError
        Unknown seed set, section, factor or preset name (the message lists the allowed ones).
    """
    if seed_set not in SEED_SETS:
        raise ValueError(f"seed set must be one of {', '.join(SEED_SETS)}, got {seed_set!r}")
    unknown = [name for name in only if name not in SECTIONS]
    if unknown:
        raise ValueError(f"sections must be among {', '.join(SECTIONS)}, got {unknown}")
    names = {f.name for f in FACTORS}
    if factor_names is not None and not set(factor_names) <= names:
        raise ValueError(f"unknown factor(s) {sorted(set(factor_names) - names)}; factors: {', '.join(sorted(names))}")
    if preset_names is not None and not set(preset_names) <= set(presets):
        raise ValueError(f"unknown preset(s) {sorted(set(preset_names) - set(presets))}; presets: {', '.join(presets)}")
    seeds = SEED_SETS[seed_set]
    common = {
        "seed": seeds.seed if seed is None else seed,
        "first_exposure_s": seeds.first_exposure_s if first_exposure_s is None else first_exposure_s,
    }

    settings: dict[str, Any] = {}
    for key, value in (preset_set or {}).items():
        settings = _merge(settings, _nested(key, value))
    suffix = " [" + ", ".join(f"{k}={_format(v)}" for k, v in preset_set.items()) + "]" if preset_set else ""

    def preset_overrides(config: dict[str, Any]) -> dict[str, Any]:
        # a preset's photo is read from the matrix's photo folder, not from its path relative to the working directory
        out = _merge(common, settings)
        return _merge(out, {"scene": {"photo_dir": str(photo_dir)}}) if config["scene"].get("rope_photo") else out

    scenes: list[Scene] = []
    if "presets" in only:
        for name, config in presets.items():
            if preset_names is not None and name not in preset_names:
                continue
            looks = [("", preset_overrides(config))]
            if seeds.late_swing_s is not None and name in LATE_SWING_PRESETS:
                looks.append(
                    (" late swing", _merge(preset_overrides(config), {"first_exposure_s": seeds.late_swing_s}))
                )
            for look, overrides in looks:
                for exposure in config["exposure_ms"]:
                    label = (name if len(config["exposure_ms"]) == 1 else f"{name} {exposure:g} ms") + look + suffix
                    key = _key(_merge(config, overrides), float(exposure))
                    scenes.append(Scene("presets", label, name, overrides, float(exposure), key))
    base = _merge(presets[IDEAL_PRESET], IDEAL)
    have, missing = available_factors(base, photo_dir)
    by_name = {f.name: f for f in have}
    exposure = float(presets[IDEAL_PRESET]["exposure_ms"][0])
    if "factors" in only:
        for factor in have:
            if factor_names is not None and factor.name not in factor_names:
                continue
            for value in factor.values:
                overrides = _merge(_merge(IDEAL, factor.overrides(value, base, photo_dir)), common)
                label = factor_label(factor, value)
                key = _key(_merge(presets[IDEAL_PRESET], overrides), exposure)
                scenes.append(Scene("factors", label, IDEAL_PRESET, overrides, exposure, key, factor.name, value))
        if seeds.pairs:
            for (name_a, value_a), (name_b, value_b) in PAIRS:
                if name_a not in by_name or name_b not in by_name:
                    continue
                fa, fb = by_name[name_a], by_name[name_b]
                overrides = _merge(
                    _merge(
                        _merge(IDEAL, fa.overrides(value_a, base, photo_dir)), fb.overrides(value_b, base, photo_dir)
                    ),
                    common,
                )
                label = f"{factor_label(fa, value_a)}, {factor_label(fb, value_b)}"
                key = _key(_merge(presets[IDEAL_PRESET], overrides), exposure)
                scenes.append(Scene("pairs", label, IDEAL_PRESET, overrides, exposure, key, f"{name_a} + {name_b}"))
    if "paper" in only:
        timed = {"paper": presets["paper"], **(paper_timed or {})}
        for name in PAPER_PRESETS:
            if name not in timed or (preset_names is not None and name not in preset_names):
                continue
            overrides = preset_overrides(timed[name])
            for exposure_ms in PAPER_EXPOSURES_MS:
                key = _key(_merge(timed[name], overrides), exposure_ms)
                label = f"{name} {exposure_ms:g} ms" if name == "paper" else f"{name} (paper camera) {exposure_ms:g} ms"
                label += suffix
                scenes.append(Scene("paper", label, name, overrides, exposure_ms, key, paper_timing=name != "paper"))
    return scenes, missing
