"""Helpers of the device's application tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

PlaneYaml = Callable[[Path, tuple[float, float], tuple[int, int]], Path]


def _plane_yaml(path: Path, origin_uv: tuple[float, float], size: tuple[int, int], focal_px: float = 400.0) -> Path:
    """Write a plane.yaml (OpenCV FileStorage, as `ropecam calibrate plane` does) of a camera of `size` (width,
    height) square to the plane at 1 m whose origin projects to `origin_uv`."""
    cx, cy = (size[0] - 1) / 2, (size[1] - 1) / 2
    t = ((origin_uv[0] - cx) / focal_px, (origin_uv[1] - cy) / focal_px, 1.0)

    def matrix(rows: int, cols: int, data: list[float]) -> str:
        values = ", ".join(repr(float(v)) for v in data)
        return f"!!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {values} ]\n"

    path.write_text(
        "%YAML:1.0\n---\n"
        f"image_width: {size[0]}\nimage_height: {size[1]}\n"
        f"camera_matrix: {matrix(3, 3, [focal_px, 0, cx, 0, focal_px, cy, 0, 0, 1])}"
        f"distortion_coefficients: {matrix(5, 1, [0, 0, 0, 0, 0])}"
        f"plane_rotation: {matrix(3, 3, [1, 0, 0, 0, 1, 0, 0, 0, 1])}"
        f"plane_translation_m: {matrix(3, 1, list(t))}"
    )
    return path


@pytest.fixture(scope="session")
def plane_yaml() -> PlaneYaml:
    """``plane_yaml(path, origin_uv, (width, height))``: write a plane.yaml whose origin projects to `origin_uv`
    (a camera square to the plane at 1 m, focal length 400 px) and return its path."""
    return _plane_yaml
