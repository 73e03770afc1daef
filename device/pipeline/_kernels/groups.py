"""Named groups of arrays that kernels take as one argument: `typing.NamedTuple` classes and their Numba types.

Each group mirrors a group of the pipeline's workspace (`ropecam.device.pipeline.workspace`), which makes its
instance once; a kernel reads a member by name (``motion.log``), never by position. A group is typed as a
whole at every call from Python (about 1 us per member on top of the call: measured in `docs/speed.md`,
"Named argument groups"), so the per-frame path passes them from compiled code (`steady_frame`) or on frames
that are not steady. The members are writable arrays: Numba does not convert a group of writable arrays into a
group of read-only ones, and `steady_frame` makes its groups from writable buffers; the docstrings of the kernels
say which members they write.
"""

from __future__ import annotations

from typing import Any, Final, NamedTuple

import numpy as np
from numba import float32, float64, int32, types
from numba.np.numpy_support import from_dtype

from ropecam.shared.jit import f4_1d, f4_2d, f8_1d, f8_2d, i4_1d, i4_2d, u1_1d, u1_2d

i8_1d: Final = types.Array(types.int64, 1, "C")
f4_3d: Final = types.Array(types.float32, 3, "C")

# A record read by field name, not a float64 vector read through numbered slots: the fields keep their own types
# (a count, a flag), NumPy takes the same ``state["name"]`` (the kernels run without the JIT too), it is one
# argument and one row of `steady_frame`'s table like the vector it replaces, and a record type caches as any
# array type. A named tuple of small arrays would have cost a table row and ~0.2 us of typing per member on every
# call from Python, and ``[0]`` on every read.
BAND_STATE: Final = np.dtype(
    [
        ("fixed_r", np.float64),
        ("fixed_c", np.float64),
        ("motion_px", np.float64),
        ("moved", np.int64),
        ("motion_held", np.bool_),
    ],
    align=True,
)
"""What `band_stage` built its last band with, one record (`Motion.band`, shape (1,)): the fixed end
(``fixed_r``, ``fixed_c``) it was built about, its uncertainty at the farthest point (``motion_px``), the number
of points it moved (``moved``, written to `Band.moved`), and ``motion_held``: the motion model held at least
``MOTION_FRAMES - 1`` frames when it was predicted."""
band_state_1d: Final = types.Array(from_dtype(BAND_STATE), 1, "C")


class Motion(NamedTuple):
    """The motion model's arrays (`MotionBuffers`): `predict_motion`'s and `observe_motion`'s ``state`` and
    ``log``, the band prediction's measured error ``need`` (2, bins) and ``profile`` (bins,), and ``band`` (one
    `BAND_STATE` record: what the last band was built with)."""

    state: Any
    log: Any
    need: Any
    profile: Any
    band: Any


MOTION: Final = types.NamedTuple((i8_1d, f8_2d, f8_2d, f8_1d, band_state_1d), Motion)


class Band(NamedTuple):
    """A band's row spans ``lo``/``hi`` (int32, one per image row) and the last contour moved by the prediction
    (``moved``, float32 (capacity, 2)): `band_stage`'s outputs (`RoiBuffers`)."""

    lo: Any
    hi: Any
    moved: Any


BAND: Final = types.NamedTuple((i4_1d, i4_1d, f4_2d), Band)


HISTORY: Final = 6
"""Tip samples kept for the time order (two per split frame: three frames)."""
ORDER_COUNT: Final = HISTORY
"""``Order.state`` after the sample times: samples held,"""
ORDER_ORDERED: Final = HISTORY + 1
"""whether the history's own order is known (0/1),"""
ORDER_REJECTS: Final = HISTORY + 2
"""frames off the predicted path in a row,"""
ORDER_PREV_COUNT: Final = HISTORY + 3
"""points of the previous frame's end shape in ``Order.prev_end`` (0: none),"""
ORDER_PREV_T: Final = HISTORY + 4
"""and the end of that shape's exposure (ns)."""
ORDER_STATE_SIZE: Final = HISTORY + 5


class Static(NamedTuple):
    """The static mask and each pixel's learned grey-level range (`EdgeBuffers`' ``static_mask``,
    ``static_low``, ``static_high``; uint8, the image's shape, or 1x1 each when there is no mask), and the mask's
    summary ``static_near`` (`mark_near_blocks`; uint8, 1-D; empty: none), which `drop_static_edges` and
    `seal_cut_ends` read."""

    mask: Any
    low: Any
    high: Any
    near: Any


STATIC: Final = types.NamedTuple((u1_2d, u1_2d, u1_2d, u1_1d), Static)


class EdgeWork(NamedTuple):
    """The edge stage's buffers besides its planes (`EdgeBuffers`): the span scratch ``work_spans`` (int32 (4,
    rows)), the smoothing's row pass ``tmp`` (float32, the image's shape), the edge map ``edges`` (uint8) and the
    edge list ``stack`` (int32 flat indices, one slot per pixel): `detect_edges`' outputs besides the planes."""

    work_spans: Any
    tmp: Any
    edges: Any
    stack: Any


EDGE_WORK: Final = types.NamedTuple((i4_2d, f4_2d, u1_2d, i4_1d), EdgeWork)


class Contour(NamedTuple):
    """The contour stage's buffers (`ContourBuffers`), `trace_rope`'s outputs: component ``labels`` (int32, the
    image's shape) and ``stack`` (int32, one slot per pixel), the component's first pixel ``start`` (int32
    (2,)), the ``chain`` (int32 (capacity, 2)), its Freeman ``codes`` (int32 (capacity,)), its subpixel
    ``points`` (float32 (capacity, 2)) and the trace's ``counts`` (int32 (4,))."""

    labels: Any
    stack: Any
    start: Any
    chain: Any
    codes: Any
    points: Any
    counts: Any


