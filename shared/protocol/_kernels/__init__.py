"""Numba kernels of the shape codec (the encoder runs on the device's per-frame path), one module per job:
`distance` (point-to-polyline distances), `spline` (B-spline fit and sampling), `coding` (varints, chains,
corrections, range checks, COBS), `encoder` (the fit-and-correct step), `decoder` (the one-call spline body)."""

from __future__ import annotations

from ropecam.shared.protocol._kernels.coding import (
    apply_corrections,
    chain_bytes,
    cobs_encode_into,
    ints_within,
    points_within,
    read_chain,
    rows_on_wire,
    svarint_bytes,
    uvarint_bytes,
    write_spline_body,
)
from ropecam.shared.protocol._kernels.decoder import decode_spline
from ropecam.shared.protocol._kernels.distance import distances_to_polyline
from ropecam.shared.protocol._kernels.encoder import fit_spline_with_corrections, fit_work_size
from ropecam.shared.protocol._kernels.spline import (
    bspline_sample_table,
    fit_bspline,
    relative_positions,
    sample_bspline,
    sample_with_table,
)

__all__ = [
    "apply_corrections",
    "bspline_sample_table",
    "chain_bytes",
    "cobs_encode_into",
    "decode_spline",
    "distances_to_polyline",
    "fit_bspline",
    "fit_spline_with_corrections",
    "fit_work_size",
    "ints_within",
    "points_within",
    "read_chain",
    "relative_positions",
    "rows_on_wire",
    "sample_bspline",
    "sample_with_table",
    "svarint_bytes",
    "uvarint_bytes",
    "write_spline_body",
]
