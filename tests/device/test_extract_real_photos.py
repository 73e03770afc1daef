"""#19 acceptance 6: the real still photos of ../shared/realdata through `extract` with default settings.

A folder of images without a frame rate is a set of separate photos, each measured on its own. A still photo has
no blur: whatever the pipeline finds, it never reports a split whose tips lie more than 2 px apart (a split of
unknown exposure without blur, or a rejected one, gives the static centreline). Every single-rope photo (mBEST S1)
gets a centreline, and it lies inside the ground-truth mask for >= 98 % of its length. The photos are read from
../shared (never copied into the repository).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from ropecam.device.extract import run_extract
from ropecam.device.pipeline.config import PipelineConfig

FOLDERS = ("mbest_dlo_dataset/S1/images", "mbest_dlo_dataset/S2/images", "trackdlo_rope")
NO_BLUR_PX = 2.0


def _inside_fraction(polyline_uv: np.ndarray, mask: np.ndarray) -> float:
    """Fraction of the polyline's length (u, v) that lies on mask pixels (sampled 8 times per segment)."""
    seg = np.diff(polyline_uv, axis=0)
    samples = np.concatenate([polyline_uv[:-1] + seg * t for t in np.linspace(0, 1, 8, endpoint=False)])
    lengths = np.repeat(np.hypot(*seg.T), 8) / 8
    rows = np.clip(np.rint(samples[:, 1]).astype(int), 0, mask.shape[0] - 1)
    cols = np.clip(np.rint(samples[:, 0]).astype(int), 0, mask.shape[1] - 1)
    return float(lengths[mask[rows, cols] > 0].sum() / lengths.sum())


def _extract(images: Path, out: Path) -> tuple[list[str], list[dict]]:
    """Run `extract` with default settings over a folder; return the image names and the JSON records."""
    if not images.is_dir():
        pytest.fail(f"{images}: missing (the real photos are expected in ../shared/realdata)")
    assert run_extract(images, out, PipelineConfig()) == 0
    records = [json.loads(line) for line in out.read_text().splitlines()]
    names = sorted(p.name for p in images.iterdir() if p.suffix in (".jpg", ".png"))
    assert records and len(records) == len(names), out
    return names, records


@pytest.mark.parametrize("folder", FOLDERS)
def test_still_photos_never_give_a_split(shared_dir: Path, tmp_path: Path, folder: str) -> None:
    _, records = _extract(shared_dir / "realdata" / folder, tmp_path / "photos.jsonl")
    for record in records:
        tips = record["tips"]
        if tips and tips["begin"] and tips["end"]:
            separation = math.dist(tips["begin"], tips["end"])
            assert separation <= NO_BLUR_PX, (folder, record["frame"], record["status"], record["reason"])
        if record["status"] == "NO_BLUR":
            assert record["reason"] == "no_blur" and record["method"] == "STATIC_FALLBACK"


def test_single_rope_centrelines_lie_inside_the_mask(shared_dir: Path, tmp_path: Path) -> None:
    images = shared_dir / "realdata" / "mbest_dlo_dataset" / "S1" / "images"
    names, records = _extract(images, tmp_path / "s1.jsonl")
    fractions = {}
    for name, record in zip(names, records, strict=True):
        if record["begin"] is not None:
            mask = np.load(images.parent / "gt_labels" / f"{Path(name).stem}.npy")
            fractions[name] = _inside_fraction(np.array(record["begin"], np.float64), mask)
    assert len(fractions) == len(names), [r["status"] for r in records]
    assert min(fractions.values()) >= 0.98, fractions
