"""Compose the montage of simulated lab frames shown in docs/simulator.md: whole frames and 1:1 crops.

Usage::

    for p in lab lab-dark lab-mjpeg lab-rolling lab-hard; do
        ropecam simulate $p --out sets/$p --frames 60 --photo-dir ../shared/realdata
    done
    python tools/sim_montage.py sets --frame 40 --out docs/img/simulator_lab.png

Each row is one preset: the whole frame scaled to the crops' height (INTER_AREA), then three 1:1 crops: around the clamp
(the fixed end) and around the rope's middle in the same frame (from truth.npz), and the rope's middle in frame 0,
where it hangs at rest before the release and its braid shows unblurred. Nothing is retouched; the PNG holds the
frames' own grey levels.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from ropecam.device.capture.frameset import FrameSet

PRESETS = ("lab", "lab-dark", "lab-mjpeg", "lab-rolling", "lab-hard")
CROP = 128


def _crop(image: np.ndarray, centre: np.ndarray) -> np.ndarray:
    height, width = image.shape
    u = int(np.clip(round(centre[0]) - CROP // 2, 0, width - CROP))
    v = int(np.clip(round(centre[1]) - CROP // 2, 0, height - CROP))
    return image[v : v + CROP, u : u + CROP]


def _row(folder: Path, frame: int, label: str) -> np.ndarray:
    frames = FrameSet(folder)
    truth = frames.truth()
    if truth is None:
        raise SystemExit(f"{folder}: no truth.npz")
    image = frames.read(frame)
    whole = cv2.resize(image, (round(image.shape[1] * CROP / image.shape[0]), CROP), interpolation=cv2.INTER_AREA)
    fixed = truth["fixed_end_px"] + np.array([0.0, 20.0])
    middle = truth["begin_px"][frame][int(0.6 * len(truth["s_m"]))]
    gap = np.full((CROP, 4), 255, dtype=np.uint8)
    still = frames.read(0)  # released at rest: the braid shows unblurred
    resting = truth["begin_px"][0][int(0.6 * len(truth["s_m"]))]
    row = np.hstack([whole, gap, _crop(image, fixed), gap, _crop(image, middle), gap, _crop(still, resting)])
    cv2.putText(row, label, (4, CROP - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4, 255, 1, cv2.LINE_AA)
    return row


def main() -> None:
    """Write the montage PNG."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sets", type=Path, help="folder holding one frame set per preset (sets/<preset>)")
    parser.add_argument("--frame", type=int, default=40, help="frame index shown (default 40)")
    parser.add_argument("--presets", nargs="+", default=list(PRESETS), help="presets, one row each")
    parser.add_argument("--out", type=Path, required=True, help="PNG to write")
    args = parser.parse_args()
    rows = [_row(args.sets / name, args.frame, f"{name}, frame {args.frame}") for name in args.presets]
    gap = np.full((4, rows[0].shape[1]), 255, dtype=np.uint8)
    montage = np.vstack([part for row in rows for part in (row, gap)][:-1])
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(args.out), montage, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        raise SystemExit(f"cannot write {args.out}")
    print(f"{args.out}: {montage.shape[1]}x{montage.shape[0]}, {args.out.stat().st_size / 1024:.0f} KB")


if __name__ == "__main__":
    main()
