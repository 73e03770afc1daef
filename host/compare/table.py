"""The per-sample table of a comparison, in metres: CSV always, Parquet when pyarrow is installed.

One row per sample and material point (two samples per frame: the rope at the start and at the end of the
exposure), in the order of the samples (frames in time order, start before end):

========================  ==========================================================================================
column                    meaning
========================  ==========================================================================================
``time_s``                when the point was seen, on the device clock, s: the exposure's start or end, plus, with a
                          rolling shutter, its row's delay (docs/compare.md, "Rolling shutter"); the model is
                          evaluated there
``frame``                 the frame the sample belongs to (-1: unknown)
``sample``                ``start`` or ``end`` of that frame's exposure
``point_s_m``             the material point: unstretched arc length from the fixed end, m
``measured_x_m/_y_m``     the measured position in the plane frame (x horizontal, y down), m; empty: not measured
``model_x_m/_y_m``        the model's position at the same time and material point, m
``error_m``               ``|measured - model|``, m; its RMS over a point's rows is the summary's RMS for the point
``mid_exposure_s``        the time the in-frame velocity belongs to: the middle between the point's two times (its
                          ``time_s`` in the start and in the end row of the frame), s; with a global shutter the
                          middle of the frame's exposure
``in_frame_vx/vy_m_s``    the velocity measured within the frame: the point's displacement from the start to the
                          end of the exposure over the time between its two times, m/s (the same in both rows of a
                          frame)
``model_vx/vy_m_s``       the model's velocity at ``mid_exposure_s``, m/s: what the in-frame velocity measures to
                          second order in the time between the two shapes
========================  ==========================================================================================

``ropecam replay --export-csv`` writes the measured columns only (no model). Numbers are written with Python's
shortest exact representation (``repr``), so a reader gets back the very floats the report was computed from.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ropecam.host.compare.tracks import MaterialPointTracks
from ropecam.shared.errors import DataError

__all__ = ["sample_table", "write_table"]

Columns = dict[str, NDArray]


def sample_table(
    tracks: MaterialPointTracks,
    model_m: NDArray[np.float64] | None = None,
    error_m: NDArray[np.float64] | None = None,
    model_velocities_m_s: NDArray[np.float64] | None = None,
) -> Columns:
    """Flatten tracks (and optionally the model's positions (M, K, 2), errors (M, K) and velocities (M, K, 2))
    into the columns described in the module docstring; one row per sample and point, time-major."""
    m, k = tracks.times_s.size, tracks.s_m.size

    def per_sample(values: NDArray) -> NDArray:
        return np.repeat(values, k)

    assert tracks.point_times_s is not None and tracks.mid_exposure_s is not None  # set by __post_init__
    columns: Columns = {
        "time_s": tracks.point_times_s.ravel(),
        "frame": per_sample(tracks.frames),
        "sample": per_sample(np.where(tracks.exposure_end, "end", "start")),
        "point_s_m": np.tile(tracks.s_m, m),
        "measured_x_m": tracks.positions_m[:, :, 0].ravel(),
        "measured_y_m": tracks.positions_m[:, :, 1].ravel(),
    }
    if model_m is not None and error_m is not None:
        columns |= {
            "model_x_m": model_m[:, :, 0].ravel(),
            "model_y_m": model_m[:, :, 1].ravel(),
            "error_m": error_m.ravel(),
        }
    columns |= {
        "mid_exposure_s": tracks.mid_exposure_s.ravel(),
        "in_frame_vx_m_s": tracks.in_frame_velocities_m_s[:, :, 0].ravel(),
        "in_frame_vy_m_s": tracks.in_frame_velocities_m_s[:, :, 1].ravel(),
    }
    if model_velocities_m_s is not None:
        columns |= {
            "model_vx_m_s": model_velocities_m_s[:, :, 0].ravel(),
            "model_vy_m_s": model_velocities_m_s[:, :, 1].ravel(),
        }
    return columns


def _cell(value: object) -> str:
    if isinstance(value, float | np.floating):
        return repr(float(value)) if np.isfinite(value) else ""
    if isinstance(value, np.integer):
        return str(int(value))
    return str(value)


def write_table(columns: Columns, csv_path: Path, parquet: bool = True) -> list[Path]:
    """Write `columns` to `csv_path` and, when pyarrow is importable and `parquet` is set, beside it as
    ``.parquet`` (NaN kept); return the paths written.

    Raises
    ------
    DataError
        A file cannot be written (the message names it).
    """
    names = list(columns)
    rows = zip(*(columns[name].tolist() for name in names), strict=True)
    written = [Path(csv_path)]
    try:
        with open(csv_path, "w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(names)
            writer.writerows([_cell(v) for v in row] for row in rows)
    except OSError as exc:
        raise DataError(f"{csv_path}: cannot write the table: {exc.strerror or exc}") from exc
    if not parquet:
        return written
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return written
    parquet_path = Path(csv_path).with_suffix(".parquet")
    try:
        pq.write_table(pa.table({name: columns[name] for name in names}), parquet_path)
    except OSError as exc:
        raise DataError(f"{parquet_path}: cannot write the table: {exc}") from exc
    written.append(parquet_path)
    return written