CONTOUR: Final = types.NamedTuple((i4_2d, i4_1d, i4_1d, i4_2d, i4_1d, f4_2d, i4_1d), Contour)


class Order(NamedTuple):
    """The time order's arrays (`OrderBuffers`): sample times and counters ``state`` (int64, `ORDER_STATE_SIZE`:
    the `HISTORY` sample times, then the ``ORDER_*`` slots), sample tips ``hist_rc`` (float64 (HISTORY, 2)), the
    previous frame's end shape ``prev_end`` (float32 (capacity, 2)) and `uncross_shapes`' scratch ``splice``
    (float32 (3, 2 capacity, 2))."""

    state: Any
    hist_rc: Any
    prev_end: Any
    splice: Any


ORDER: Final = types.NamedTuple((i8_1d, f8_2d, f4_2d, f4_3d), Order)


class Track(NamedTuple):
    """The material points' arrays (`TrackBuffers`): arc ``fraction`` (float64, read only by the kernels), their
    positions on both shapes ``out`` (float32 (2, points, 2)), the shapes' lengths ``lengths_px`` (float64 (2,))
    and a shape's segment lengths ``work`` (float64)."""

    fraction: Any
    out: Any
    lengths_px: Any
    work: Any


TRACK: Final = types.NamedTuple((f8_1d, f4_3d, f8_1d, f8_1d), Track)


class Planes(NamedTuple):
    """The edge stage's float planes that the split reads (`EdgeBuffers`): the smoothed image ``smooth`` (which
    `split_frame` also writes, around the band's corners), the Sobel gradients ``gx``, ``gy`` and their norm
    ``mag`` (float32, the image's shape)."""

    smooth: Any
    gx: Any
    gy: Any
    mag: Any


PLANES: Final = types.NamedUniTuple(f4_2d, 4, Planes)


class SplitWork(NamedTuple):
    """The blur split's buffers (`SplitBuffers`): ``lines`` float32 (3, capacity) (work, the sweeps of side A, of
    side B), ``sides`` float32 (4, capacity, 2) (side A, side B, out A, out B), ``scratch`` float64 (3, capacity)
    (arc lengths, distances from the fixed end, slope work), the turning angles ``turn``, the segmentation
    indices ``idx`` (4,), the segmentation points ``seg`` (2, 2) and the results ``info`` (`FRAME_INFO`)."""

    lines: Any
    sides: Any
    scratch: Any
    turn: Any
    idx: Any
    seg: Any
    info: Any


SPLIT_WORK: Final = types.NamedTuple((f4_2d, f4_3d, f8_2d, f4_1d, i4_1d, f4_2d, f8_1d), SplitWork)


class SplitWidth(NamedTuple):
    """What the blur split takes from the rope's width (`WidthTables.group`): the edge model's ``ratios`` and
    ``sweeps`` (float64) and ``offsets`` (float32) tables, then the scalars, each of the type the kernels compute
    with: the sweep window ``half`` (points), the table's ``step_px``, the width ``width_px``, the tip cap
    ``cap_px``, the tip fit's ``skip_px``, ``span_px`` and ``blur_px``, the slant gain ``slant_gain_px`` and the
    width again as ``width64_px`` (float64: the length check's and the sweep tests'), the output's
    ``out_step_px`` and ``smoothing_px``; the segmentation points' ``scale`` and ``min_gap`` (int32),
    ``search_px`` (float64) and ``corner_rad``, the corner box's growth ``grow_px`` and the ``static_ratio``
    (sweep / width below which the rope is taken as not moving; float64), and the rope's own width ``rope_px``
    (float64: the edge model's for this edge spacing, which the band's integral across is the contrast times);
    ``through_fixed`` (float64) 1 when the fixed end is given (plane, ``fixed_end_uv``): the shapes start at it
    (`anchor_start`), not at its foot on the fitted axis."""

    ratios: Any
    sweeps: Any
    offsets: Any
    half: Any
    step_px: Any
    width_px: Any
    cap_px: Any
    skip_px: Any
    span_px: Any
    blur_px: Any
    slant_gain_px: Any
    width64_px: Any
    out_step_px: Any
    smoothing_px: Any
    scale: Any
    min_gap: Any
    search_px: Any
    corner_rad: Any
    grow_px: Any
    static_ratio: Any
    rope_px: Any
    through_fixed: Any


SPLIT_WIDTH_SCALARS: Final = SplitWidth._fields[3:]
"""The scalars of `SplitWidth`, in order: `steady_frame`'s table holds them as one float64 array (each exactly
representable) that `split_width` reads by these names."""
SPLIT_WIDTH: Final = types.NamedTuple(
    (f8_1d, f8_1d, f4_1d, int32, float32, float32, float32, float32, float32, float32, float64, float64, float32,
     float32, int32, int32, float64, float32, float64, float64, float64, float64),
    SplitWidth,
)  # fmt: skip

__all__ = [
    "BAND",
    "BAND_STATE",
    "CONTOUR",
    "EDGE_WORK",
    "MOTION",
    "ORDER",
    "PLANES",
    "SPLIT_WIDTH",
    "SPLIT_WIDTH_SCALARS",
    "SPLIT_WORK",
    "STATIC",
    "TRACK",
    "Band",
    "Contour",
    "EdgeWork",
    "Motion",
    "Order",
    "Planes",
    "SplitWidth",
    "SplitWork",
    "Static",
    "Track",
    "f4_3d",
    "i8_1d",
]
