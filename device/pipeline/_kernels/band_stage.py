"""The band of a frame in one call: the last band's measured error, the motion prediction and the band.

Each call from Python costs a dispatch (type matching of every argument) and a return to the interpreter with
caches the frame's kernels have filled: a stream builds its band with one call instead of
`need_profile` (after the search), `predict_motion` and `spans_around_chain`.
"""

from __future__ import annotations

from numba import boolean, float64, int64

from ropecam.device.pipeline._kernels.groups import BAND, MOTION
from ropecam.device.pipeline._kernels.prediction import need_profile
from ropecam.device.pipeline._kernels.spans import spans_around_chain
from ropecam.device.pipeline._kernels.tracking import MOTION_COUNT, MOTION_FRAMES, predict_motion
from ropecam.shared.jit import f4_1d, f4_2d_ro, kernel


@kernel(
    float64(
        f4_2d_ro, int64, boolean, boolean, boolean, int64, int64, int64, int64, int64, float64, float64, float64,
        f4_1d, MOTION, BAND,
    )
)  # fmt: skip
def band_stage(
    points, n_points, measure, use_profile, predict, t_ns, exposure_ns, margin_px, height, width, gain, floor_px,
    floor_share, fixed, motion, band,
):  # fmt: skip
    """Build the band of the frame exposed from `t_ns` for `exposure_ns` around the last contour (`points`, a
    closed chain of `n_points` (row, col)), first measuring how well the last band predicted it when `measure`.

    1. With `measure` (the last frame was found in the band the last call built, and `points` is that contour):
       `need_profile` of `points` against the last call's moved points (`out_moved`, ``band_state["moved"]``
       of them) with the last call's fixed end, margin `margin_px`, `gain` and ``floor_px + floor_share *
       band_state["motion_px"]``, and its ``motion_held``: updates `need_hist` (2, bins) and `profile` (bins,).
    2. With `predict` (the fixed end `fixed`, float32 (row, col), is known): `predict_motion(t_ns, exposure_ns,
       motion_state, motion_log)`; else no motion (1, 0, 0) about (0, 0).
    3. `spans_around_chain` of `points` with that motion, margin `margin_px` and, when `use_profile`, `profile`
       (else none), into `out_lo`/`out_hi` (`height` rows, `width` columns); the moved points into `out_moved`.
       `band_state` (one `BAND_STATE` record) gets what step 1 of the next call needs.

    `motion` is the motion model's group (`Motion`: ``state``, ``log`` as `motion_state`, `motion_log` above,
    ``need`` as `need_hist`, ``profile``, ``band`` as `band_state`), `band` the band's (`Band`: ``lo``, ``hi``,
    ``moved`` as `out_lo`, `out_hi`, `out_moved`). The same results as `need_profile` after the last frame's
    search, then `predict_motion` and `spans_around_chain` on this frame. Returns the uncertainty at the farthest
    point (px).
    """
    motion_state = motion.state
    motion_log = motion.log
    need_hist = motion.need
    profile = motion.profile
    band_state = motion.band[0]
    out_lo = band.lo
    out_hi = band.hi
    out_moved = band.moved
    if measure:
        need_profile(
            out_moved, band_state["moved"], points, n_points, margin_px, band_state["fixed_r"],
            band_state["fixed_c"], gain, floor_px + floor_share * band_state["motion_px"], band_state["motion_held"],
            need_hist, profile,
        )  # fmt: skip
    rot_a = 1.0
    rot_b = 0.0
    motion_px = 0.0
    fixed_r = 0.0
    fixed_c = 0.0
    if predict:
        rot_a, rot_b, motion_px = predict_motion(t_ns, exposure_ns, motion_state, motion_log)
        fixed_r = float(fixed[0])
        fixed_c = float(fixed[1])
    spans_around_chain(
        points, n_points, margin_px, motion_px, profile if use_profile else profile[:0], rot_a, rot_b, fixed_r,
        fixed_c, height, width, out_lo, out_hi, out_moved,
    )  # fmt: skip
    band_state["fixed_r"] = fixed_r
    band_state["fixed_c"] = fixed_c
    band_state["motion_px"] = motion_px
    band_state["moved"] = n_points
    band_state["motion_held"] = motion_state[MOTION_COUNT] >= MOTION_FRAMES - 1
    return motion_px
