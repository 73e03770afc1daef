"""Frame sets round-trip, and malformed ones are refused with the file named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ropecam.device.capture.frameset import FrameSet, FrameSetWriter, is_frameset
from ropecam.shared.errors import DataError


def _write(root: Path, frames: int = 3) -> list[np.ndarray]:
    rng = np.random.default_rng(1)
    images = [rng.integers(0, 256, (12, 16), dtype=np.uint8) for _ in range(frames)]
    with FrameSetWriter(root, (16, 12), 119.0, {"rig": {"preset": "test"}}) as writer:
        for i, image in enumerate(images):
            writer.add(image, t_ns=1_000_000 + i * 8_403_361, exposure_us=4000)
        writer.write_truth({"begin_px": np.zeros((frames, 5, 2))})
    return images


def test_round_trip(tmp_path: Path) -> None:
    images = _write(tmp_path / "set")
    frames = FrameSet(tmp_path / "set")
    assert is_frameset(tmp_path / "set")
    assert len(frames) == 3 and frames.image_size == (16, 12) and frames.fps == 119.0
    assert frames.meta["rig"] == {"preset": "test"}
    assert [r.t_ns for r in frames.records] == [1_000_000, 9_403_361, 17_806_722]
    for (record, image), expected in zip(frames, images, strict=True):
        assert record.exposure_us == 4000
        np.testing.assert_array_equal(image, expected)
    truth = frames.truth()
    assert truth is not None and truth["begin_px"].shape == (3, 5, 2)


def test_refuses_overwrite_and_bad_images(tmp_path: Path) -> None:
    _write(tmp_path / "set")
    with pytest.raises(DataError, match="exists already"):
        FrameSetWriter(tmp_path / "set", (16, 12), 119.0)
    writer = FrameSetWriter(tmp_path / "other", (16, 12), 30.0)
    with pytest.raises(ValueError, match="uint8 of shape"):
        writer.add(np.zeros((12, 16), np.float32), 0, 1000)
    writer.close()


def test_overwrite_removes_the_old_frames_only(tmp_path: Path) -> None:
    root = tmp_path / "set"
    _write(root, frames=5)
    (root / "frames" / "notes.txt").write_text("keep")
    (root / "frames" / "snapshot.png").write_bytes(b"not ours")
    images = []
    with FrameSetWriter(root, (16, 12), 30.0, overwrite=True) as writer:
        for i in range(2):
            images.append(np.full((12, 16), 10 * i, np.uint8))
            writer.add(images[-1], t_ns=i, exposure_us=100)
    assert sorted(p.name for p in (root / "frames").iterdir()) == ["000000.png", "000001.png", "notes.txt",
                                                                    "snapshot.png"]  # fmt: skip
    frames = FrameSet(root)
    assert len(frames) == 2 and frames.fps == 30.0 and frames.truth() is None
    for (_, image), expected in zip(frames, images, strict=True):
        np.testing.assert_array_equal(image, expected)


def test_frames_without_metadata_are_not_overwritten_silently(tmp_path: Path) -> None:
    root = tmp_path / "set"
    _write(root)
    (root / "frameset.json").unlink()
    before = (root / "frames" / "000000.png").read_bytes()
    with pytest.raises(DataError, match=r"frames: holds 3 frame files \(e\.g\. 000000\.png\).*no frameset\.json"):
        FrameSetWriter(root, (16, 12), 30.0)
    assert (root / "frames" / "000000.png").read_bytes() == before
    FrameSetWriter(root, (16, 12), 30.0, overwrite=True).close()
    assert not list((root / "frames").iterdir()) and len(FrameSet(root)) == 0


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda root: (root / "frameset.json").write_text("{"), "cannot read frame-set metadata"),
        (lambda root: (root / "frameset.json").write_text('{"format": "x"}'), "expected 'ropecam-frameset'"),
        (lambda root: (root / "index.csv").unlink(), "has no index.csv"),
        (lambda root: (root / "index.csv").write_text("frame,t_ns,exposure_us,file\n0,x,1,a.png\n"), "index.csv:2"),
    ],
)
def test_malformed_sets_name_the_file(tmp_path: Path, damage, message: str) -> None:
    _write(tmp_path / "set")
    damage(tmp_path / "set")
    with pytest.raises(DataError, match=message):
        FrameSet(tmp_path / "set")


def test_missing_image_is_named(tmp_path: Path) -> None:
    _write(tmp_path / "set")
    (tmp_path / "set" / "frames" / "000001.png").unlink()
    frames = FrameSet(tmp_path / "set")
    frames.read(0)
    with pytest.raises(DataError, match=r"000001\.png"):
        frames.read(1)
