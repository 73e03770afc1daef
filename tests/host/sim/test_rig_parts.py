"""The rig's parts: clamp and rod, plate edge, scratches, dust and a distractor cable, where and as stated."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from ropecam.host.sim.config import SceneSpec
from ropecam.host.sim.rig_parts import add_plate_details, clamp_with_rod
from ropecam.host.sim.scene import build_scene
from ropecam.shared.errors import ConfigError

W, H = 200, 120
U = np.arange(W, dtype=np.float64)[None, :]
V = np.arange(H, dtype=np.float64)[:, None]


def test_clamp_covers_the_fixed_end_and_its_rod_runs_to_the_top_border() -> None:
    parts = clamp_with_rod(U, V, (100.0, 40.0), width_px=30.0, rod_width_px=8.0, level_dn=100.0, sigma_px=0.5)
    assert parts.box_px == (85.0, 31.0, 115.0, 49.0)
    assert parts.cover[40, 86:115].min() > 0.95  # the rope's first 15 px (either way) are hidden
    assert parts.cover[40, 80] < 0.01 and parts.cover[52, 100] < 0.01
    assert parts.rod_px == (96.0, 0.0, 104.0, 33.0)
    assert parts.cover[0:30, 97:104].min() > 0.95 and parts.cover[0:30, 107].max() < 0.01
    assert parts.level[40, 92] < 0.8 * parts.level[44, 100]  # the bolt heads are darker than the block's face
    assert parts.level[32, 90] > 1.5 * parts.level[44, 100]  # the lit chamfer along the top
    assert parts.shadow[52, 112] < 0.6 and parts.shadow[20, 60] == 1.0  # a shadow below right, none elsewhere
    no_rod = clamp_with_rod(U, V, (100.0, 40.0), 30.0, 0.0, 100.0, 0.5)
    assert no_rod.rod_px is None and no_rod.cover[10, 100] < 0.01


def _details(**options: object) -> tuple[np.ndarray, dict[str, object]]:
    base = np.full((H, W), 10.0)
    kwargs = {"plate_edge": 0.0, "scratches": 0, "dust": 0, "distractor": False, **options}
    return add_plate_details(base, U, V, rope_level=110.0, background_level=10.0, rope_width_px=3.0, sigma_px=0.5,
                             seed=3, **kwargs)  # fmt: skip


def test_plate_edge_is_where_stated_and_leans_two_degrees() -> None:
    image, where = _details(plate_edge=0.8)
    top, bottom = where["plate_edge_px"]
    assert top == pytest.approx(0.8 * (W - 1))
    assert abs(bottom - top) == pytest.approx(np.tan(np.radians(2.0)) * (H - 1))
    for row, edge in ((0, top), (H - 1, bottom)):
        wall = image[row, int(edge) + 4 :]
        assert np.all(np.abs(image[row, : int(edge) - 4] - 10.0) < 1e-3)
        assert np.all(np.abs(wall - (10.0 + 0.12 * 100) * (1 + 0.3 * (row / (H - 1) - 0.5))) < 1e-3)


def test_scratches_and_dust_are_faint_marks_of_the_ropes_polarity() -> None:
    plain, _ = _details()
    for option, count in (("scratches", 12), ("dust", 40)):
        image, _ = _details(**{option: count})
        change = image - plain
        assert change.min() >= -1e-9 and 0.5 < change.max() <= 0.13 * 100  # brighter, a few % of the contrast
        _, marks = ndimage.label(change > 0.3)
        assert 0.4 * count <= marks <= count  # crossing marks merge (long scratches in a small image)
    dark_plate = add_plate_details(np.full((H, W), 150.0), U, V, rope_level=20.0, background_level=150.0,
                                   rope_width_px=3.0, sigma_px=0.5, plate_edge=0.0, scratches=0, dust=30,
                                   distractor=False, seed=3)[0]  # fmt: skip
    assert dark_plate.max() <= 150.0 + 1e-9 and dark_plate.min() < 149.0  # grime on a white sheet is darker


def test_distractor_is_a_static_rope_wide_cable_from_top_to_bottom() -> None:
    image, where = _details(distractor=True)
    points = np.array(where["distractor_px"])
    assert points[0, 1] < 0 and points[-1, 1] > H - 1
    for row in (10, 60, 110):
        profile = image[row]
        band = np.nonzero(profile > 50)[0]
        assert 2 <= band.size <= 5 and band.max() < 0.35 * W  # about 3 px, beside the swing
        assert profile.max() == pytest.approx(110 * (0.85 + 0.1 * np.sin(row / 37.0)), rel=0.1)


def test_build_scene_reports_the_parts_and_options_are_validated() -> None:
    scene = SceneSpec(clamp=True, clamp_width_px=20.0, rod_width_px=6.0, plate_edge=0.9, distractor=True)
    layers = build_scene(scene, (W, H), (100.0, 30.0), 80.0, 2.0, 0.5, seed=1)
    assert set(layers.parts) == {"rod_px", "plate_edge_px", "distractor_px"}
    assert layers.clamp_level is not None and layers.clamp_box_px == (90.0, 24.0, 110.0, 36.0)
    for changes, message in (
        ({"rod_width_px": 5.0}, r"scene.rod_width_px = 5.0 draws the clamp's rod: set scene.clamp = true"),
        ({"plate_edge": 0.3}, r"scene.plate_edge must be in \[0.5, 0.99\], got 0.3"),
        ({"dust": 5000}, r"scene.dust must be in \[0, 2000\], got 5000"),
        ({"scratches": -1}, r"scene.scratches must be in \[0, 50\]"),
        ({"clamp": True, "clamp_width_px": 2.0}, r"scene.clamp_width_px must be in \[4.0, 200.0\], got 2.0"),
    ):
        with pytest.raises(ConfigError, match=message):
            SceneSpec(**changes)
