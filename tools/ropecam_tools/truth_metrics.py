"""Errors of pipeline results against a simulator frame set's ground truth (pixels and millimetres on the plane).

`measure_frameset` runs one method over a frame set and returns one `FrameErrors` per frame; `summarise` turns them
into the figures of a table row. Definitions (also in docs/robustness.md):

* tip error: distance of our free tip to the true one, at the start and at the end of the exposure (px);
* centreline error: mean distance of 100 points spread evenly along the true centreline to our polyline (px);
* start-point error: distance of our shape's first point (the fixed end) to the true one (px);
* material-point error: our material points (pixels, back-projected onto the motion plane with the simulator's true
  camera and plane pose, i.e. a perfect calibration) against the true positions of the same material arc lengths
  (mm);
* silent failure: a frame whose status is OK but whose worse tip error exceeds `SILENT_TIP_PX` or whose worse
  centreline error exceeds `SILENT_CURVE_PX`;
* flagged: a frame with both shapes whose status tells the user not to trust them (any status but OK and the
  no-blur status `TRUSTED_STATUSES`): the device says so, so it is not silent, but it is not a measurement either;
  missing + flagged is the share of frames that give the user no trusted shape;
* time order: among frames whose true tip moves at least `ORDER_MIN_SWEEP_PX`, our begin/end tips are closer to the
  true begin/end tips than to the swapped ones.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

SILENT_TIP_PX = 3.0
SILENT_CURVE_PX = 1.0
ORDER_MIN_SWEEP_PX = 2.0
TRUSTED_STATUSES = frozenset({"OK", "NO_BLUR"})
"""Statuses whose shapes a user may take as measured (NO_BLUR: the rope did not move; its shapes are the still
centreline)."""
CURVE_SAMPLES = 100
MATERIAL_FRACTIONS = (0.25, 0.5, 0.75, 1.0)
"""Material points tracked, as fractions of the rope's length from the fixed end."""


