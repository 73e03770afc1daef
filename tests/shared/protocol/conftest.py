"""Helpers for the protocol tests: comparing records after a trip over the wire."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ropecam.shared.protocol import FrameResult, polyline_distances_px
from ropecam.shared.protocol.quality import QUALITY_KEYS, QUALITY_SCALES

POINT_RESOLUTION_PX = 1 / 128 + 1e-12  # half of the 1/64 px quantum


def shape_error_px(original: np.ndarray, decoded: np.ndarray) -> float:
    """Worst distance of the device points to the decoded polyline, and between the end points."""
    inner = float(np.max(polyline_distances_px(original, decoded)))
    ends = max(float(np.hypot(*(original[0] - decoded[0]))), float(np.hypot(*(original[-1] - decoded[-1]))))
    return max(inner, ends)


def assert_frame_results_match(original: FrameResult, decoded: FrameResult, tolerance_px: float = 0.05) -> None:
    """Assert `decoded` is `original` within the documented wire resolution."""
    for name in ("frame_index", "exposure_start_t_ns", "exposure_end_t_ns", "status", "method", "pipeline_us"):
        assert getattr(decoded, name) == getattr(original, name), name
    assert decoded.order_confidence == pytest.approx(original.order_confidence, abs=0.5 / 65535 + 1e-12)
    for name in ("begin_px", "end_px"):
        a, b = getattr(original, name), getattr(decoded, name)
        assert (a is None) == (b is None), name
        if a is not None:
            assert len(b) == len(a), name
            assert shape_error_px(a, b) <= tolerance_px + 1e-9, name
    for name in ("begin_tip_px", "end_tip_px", "fixed_end_px"):
        a, b = getattr(original, name), getattr(decoded, name)
        assert (a is None) == (b is None), name
        if a is not None:
            assert np.max(np.abs(np.subtract(a, b))) <= POINT_RESOLUTION_PX, name
    assert decoded.material_s_m == pytest.approx(original.material_s_m, abs=0.5e-4 + 1e-12)
    for name in ("material_begin_px", "material_end_px"):
        a, b = getattr(original, name), getattr(decoded, name)
        assert np.array_equal(np.isnan(a), np.isnan(b)), name
        assert np.nanmax(np.abs(a - b), initial=0.0) <= POINT_RESOLUTION_PX, name
    for name in ("stretch_begin", "stretch_end"):
        a, b = getattr(original, name), getattr(decoded, name)
        assert math.isnan(a) == math.isnan(b), name
        if not math.isnan(a):
            assert b == pytest.approx(a, abs=0.5e-5 + 1e-12), name
    assert (decoded.reason, decoded.readout_ns) == (original.reason, original.readout_ns)
    assert decoded.quality.keys() == original.quality.keys()
    for key, scale in zip(QUALITY_KEYS, QUALITY_SCALES, strict=True):
        if key in original.quality:
            assert decoded.quality[key] == pytest.approx(original.quality[key], abs=0.5 * scale + 1e-12), key


@pytest.fixture(scope="session")
def frames_match():
    """The `assert_frame_results_match` helper."""
    return assert_frame_results_match


@pytest.fixture(scope="session")
def shape_error():
    """The `shape_error_px` helper."""
    return shape_error_px
