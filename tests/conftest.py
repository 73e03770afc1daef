"""Fixtures and markers shared by the whole suite."""

from __future__ import annotations

import glob
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DIR = REPO_ROOT.parent / "shared"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip tests marked `hardware` when no camera is attached."""
    if glob.glob("/dev/video*"):
        return
    skip = pytest.mark.skip(reason="hardware test: no /dev/video* on this machine")
    for item in items:
        if "hardware" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The `../shared` folder handed to the developers (reference data, real images)."""
    if not SHARED_DIR.is_dir():
        pytest.fail(f"{SHARED_DIR} is missing: the suite reads reference data from ../shared beside the repo")
    return SHARED_DIR


@pytest.fixture(scope="session")
def ancf_reference_dir(shared_dir: Path) -> Path:
    """Exudyn's reference trajectories of the paper's rope."""
    return shared_dir / "reference" / "ancf"
