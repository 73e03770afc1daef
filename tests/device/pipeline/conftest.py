"""Fixtures of the pipeline tests: small synthetic motion-blurred rope frames and kernel buffers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ropecam.device.capture.synthetic import SyntheticFrame, SyntheticRope


@pytest.fixture(scope="session")
def rope() -> SyntheticRope:
    """A 320x240 rope, 180 px long, 4 px thick, swinging fast enough for several pixels of tip blur at 8 ms."""
    return SyntheticRope(exposure_us=8000, amplitude_rad=0.7, period_s=0.9)


@pytest.fixture(scope="session")
def blurred_frames(rope: SyntheticRope) -> list[SyntheticFrame]:
    """Eight consecutive blurred frames of `rope`."""
    return list(rope.frames(8, start=2))


@pytest.fixture(scope="session")
def static_frame(rope: SyntheticRope) -> SyntheticFrame:
    """A frame with a (nearly) motionless rope: 50 us exposure at a turning point of the swing."""
    return replace(rope, exposure_us=50, phase_rad=0.0).render(0)


@pytest.fixture(scope="session")
def fast_rope() -> SyntheticRope:
    """A rope blurred over ~10 px at the tip (12 ms exposure)."""
    return SyntheticRope(exposure_us=12000, amplitude_rad=0.7, period_s=0.9, diameter_px=3.0, phase_rad=1.2)


@pytest.fixture(scope="session")
def fast_frames(fast_rope: SyntheticRope) -> list[SyntheticFrame]:
    """Six consecutive frames of `fast_rope`."""
    return list(fast_rope.frames(6))


def full_spans(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Return row spans covering the whole image."""
    return np.zeros(height, np.int32), np.full(height, width - 1, np.int32)


@pytest.fixture
def spans_full():
    """The `full_spans` helper as a fixture."""
    return full_spans
