"""Decide a rig's `[pipeline]` settings from a few seconds of its frames, by running the pipeline itself.

Nothing here re-implements a pipeline step: each candidate setting is tried by running `Pipeline` over the frames,
and the setting that measures most frames, most consistently (the same rope length, width and fixed end on every
frame) is kept. The static mask comes from the pipeline's own `EdgeDetector` run over whole frames, and every
candidate runs with it, as the device will.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline.background import BackgroundFlattening
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.edge_profile import EdgeBlur
from ropecam.device.pipeline.edges import EdgeDetector
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus
from ropecam.device.pipeline.tone import ToneCurve
from ropecam.device.setup_overlay import write_png

__all__ = ["THRESHOLDS", "Frame", "Run", "SetupFindings", "decide", "run_candidate", "static_mask"]

THRESHOLDS: tuple[tuple[float, float], ...] = ((8.0, 20.0), (12.0, 30.0), (20.0, 50.0), (32.0, 80.0), (48.0, 120.0))
"""Candidate Canny hysteresis thresholds (low, high), the pipeline's default (20, 50) among them."""
MIN_MEASURED = 0.5
"""A setting that gives shapes on fewer than this fraction of the frames has not found a rope."""
STATIC_FRACTION = 0.5
"""A pixel that is an edge in at least this fraction of the frames belongs to the static mask. Half, not nearly
all: the rope passes over the clamp's edge where it leaves the clamp on most frames and hides it there (at 0.9
that part of the clamp's outline stayed out of the mask and joined the rope's contour). A moving rope's own
pixels are edges on far fewer frames; the few still ones next to the clamp are masked too, and the pipeline seals
and extends the rope across them (`seal_cut_ends`, `anchor_start`)."""
FIXED_END_SPREAD_PX = 3.0
"""The fixed end is decided when its per-frame readings stay within this distance of their median (p90)."""
WIDTH_SPREAD = 0.25
"""The rope width is decided when its per-frame readings stay within this fraction of their median (IQR)."""
LENGTH_SPREAD = 0.05
"""Lc0 is decided when the shapes' lengths stay within this fraction of their median (IQR / median)."""


@dataclass(frozen=True, slots=True)
class Frame:
    """One frame to decide from: 8-bit grey image, start of exposure (ns), exposure (us; 0 = unknown)."""

    image: NDArray[np.uint8]
    t_ns: int
    exposure_us: float


@dataclass(slots=True)
class Run:
    """What the pipeline measured over the frames with one setting."""

    config: PipelineConfig
    statuses: dict[str, int] = field(default_factory=dict)
    lengths_px: list[float] = field(default_factory=list)
    widths_px: list[float] = field(default_factory=list)
    fixed_uv: list[tuple[float, float]] = field(default_factory=list)
    shapes: dict[int, tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32] | None]] = field(
        default_factory=dict
    )
    """Frame position -> (begin, end, segmentation points) copies, (row, col)."""
    tips: list[tuple[float, float]] = field(default_factory=list)
    """(row, col) of both free tips of every frame with shapes."""
    blur: EdgeBlur | None = None
    """The camera's blur and sharpening the pipeline measured on the first frames (None: not measured)."""
    frames: int = 0
    reasons: dict[str, int] = field(default_factory=dict)
    """Why frames were not measured: each status but OK with the first clause of its message, and its count."""
    thresholds_used: tuple[float, float] | None = None
    """The Canny thresholds the pipeline used last (low, high): measured from the frames' own noise, at most the
    configured ones (`EdgeThresholds`); None when it measured none."""

    @property
    def found(self) -> bool:
        """Whether what was measured is a rope (it moves, and its length is the same on every frame measured),
        whatever share of the frames it was measured on."""
        return bool(self.shapes) and self.moving and self.length_spread <= LENGTH_SPREAD

    @property
    def tip_spread_px(self) -> float:
        """90th percentile of the tips' distances from their median (0 without shapes): how far the rope moves."""
        if not self.tips:
            return 0.0
        tips = np.asarray(self.tips)
        return float(np.percentile(np.hypot(*(tips - np.median(tips, axis=0)).T), 90))

    @property
    def moving(self) -> bool:
        """Whether what was measured moves (a still outline is a rod, a clamp or a static cable, not the rope)."""
        width = float(np.median(self.widths_px)) if self.widths_px else 3.0
        return self.tip_spread_px > 2.0 * width + 2.0

    @property
    def measured(self) -> float:
        """Fraction of the frames with both shapes."""
        return len(self.shapes) / max(self.frames, 1)

    @property
    def length_spread(self) -> float:
        """Interquartile range of the shapes' lengths over their median (inf without shapes)."""
        if len(self.lengths_px) < 2:
            return math.inf
        q1, q2, q3 = np.percentile(self.lengths_px, (25, 50, 75))
        return float((q3 - q1) / q2) if q2 > 0 else math.inf

    @property
    def score(self) -> float:
        """Measured fraction, lowered by inconsistent lengths (0 when what was measured does not move): the setting
        with the highest score is kept."""
        if not self.moving:
            return 0.0
        return self.measured * max(0.0, 1.0 - 5.0 * min(self.length_spread, 1.0))


