"""Acceptance 6: on real photos of static ropes (mBEST S1) the static centreline lies inside the ground-truth mask.

Same settings for every image; the photos are read from ../shared (never copied into the repository).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ropecam.device.pipeline.config import PipelineConfig
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import Method

SETTINGS = PipelineConfig(method="static", canny_low=30.0, canny_high=80.0, smooth_sigma_px=1.5, max_contour=60_000)


def _inside_fraction(polyline_rc: np.ndarray, mask: np.ndarray) -> float:
    seg = np.diff(polyline_rc, axis=0)
    samples = np.concatenate([polyline_rc[:-1] + seg * t for t in np.linspace(0, 1, 8, endpoint=False)])
    lengths = np.repeat(np.hypot(*seg.T), 8) / 8
    rows = np.clip(np.rint(samples[:, 0]).astype(int), 0, mask.shape[0] - 1)
    cols = np.clip(np.rint(samples[:, 1]).astype(int), 0, mask.shape[1] - 1)
    inside = mask[rows, cols] > 0
    return float(lengths[inside].sum() / lengths.sum())


def test_static_centreline_inside_the_mask(shared_dir) -> None:
    root = shared_dir / "realdata" / "mbest_dlo_dataset" / "S1"
    images = sorted((root / "images").glob("img*.jpg"))
    if not images:
        pytest.fail(f"{root}: no images")
    fractions = {}
    for path in images:
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        mask = np.load(root / "gt_labels" / f"{path.stem}.npy")
        result = Pipeline(SETTINGS, (image.shape[1], image.shape[0])).process(image, 0, 0, 0)
        assert result.begin is not None, (path.name, result.status, result.message)
        assert result.method is Method.STATIC_FALLBACK
        length = float(np.hypot(*np.diff(result.begin, axis=0).T).sum())
        assert length > 200, path.name  # a real centreline, not a stub
        fractions[path.name] = _inside_fraction(result.begin.astype(np.float64), mask)
    assert min(fractions.values()) >= 0.98, fractions
