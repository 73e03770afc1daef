"""Model configuration is validated with clear messages; `ropecam model simulate` works end to end."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ropecam.host.cli import main
from ropecam.host.model import RopeConfig, SolverConfig
from ropecam.shared.errors import ConfigError


@pytest.mark.parametrize(
    ("factory", "message"),
    [
        (lambda: RopeConfig(length_m=0.0), "length_m must be > 0, got 0.0"),
        (lambda: RopeConfig(diameter_m=math.nan), "diameter_m must be a finite number, got nan"),
        (lambda: RopeConfig(fixed_end="free"), "fixed_end must be 'pinned' or 'clamped'"),
        (lambda: SolverConfig(elements=0), "elements must be an integer in"),
        (lambda: SolverConfig(step_s=1.0, duration_s=0.5), r"step_s \(1.0\) must not be longer than duration_s"),
        (lambda: SolverConfig(spectral_radius=1.5), r"spectral_radius must be in \[0.0, 1.0\], got 1.5"),
    ],
)
def test_nonsense_is_refused_with_the_value(factory, message: str) -> None:
    with pytest.raises((ConfigError, ValueError), match=message):
        factory()


def _simulate(tmp_path: Path, *extra: str) -> int:
    return main(["model", "simulate", "--out", str(tmp_path / "tip.csv"), "--quiet", *extra])


def test_cli_writes_tip_csv_plot_and_trajectory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = _simulate(
        tmp_path,
        *("--length-m", "1", "--diameter-m", "0.001", "--youngs-modulus-pa", "1.24e11", "--density-kg-m3", "1440"),
        *("--elements", "4", "--step-s", "1e-3", "--duration-s", "0.05", "--plot", str(tmp_path / "tip.png")),
        *("--trajectory", str(tmp_path / "run.npz")),
    )
    assert code == 0
    lines = (tmp_path / "tip.csv").read_text().splitlines()
    assert lines[0] == "t,x,y" and len(lines) == 52
    table = np.loadtxt(tmp_path / "tip.csv", delimiter=",", skiprows=1)
    assert table[0].tolist() == [0.0, 1.0, 0.0]
    assert 0 < table[-1, 2] < 0.5 * 9.81 * 0.05**2 * 1.6  # falling, at most a bit faster than free fall
    assert (tmp_path / "tip.png").stat().st_size > 10_000
    assert np.load(tmp_path / "run.npz")["q"].shape == (51, 20)
    out = capsys.readouterr().out
    assert "solve" in out and "energy drift" in out


def test_cli_reads_toml_and_flags_override(tmp_path: Path) -> None:
    config = tmp_path / "rope.toml"
    config.write_text("[rope]\nlength_m = 0.5\nei_nm2 = 1e-4\n[solver]\nelements = 3\nduration_s = 0.02\n")
    assert _simulate(tmp_path, "--config", str(config), "--output-every-s", "0.01", "--duration-s", "0.04") == 0
    table = np.loadtxt(tmp_path / "tip.csv", delimiter=",", skiprows=1)
    assert table[:, 0].tolist() == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04])
    assert table[0, 1] == 0.5


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        ("[rope]\nlenght_m = 1.0\n", "unknown key 'lenght_m'"),
        ("[rope]\nlength_m = -1.0\n", r"\[rope\]: length_m must be > 0, got -1.0"),
        ("[solver]\nelements = 2.5\n", r"\[solver\].elements: expected an integer, got 2.5"),
        ("[ropes]\n", r"unknown table \[ropes\]"),
        ("[rope\n", "not valid TOML"),
    ],
)
def test_cli_bad_config_names_file_key_and_value(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], toml: str, message: str
) -> None:
    config = tmp_path / "rope.toml"
    config.write_text(toml)
    assert _simulate(tmp_path, "--config", str(config)) == 2
    err = capsys.readouterr().err
    assert str(config) in err
    assert __import__("re").search(message, err), err
    assert not (tmp_path / "tip.csv").exists()


def test_cli_missing_output_folder_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "simulate", "--out", str(tmp_path / "no" / "tip.csv"), "--duration-s", "0.01"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_help_teaches(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["model", "simulate", "--help"])
    text = capsys.readouterr().out
    assert "--youngs-modulus-pa" in text and "[rope]" in text and "examples" in text