@dataclass(slots=True)
class SetupFindings:
    """What setup decided (`settings`: `[pipeline]` keys), what it measured, and what it could not decide."""

    settings: dict[str, Any]
    run: Run
    notes: list[str]
    undecided: list[str]
    mask: NDArray[np.bool_] | None
    length_px: float | None
    split_frame: int | None
    tried: list[str]
    image_shape: tuple[int, int] = (0, 0)
    """(height, width) of the frames."""


def _polyline_length(points: NDArray[np.float32]) -> float:
    return float(np.hypot(*np.diff(points.astype(np.float64), axis=0).T).sum()) if len(points) > 1 else 0.0


def run_candidate(frames: Sequence[Frame], config: PipelineConfig, keep_shapes: bool = False) -> Run:
    """Run the pipeline with `config` over `frames` and collect what it measured (`Run`); with the config's
    `plane_file` as the device runs it (the fixed end from the plane)."""
    height, width = frames[0].image.shape
    plane = None
    if config.plane_file:
        from ropecam.shared.plane import read_plane_file

        plane = read_plane_file(config.plane_file)
    pipeline = Pipeline(config, (width, height), plane=plane)
    run = Run(config, frames=len(frames))
    for position, frame in enumerate(frames):
        result = pipeline.process(frame.image, position, frame.t_ns, frame.exposure_us)
        name = result.status.name
        run.statuses[name] = run.statuses.get(name, 0) + 1
        if result.status is not FrameStatus.OK:
            why = f"{name}: {result.message.split(':')[0].split(' (')[0]}" if result.message else name
            run.reasons[why] = run.reasons.get(why, 0) + 1
        if result.status is not FrameStatus.OK or result.begin is None or result.end is None:
            continue
        run.lengths_px += [_polyline_length(result.begin), _polyline_length(result.end)]
        run.tips += [(float(result.begin[-1, 0]), float(result.begin[-1, 1]))]
        run.tips += [(float(result.end[-1, 0]), float(result.end[-1, 1]))]
        if result.rope_width_px is not None and math.isfinite(result.rope_width_px):
            run.widths_px.append(float(result.rope_width_px))
        if result.fixed_end is not None:
            run.fixed_uv.append((float(result.fixed_end[1]), float(result.fixed_end[0])))
        seg = None if result.segmentation_points is None else result.segmentation_points.copy()
        run.shapes[position] = (
            (result.begin.copy(), result.end.copy(), seg) if keep_shapes else (result.begin[:0], result.end[:0], None)
        )
    run.blur = pipeline.splitter.blur_read
    used = pipeline.thresholds.used
    run.thresholds_used = None if used is None else (float(used[0]), float(used[1]))
    return run


