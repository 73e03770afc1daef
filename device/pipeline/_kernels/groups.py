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

from numba import types

from ropecam.shared.jit import f4_2d, f8_1d, f8_2d, i4_1d

i8_1d: Final = types.Array(types.int64, 1, "C")
f4_3d: Final = types.Array(types.float32, 3, "C")


class Motion(NamedTuple):
    """The motion model's arrays (`MotionBuffers`): `predict_motion`'s and `observe_motion`'s ``state`` and
    ``log``, the band prediction's measured error ``need`` (2, bins) and ``profile`` (bins,), and ``band``
    (`BAND_SLOTS`: what the last band was built with)."""

    state: Any
    log: Any
    need: Any
    profile: Any
    band: Any


MOTION: Final = types.NamedTuple((i8_1d, f8_2d, f8_2d, f8_1d, f8_1d), Motion)


class Band(NamedTuple):
    """A band's row spans ``lo``/``hi`` (int32, one per image row) and the last contour moved by the prediction
    (``moved``, float32 (capacity, 2)): `band_stage`'s outputs (`RoiBuffers`)."""

    lo: Any
    hi: Any
    moved: Any


BAND: Final = types.NamedTuple((i4_1d, i4_1d, f4_2d), Band)


class Order(NamedTuple):
    """The time order's history (`OrderBuffers`): sample times and counters ``state`` (int64), sample tips
    ``hist_rc`` (float64 (HISTORY, 2))."""

    state: Any
    hist_rc: Any


ORDER: Final = types.NamedTuple((i8_1d, f8_2d), Order)


class Track(NamedTuple):
    """The material points' arrays (`TrackBuffers`): arc ``fraction`` (float64, read only by the kernels), their
    positions on both shapes ``out`` (float32 (2, points, 2)), the shapes' lengths ``lengths_px`` (float64 (2,))
    and a shape's segment lengths ``work`` (float64)."""

    fraction: Any
    out: Any
    lengths_px: Any
    work: Any


TRACK: Final = types.NamedTuple((f8_1d, f4_3d, f8_1d, f8_1d), Track)

__all__ = ["BAND", "MOTION", "ORDER", "TRACK", "Band", "Motion", "Order", "Track", "f4_3d", "i8_1d"]
