"""The self-checks of a measured frame in one call: the tips' predicted position, then every check and its measure.

The thresholds and the measures travel as one-record structured arrays (`CHECK_THRESHOLDS`, `CHECK_QUALITY`), read
and written by field name (``record["name"]``, which NumPy also takes: the kernels run without the JIT too). The
reason codes are the wire's (`ropecam.shared.protocol.quality.Reason`; a test keeps them equal).
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numba import boolean, float64, int64, types
from numba.np.numpy_support import from_dtype

from ropecam.device.pipeline._kernels.tracking import MOTION_COUNT, i8_1d, predict_motion
from ropecam.shared.jit import f4_1d, f4_2d, f4_2d_ro, f8_1d, f8_2d, kernel

CHECK_NONE: Final = 0
"""Every check passed."""
CHECK_LENGTH: Final = 1
CHECK_WIDTH: Final = 2
CHECK_FIXED_END: Final = 3
CHECK_TIP_MOTION: Final = 4
CHECK_ORDER: Final = 5
CHECK_NO_BLUR: Final = 6

CHECK_THRESHOLDS: Final = np.dtype(
    [
        ("length_tolerance", np.float64),
        ("width_tolerance", np.float64),
        ("fixed_end_widths", np.float64),
        ("fixed_end_floor_px", np.float64),
        ("tip_motion_factor", np.float64),
        ("tip_motion_floor_px", np.float64),
        ("min_order_confidence", np.float64),
        ("no_blur_px", np.float64),
        ("min_blur_evidence", np.float64),
    ]
)
"""The checks' thresholds (`ChecksConfig`'s numbers), one record."""
CHECK_QUALITY: Final = np.dtype(
    [
        ("length_ratio", np.float64),
        ("width_ratio", np.float64),
        ("fixed_end_px", np.float64),
        ("tip_separation_px", np.float64),
        ("tip_motion_px", np.float64),
        ("tip_motion_limit_px", np.float64),
        ("blur_evidence", np.float64),
    ]
)
"""The checks' measures of one frame (the wire's `QUALITY_KEYS`, in its order), one record."""

_thresholds_ro = types.Array(from_dtype(CHECK_THRESHOLDS), 1, "C", readonly=True)
_quality = types.Array(from_dtype(CHECK_QUALITY), 1, "C")


@kernel(boolean(int64, int64, i8_1d, f8_2d, f4_1d, f8_1d))
def predict_tips(t_ns, exposure_ns, motion_state, motion_log, fixed, out_predicted):
    """Write where the motion model (`motion_state`, `motion_log`) puts the tips' midpoint (row, col) in the frame
    exposed from `t_ns` for `exposure_ns`, about the fixed end (row, col), and the prediction's error (px), into
    `out_predicted` (3,). With fewer than two frames in the model: nan error (no prediction); returns whether there
    is a prediction."""
    count = motion_state[MOTION_COUNT]
    if count < 2:
        out_predicted[2] = math.nan
        return False
    f_re, f_im, error_px = predict_motion(t_ns, exposure_ns, motion_state, motion_log)
    radius = math.exp(motion_log[count - 1, 0])
    angle = motion_log[count - 1, 1]
    z_re = radius * math.cos(angle)
    z_im = radius * math.sin(angle)
    out_predicted[0] = float64(fixed[0]) + f_re * z_re - f_im * z_im
    out_predicted[1] = float64(fixed[1]) + f_re * z_im + f_im * z_re
    out_predicted[2] = error_px
    return True


# The shapes as the splitter leaves them (writable) or read-only views; the fixed end is the workspace's.
_CHECK_SIGNATURES = [
    int64(shape, shape, f4_1d, f8_1d, *(float64,) * 5, int64, boolean, float64, _thresholds_ro, _quality)
    for shape in (f4_2d, f4_2d_ro)
]


@kernel(_CHECK_SIGNATURES)
def check_frame(
    begin, end, fixed, predicted, stretch_begin, stretch_end, width_px, learned_width_px, order_confidence,
    exposure_ns, split, contour_area_px2, thresholds, out_quality,
):  # fmt: skip
    """Run every self-check on a measured frame; return the first failed check's code (`CHECK_NO_BLUR` before the
    others; `CHECK_NONE`: all passed) and write every measure into `out_quality[0]`.

    `begin`/`end` are the shapes (row, col), fixed end first; `fixed` the fixed end; `predicted` the tips' predicted
    midpoint and its error (`predict_tips`; nan error: none); `stretch_*` Lc / Lc0 of each shape (nan: unknown);
    `width_px` the split's width, `learned_width_px` the learned one (0: unknown); `split` whether the method gave
    two shapes; `contour_area_px2` the contour's area (used only for a split the motion model cannot check:
    unknown exposure or no prediction). The rules are `ropecam.device.pipeline.checks`' table.
    """
    limits = thresholds[0]
    q = out_quality[0]
    failed = CHECK_NONE
    length_ratio = math.nan
    for stretch in (stretch_begin, stretch_end):
        if math.isfinite(stretch) and not abs(stretch - 1.0) <= abs(length_ratio - 1.0):
            length_ratio = stretch
    q["length_ratio"] = length_ratio
    if abs(length_ratio - 1.0) > limits["length_tolerance"]:
        failed = CHECK_LENGTH
    width_ratio = width_px / learned_width_px if learned_width_px != 0.0 else math.nan
    q["width_ratio"] = width_ratio
    if failed == CHECK_NONE and abs(width_ratio - 1.0) > limits["width_tolerance"]:
        failed = CHECK_WIDTH
    fr = float64(fixed[0])
    fc = float64(fixed[1])
    offset = max(
        math.hypot(float64(begin[0, 0]) - fr, float64(begin[0, 1]) - fc),
        math.hypot(float64(end[0, 0]) - fr, float64(end[0, 1]) - fc),
    )
    q["fixed_end_px"] = offset
    width = learned_width_px if learned_width_px != 0.0 else width_px
    if failed == CHECK_NONE and offset > limits["fixed_end_widths"] * width + limits["fixed_end_floor_px"]:
        failed = CHECK_FIXED_END
    nb = begin.shape[0] - 1
    ne = end.shape[0] - 1
    br = float64(begin[nb, 0])
    bc = float64(begin[nb, 1])
    er = float64(end[ne, 0])
    ec = float64(end[ne, 1])
    separation = math.hypot(er - br, ec - bc)
    q["tip_separation_px"] = separation
    motion_px = math.nan
    motion_limit_px = math.nan
    if not math.isnan(predicted[2]):
        motion_px = math.hypot(0.5 * (br + er) - predicted[0], 0.5 * (bc + ec) - predicted[1])
        motion_limit_px = limits["tip_motion_factor"] * predicted[2] + limits["tip_motion_floor_px"]
    q["tip_motion_px"] = motion_px
    q["tip_motion_limit_px"] = motion_limit_px
    if failed == CHECK_NONE and motion_px > motion_limit_px:
        failed = CHECK_TIP_MOTION
    if failed == CHECK_NONE and split and exposure_ns > 0 and order_confidence < limits["min_order_confidence"]:
        failed = CHECK_ORDER
    evidence = math.nan
    unchecked = split and (exposure_ns <= 0 or math.isnan(predicted[2]))
    if unchecked:
        length_px = 0.0
        for k in range(nb):
            length_px += math.hypot(
                float64(begin[k + 1, 0]) - float64(begin[k, 0]), float64(begin[k + 1, 1]) - float64(begin[k, 1])
            )
        evidence = (contour_area_px2 - length_px * width) / max(0.5 * length_px * separation, 1.0)
    q["blur_evidence"] = evidence
    # The pixel contour's area is uncertain by ~ half a pixel along both sides (~ length px^2), which is
    # 2 / separation of the implied sweep area: a verdict only where that is below half the threshold.
    no_blur_px = limits["no_blur_px"]
    if limits["min_blur_evidence"] > 0.0:
        no_blur_px = max(no_blur_px, 4.0 / limits["min_blur_evidence"])
    if unchecked and separation > no_blur_px and not evidence >= limits["min_blur_evidence"]:
        failed = CHECK_NO_BLUR
    return failed