def static_mask(
    frames: Sequence[Frame], config: PipelineConfig, samples: int = 40
) -> tuple[NDArray[np.bool_], NDArray[np.float32]]:
    """Return the pixels that are edges in at least `STATIC_FRACTION` of up to `samples` frames (the pipeline's
    edge detector over whole frames, in linear light as the pipeline sees them), grown by one pixel, and each
    pixel's edge frequency (0-1)."""
    height, width = frames[0].image.shape
    detector = EdgeDetector(height, width, config.smooth_sigma_px, config.canny_low, config.canny_high)
    tone = (
        BackgroundFlattening.from_png(config.background_png, (height, width), config.gamma)
        if config.background_png
        else ToneCurve(config.gamma, (height, width))
    )
    lo = np.zeros(height, np.int32)
    hi = np.full(height, width - 1, np.int32)
    picks = np.unique(np.linspace(0, len(frames) - 1, min(samples, len(frames))).round().astype(int))
    counts = np.zeros((height, width), np.float32)
    for position in picks:
        detector.detect(tone.apply(frames[position].image), lo, hi)
        counts += detector.edges != 0
    frequency = counts / len(picks)
    static = frequency >= STATIC_FRACTION
    # Noise moves a static edge by a pixel now and then: the mask covers its 8 neighbours too.
    grown = static.copy()
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            grown[max(dr, 0) : height + min(dr, 0), max(dc, 0) : width + min(dc, 0)] |= static[
                max(-dr, 0) : height + min(-dr, 0), max(-dc, 0) : width + min(-dc, 0)
            ]
    return grown, frequency