def point_to_polyline(points: NDArray[np.float64], poly: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the distance of each point (k, 2) to the polyline (m, 2), shape (k,) (to its point when m = 1: a
    pipeline's shape may be one point on a rejected frame)."""
    if len(poly) == 1:
        return np.hypot(*(points - poly[0]).T)
    a = poly[:-1][None]
    d = (poly[1:] - poly[:-1])[None]
    p = points[:, None]
    t = np.clip(((p - a) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-12), 0.0, 1.0)
    foot = a + t[..., None] * d
    return np.min(np.hypot(*(p - foot).transpose(2, 0, 1)), axis=1)


def resample(poly: NDArray[np.float64], count: int) -> NDArray[np.float64]:
    """Return `count` points at equal arc length along `poly` (m, 2), shape (count, 2)."""
    seg = np.hypot(*np.diff(poly, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    target = np.linspace(0.0, s[-1], count)
    return np.stack([np.interp(target, s, poly[:, 0]), np.interp(target, s, poly[:, 1])], axis=1)


@dataclass(frozen=True, slots=True)
class FrameErrors:
    """Errors of one frame. NaN where the pipeline gave no such output.

    Attributes
    ----------
    status
        The pipeline's `FrameStatus` name.
    shapes
        Both the begin and the end shape were reported.
    tip_begin_px, tip_end_px
        Free-tip errors at the start and the end of the exposure (px).
    start_begin_px, start_end_px
        Fixed-end (first point) errors of the begin and end shapes (px).
    curve_begin_px, curve_end_px
        Mean distance from the true centreline to ours (px).
    material_mm
        Mean material-point error on the plane over the tracked points, begin and end shapes (mm).
    order
        1.0 right time order, 0.0 swapped, NaN when the true tip moved less than `ORDER_MIN_SWEEP_PX`.
    pipeline_ms
        The pipeline's own time for the frame (`PipelineResult.pipeline_us`), milliseconds.
    """

    status: str
    shapes: bool
    tip_begin_px: float
    tip_end_px: float
    start_begin_px: float
    start_end_px: float
    curve_begin_px: float
    curve_end_px: float
    material_mm: float
    order: float
    pipeline_ms: float

    @property
    def silent(self) -> bool:
        """Status OK but the tip or the centreline is wrong (see the module docstring)."""
        if self.status != "OK" or not self.shapes:
            return False
        tip = max(self.tip_begin_px, self.tip_end_px)
        curve = max(self.curve_begin_px, self.curve_end_px)
        return bool(tip > SILENT_TIP_PX or curve > SILENT_CURVE_PX or math.isnan(tip) or math.isnan(curve))


def _material_truth(s_m: NDArray[np.float64], true_m: NDArray[np.float64], arcs: NDArray[np.float64]) -> NDArray:
    return np.stack([np.interp(arcs, s_m, true_m[:, 0]), np.interp(arcs, s_m, true_m[:, 1])], axis=1)


def frame_errors(result: Any, truth: dict[str, NDArray[Any]], position: int, camera: Any, plane: Any) -> FrameErrors:
    """Compare one `PipelineResult` with frame `position` of a frame set's truth arrays.

    Parameters
    ----------
    result
        The pipeline's `PipelineResult` for the frame.
    truth
        The frame set's ``truth.npz`` arrays (``begin_px``/``end_px`` (F, S, 2) (u, v), ``begin_m``/``end_m``
        (F, S, 2) metres on the plane, ``s_m`` (S,)).
    position
        Frame number in the set.
    camera, plane
        The true `CameraModel` and `PlanePose` (for the material points in mm).
    """
    from ropecam.host.calibration.geometry import pixels_to_plane

    nan = math.nan
    status = result.status.name
    true_b, true_e = truth["begin_px"][position], truth["end_px"][position]
    ms = result.pipeline_us / 1000.0
    if result.begin is None or result.end is None:
        return FrameErrors(status, False, nan, nan, nan, nan, nan, nan, nan, nan, ms)
    ours_b = result.begin[:, ::-1].astype(np.float64)
    ours_e = result.end[:, ::-1].astype(np.float64)
    tip_b = float(np.hypot(*(ours_b[-1] - true_b[-1])))
    tip_e = float(np.hypot(*(ours_e[-1] - true_e[-1])))
    curve_b = float(point_to_polyline(resample(true_b, CURVE_SAMPLES), ours_b).mean())
    curve_e = float(point_to_polyline(resample(true_e, CURVE_SAMPLES), ours_e).mean())
    order = nan
    if np.hypot(*(true_e[-1] - true_b[-1])) >= ORDER_MIN_SWEEP_PX:
        swapped = np.hypot(*(ours_b[-1] - true_e[-1])) + np.hypot(*(ours_e[-1] - true_b[-1]))
        order = 1.0 if tip_b + tip_e <= swapped else 0.0
    material = nan
    if result.material_begin is not None and len(result.material_arc_m):
        arcs = np.asarray(result.material_arc_m, dtype=np.float64)
        errors = []
        for ours_px, true_m in ((result.material_begin, truth["begin_m"]), (result.material_end, truth["end_m"])):
            if ours_px is None:
                continue
            try:
                ours_m = pixels_to_plane(ours_px[:, ::-1].astype(np.float64), camera, plane)
            except ValueError:  # a point whose ray misses the plane: count it as missing, not as an error
                continue
            expected = _material_truth(truth["s_m"], true_m[position], arcs)
            errors.extend(np.hypot(*(ours_m - expected).T) * 1000.0)
        if errors:
            material = float(np.mean(errors))
    start_b = float(np.hypot(*(ours_b[0] - true_b[0])))
    start_e = float(np.hypot(*(ours_e[0] - true_e[0])))
    return FrameErrors(status, True, tip_b, tip_e, start_b, start_e, curve_b, curve_e, material, order, ms)


def frameset_camera(meta: dict[str, Any]) -> tuple[Any, Any]:
    """Return the true `CameraModel` and `PlanePose` recorded in a simulator frame set's metadata."""
    from ropecam.host.calibration.geometry import CameraModel, PlanePose

    camera = meta["camera"]
    model = CameraModel(
        np.asarray(camera["camera_matrix"], dtype=np.float64),
        np.asarray(camera["distortion"], dtype=np.float64),
        tuple(camera["image_size"]),
    )
    return model, PlanePose.from_rvec(meta["plane"]["rvec"], meta["plane"]["tvec_m"])


def frameset_plane(meta: dict[str, Any]) -> Any:
    """Return the simulator's true camera and plane as the device's `PlaneCalibration` (what a perfect
    ``plane.yaml`` holds)."""
    from ropecam.shared.plane import PlaneCalibration

    camera, plane = frameset_camera(meta)
    return PlaneCalibration(
        camera.camera_matrix, camera.distortion.ravel(), tuple(camera.image_size), plane.rotation,
        plane.translation_m, "the frame set's true plane",
    )  # fmt: skip


def open_truth_set(path: str | Path) -> tuple[Any, dict[str, NDArray[Any]]]:
    """Return the simulator frame set at `path` (a `FrameSet`) and its ``truth.npz`` arrays.

    Raises
    ------
    ValueError
        The frame set has no ground truth.
    """
    from ropecam.device.capture.frameset import FrameSet

    frameset = FrameSet(path)
    truth = frameset.truth()
    if truth is None:
        raise ValueError(f"{path}: no truth.npz (a simulator frame set is needed)")
    return frameset, truth


def measure_frameset(
    path: str | Path, method: str, frames: int | None = None, plane: bool = False, config: Any = None
) -> list[FrameErrors]:
    """Run `method` over a simulator frame set, as the device would (fixed end found automatically, or with
    `plane` from the true plane calibration as the device's ``plane_file`` gives it).

    The pipeline is told the rope's true length (``rig.rope_length_m``) so that its material points (at
    `MATERIAL_FRACTIONS` of the length) are the same material as the truth's; nothing else of the truth is given
    (but the plane calibration with `plane`).

    Parameters
    ----------
    path
        The frame set's folder (with ``truth.npz``).
    method
        A pipeline method (`ropecam.device.pipeline.config.METHODS`).
    frames
        Use at most this many frames (all when None).
    plane
        Give the pipeline the frame set's true plane calibration (a perfect ``plane.yaml``).
    config
        A `PipelineConfig` to start from (a device.toml's, e.g. written by ``ropecam-device setup``); its method,
        rope length and material points are replaced as above. None: the defaults.

    Raises
    ------
    ValueError
        The frame set has no ground truth.
    """
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline

    fs, truth = open_truth_set(path)
    rig = fs.meta.get("rig", {})
    length_m = float(rig.get("rope_length_m", 1.0))
    config = replace(
        PipelineConfig() if config is None else config,
        method=method,  # type: ignore[arg-type]
        rope_length_m=length_m,
        material_points_m=tuple(round(f * length_m, 9) for f in MATERIAL_FRACTIONS),
    )
    camera, pose = frameset_camera(fs.meta)
    readout_us = round(float(rig.get("readout_ms", 0.0)) * 1000.0)
    pipeline = Pipeline(config, fs.image_size, readout_us, frameset_plane(fs.meta) if plane else None)
    count = len(fs) if frames is None else min(frames, len(fs))
    out = []
    for position in range(count):
        record = fs.records[position]
        result = pipeline.process(fs.read(position), position, record.t_ns, float(record.exposure_us))
        out.append(frame_errors(result, truth, position, camera, pose))
    return out


def _stat(values: list[float], how: str) -> float:
    finite = [v for v in values if not math.isnan(v)]
    if not finite:
        return math.nan
    if how == "mean":
        return float(np.mean(finite))
    if how == "max":
        return float(np.max(finite))
    return float(np.percentile(finite, 95))


def summarise(frames: list[FrameErrors]) -> dict[str, Any]:
    """Return the figures of a table row (percentages 0-100, NaN where nothing was measured).

    Tip statistics pool the begin and end tips of every frame with shapes; missing % counts frames without both
    shapes; flagged % frames with both shapes and a status outside `TRUSTED_STATUSES`; silent %, missing % and
    flagged % are of all frames.
    """
    measured = [f for f in frames if f.shapes]
    tips = [f.tip_begin_px for f in measured] + [f.tip_end_px for f in measured]
    curves = [f.curve_begin_px for f in measured] + [f.curve_end_px for f in measured]
    orders = [f.order for f in measured if not math.isnan(f.order)]
    statuses: dict[str, int] = {}
    for f in frames:
        statuses[f.status] = statuses.get(f.status, 0) + 1
    n = max(len(frames), 1)
    row: dict[str, Any] = {
        "frames": len(frames),
        "tip_mean_px": _stat(tips, "mean"),
        "tip_p95_px": _stat(tips, "p95"),
        "curve_mean_px": _stat(curves, "mean"),
        "material_mean_mm": _stat([f.material_mm for f in measured], "mean"),
        "missing_pct": 100.0 * (len(frames) - len(measured)) / n,
        "flagged_pct": 100.0 * sum(f.status not in TRUSTED_STATUSES for f in measured) / n,
        "silent_pct": 100.0 * sum(f.silent for f in frames) / n,
        "order_right_pct": 100.0 * float(np.mean(orders)) if orders else math.nan,
        "order_frames": len(orders),
        "pipeline_ms": _stat([f.pipeline_ms for f in frames], "mean"),
        "statuses": statuses,
    }
    for key in ("tip_begin_px", "tip_end_px", "start_begin_px", "start_end_px"):
        values = [getattr(f, key) for f in measured]
        row[f"{key[:-3]}_mean_px"] = _stat(values, "mean")
        row[f"{key[:-3]}_max_px"] = _stat(values, "max")
    return row


def frame_rows(frames: list[FrameErrors]) -> list[dict[str, Any]]:
    """Per-frame errors as plain dicts (for the JSON output)."""
    return [asdict(f) for f in frames]
