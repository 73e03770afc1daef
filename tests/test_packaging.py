"""The wheel's package list must match the folders on disk, and every import must use the mapped names."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
MAPPING = {"device": "ropecam.device", "host": "ropecam.host", "shared": "ropecam.shared"}


def _packages_on_disk() -> set[str]:
    found = set()
    for top, name in MAPPING.items():
        for init in (REPO_ROOT / top).rglob("__init__.py"):
            rel = init.parent.relative_to(REPO_ROOT / top)
            found.add(".".join([name, *rel.parts]))
    return found


def test_package_list_matches_init_files() -> None:
    config = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())
    listed = set(config["tool"]["setuptools"]["packages"])
    assert listed == _packages_on_disk()


def test_no_root_ropecam_folder_and_no_bare_imports() -> None:
    assert not (REPO_ROOT / "ropecam").exists()
    bare = re.compile(r"^\s*(from|import)\s+(shared|device|host)(\.|\s|$)", re.MULTILINE)
    offenders = [
        str(path.relative_to(REPO_ROOT))
        for top in (*MAPPING, "tests", "tools")
        for path in (REPO_ROOT / top).rglob("*.py")
        if bare.search(path.read_text())
    ]
    assert offenders == []


def test_each_mapped_folder_ships_py_typed() -> None:
    for top in MAPPING:
        assert (REPO_ROOT / top / "py.typed").is_file()