def decide(
    frames: Sequence[Frame],
    base: PipelineConfig,
    progress: Callable[[str], None] = lambda _: None,
    trial_frames: int = 60,
) -> SetupFindings:
    """Decide polarity, edge thresholds, rope width, Lc0 (px), fixed end and static mask from `frames`.

    Parameters
    ----------
    frames
        The rig's frames (at least 5), in order, all of one size.
    base
        Settings not decided here (method, rope length in metres, material points ...).
    progress
        Called with one line of progress per step.
    trial_frames
        Frames (the first ones) each candidate setting is tried on; the kept one then runs over all frames.
        Each candidate runs with the static mask learned at its thresholds (`static_mask_png`).

    Returns
    -------
    SetupFindings
        ``settings`` holds only the keys that were decided; ``undecided`` says what was not, and why. ``run`` is
        None-free: when no setting found a rope, ``run.measured`` is below `MIN_MEASURED` (the caller reports it).
    """
    if len(frames) < 5:
        raise ValueError(f"setup needs at least 5 frames, got {len(frames)}")
    trial = frames[: max(5, min(trial_frames, len(frames)))]
    tried: list[str] = []
    runs: list[Run] = []
    masks: list[NDArray[np.bool_]] = []
    with tempfile.TemporaryDirectory(prefix="ropecam-setup-") as folder:
        for index, (low, high) in enumerate(THRESHOLDS):
            # The static mask at these thresholds (edges in nearly every frame), applied as the device will.
            config = replace(base, canny_low=low, canny_high=high, polarity="auto", static_mask_png="")
            mask, _ = static_mask(frames, config)
            masks.append(mask)
            mask_file = Path(folder) / f"mask{index}.png"
            write_png(mask_file, mask.astype(np.uint8) * 255)
            run = run_candidate(trial, replace(config, static_mask_png=str(mask_file)))
            runs.append(run)
            tried.append(
                f"edges {low:g}/{high:g}{_used(run)}: static mask {100 * mask.mean():.2f} % of the frame; shapes on "
                f"{100 * run.measured:.0f} % of {run.frames} frames, length spread {100 * run.length_spread:.1f} %, "
                f"tips move {run.tip_spread_px:.0f} px (p90)"
            )
            progress(tried[-1])
        default_index = THRESHOLDS.index((20.0, 50.0))
        # Ties (within 2 % of the best score) go to the default, then to the lower thresholds (fewer edges lost).
        best_score = max(r.score for r in runs)
        close = [i for i, r in enumerate(runs) if r.score >= best_score - 0.02]
        chosen = default_index if default_index in close else close[0]
        thresholds = runs[chosen].config
        # The mask also cuts the rope's own still part near the fixed end: it is kept only when it measures better.
        bare = run_candidate(trial, replace(thresholds, static_mask_png=""))
        shape = frames[0].image.shape
        use_mask = bare.score < runs[chosen].score - 0.02 or (
            _on_border(bare, shape) and not _on_border(runs[chosen], shape)
        )
        tried.append(
            f"without the static mask: shapes on {100 * bare.measured:.0f} %, length spread "
            f"{100 * bare.length_spread:.1f} %: {'mask kept' if use_mask else 'no mask (it measures no better)'}"
        )
        progress(tried[-1])
        if not use_mask:
            thresholds = replace(thresholds, static_mask_png="")
        notes: list[str] = []
        undecided: list[str] = []
        settings: dict[str, Any] = {}
        final = thresholds
        polarity, why = _polarity(trial, run_candidate(trial, thresholds, keep_shapes=True))
        if polarity is None:
            undecided.append(f"polarity: {why}; left to the per-frame decision (auto)")
        else:
            settings["polarity"] = polarity
            final = replace(thresholds, polarity=polarity)
            tried.append(f"polarity {polarity}: {why}")
            progress(tried[-1])
        progress(f"running the pipeline over all {len(frames)} frames with the chosen settings")
        run = run_candidate(frames, final, keep_shapes=True)
    findings = SetupFindings(settings, run, notes, undecided, masks[chosen] if use_mask else None, None, None, tried)
    findings.image_shape = frames[0].image.shape
    if run.measured < MIN_MEASURED or not run.moving:
        return findings
    settings["canny_low"], settings["canny_high"] = final.canny_low, final.canny_high
    _decide_traits(findings)
    share = f"{int(masks[chosen].sum())} pixels ({100 * masks[chosen].mean():.2f} % of the frame)"
    notes.append(f"static mask: {share}" + ("" if use_mask else ", not used: the pipeline measures as well without"))
    sweeps = {p: float(np.hypot(*(b[-1] - e[-1]))) for p, (b, e, _) in run.shapes.items()}
    findings.split_frame = max(sweeps, key=sweeps.__getitem__) if sweeps else None
    return findings


def _used(run: Run) -> str:
    """`run`'s thresholds as the pipeline measured them from the frames' noise, when they are below the
    configured ones (then every candidate above them measures alike)."""
    used, config = run.thresholds_used, run.config
    if used is None or (used[0] >= config.canny_low and used[1] >= config.canny_high):
        return ""
    return f" (measured from the frames' noise: {used[0]:.1f}/{used[1]:.1f})"


def _on_border(run: Run, shape: tuple[int, int]) -> bool:
    """Whether the run's median fixed end lies on the image border (a rod or cable taken for the rope's root)."""
    if not run.fixed_uv:
        return False
    u, v = np.median(np.asarray(run.fixed_uv), axis=0)
    return bool(min(u, v, shape[1] - 1 - u, shape[0] - 1 - v) < 2.0)


def _polarity(frames: Sequence[Frame], run: Run) -> tuple[str | None, str]:
    """Bright or dark rope: the grey level on the measured centrelines against the frame's median, per frame with
    shapes; decided when at least 80 % of those frames agree."""
    votes = []
    for position, (begin, end, _) in run.shapes.items():
        image = frames[position].image
        points = np.round(np.concatenate([begin, end])).astype(int)
        ok = (
            (points[:, 0] >= 0)
            & (points[:, 0] < image.shape[0])
            & (points[:, 1] >= 0)
            & (points[:, 1] < image.shape[1])
        )
        if ok.sum() < 10:
            continue
        on_rope = float(np.median(image[points[ok, 0], points[ok, 1]]))
        votes.append(on_rope - float(np.median(image)))
    if len(votes) < 3:
        return None, f"{len(votes)} frames with shapes to read it from, 3 needed"
    bright = sum(v > 0 for v in votes) / len(votes)
    if bright >= 0.8 or bright <= 0.2:
        name = "bright" if bright >= 0.8 else "dark"
        share = 100 * max(bright, 1 - bright)
        return name, (
            f"the centrelines are {name}er than the frame's median on {share:.0f} % of {len(votes)} frames "
            f"(median difference {np.median(votes):+.0f} DN)"
        )
    return (
        None,
        f"the centrelines are brighter than the frame's median on {100 * bright:.0f} % of {len(votes)} frames only",
    )


def _decide_traits(findings: SetupFindings) -> None:
    """Lens blur, rope width, Lc0 and fixed end from the kept run, each only when its readings agree."""
    run, settings = findings.run, findings.settings
    if run.blur is not None:
        # The rope width below is the edge model's for this blur: they go into the config together.
        settings["lens_blur_px"] = round(run.blur.lens_blur_px, 2)
        if run.blur.sharpen_gain > 0.0:
            settings["sharpen_gain"] = round(run.blur.sharpen_gain, 2)
            settings["sharpen_sigma_px"] = round(run.blur.sharpen_sigma_px, 2)
    elif run.config.lens_blur_px is None:
        findings.undecided.append(
            "lens_blur_px: the rope never held still enough near the fixed end to read the camera's blur; "
            "left to the pipeline's first frames"
        )
    widths = np.asarray(run.widths_px)
    if len(widths) >= 3:
        q1, median, q3 = np.percentile(widths, (25, 50, 75))
        if (q3 - q1) <= WIDTH_SPREAD * median:
            settings["rope_width_px"] = round(float(median), 3)
        else:
            findings.undecided.append(
                f"rope_width_px: readings vary too much ({q1:.2f}-{q3:.2f} px, median {median:.2f}); "
                "left to the pipeline's first frames"
            )
    else:
        findings.undecided.append(f"rope_width_px: only {len(widths)} width readings; left to the pipeline")
    if run.lengths_px:
        findings.length_px = float(np.median(run.lengths_px))
        if run.length_spread <= LENGTH_SPREAD:
            settings["length0_px"] = round(findings.length_px, 2)
        else:
            findings.undecided.append(
                f"length0_px: the shapes' lengths vary by {100 * run.length_spread:.1f} % (IQR/median, more than "
                f"{100 * LENGTH_SPREAD:.0f} %); left to the pipeline's first frames"
            )
    if run.config.plane_file:
        findings.notes.append(f"fixed end: the plane calibration's origin ({run.config.plane_file})")
    elif run.fixed_uv:
        uv = np.asarray(run.fixed_uv)
        median_uv = np.median(uv, axis=0)
        spread = float(np.percentile(np.hypot(*(uv - median_uv).T), 90))
        height, width = findings.image_shape
        on_border = min(median_uv[0], median_uv[1], width - 1 - median_uv[0], height - 1 - median_uv[1]) < 2.0
        if on_border:
            findings.undecided.append(
                f"fixed_end_uv: the pipeline's fixed end ({median_uv[0]:.0f}, {median_uv[1]:.0f}) lies on the image "
                "border: the rope's outline probably runs along a rod or cable out of the frame (see the overlay); "
                "left to the pipeline"
            )
        elif spread <= FIXED_END_SPREAD_PX:
            settings["fixed_end_uv"] = [round(float(median_uv[0]), 2), round(float(median_uv[1]), 2)]
        else:
            findings.undecided.append(
                f"fixed_end_uv: the per-frame fixed ends spread {spread:.1f} px (p90, more than "
                f"{FIXED_END_SPREAD_PX:g}); left to the pipeline's first frames"
            )
