"""Plots of a simulated rope: tip trajectory, tip coordinates over time, snapshots of the shape, energies."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ropecam.host.model.config import RopeConfig
from ropecam.host.model.trajectory import Trajectory
from ropecam.shared.errors import DataError

__all__ = ["plot_simulation"]


def plot_simulation(trajectory: Trajectory, rope: RopeConfig, path: str | Path, snapshots: int = 9) -> None:
    """Write a PNG with the rope's shapes and tip path, the tip coordinates and the energies over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = trajectory.times_s
    tip = trajectory.tip()
    s = np.linspace(0.0, rope.length_m, 101)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), constrained_layout=True)
    ax = axes[0]
    for i in np.linspace(0, t.size - 1, snapshots).astype(int):
        shape = trajectory.sample_positions(s)[i] if t.size < 5000 else trajectory.positions([t[i]], s)[0]
        ax.plot(shape[:, 0], shape[:, 1], lw=1.2, label=f"t = {t[i]:.2f} s")
    ax.plot(tip[:, 0], tip[:, 1], "k:", lw=0.8, label="tip path")
    ax.set_xlabel("x (m, horizontal)")
    ax.set_ylabel("y (m, down)")
    ax.invert_yaxis()
    ax.set_aspect("equal")
    ax.set_title("Rope shapes and tip path")
    ax.legend(fontsize=7, loc="best")
    ax = axes[1]
    ax.plot(t, tip[:, 0], label="x")
    ax.plot(t, tip[:, 1], label="y (down)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tip position (m)")
    ax.set_title("Free tip")
    ax.legend()
    ax.grid(alpha=0.3)
    ax = axes[2]
    energies = trajectory.energies
    for name in ("kinetic", "gravity", "axial", "bending", "total"):
        if name in energies:
            ax.plot(t, energies[name] * 1e3, label=name, lw=2 if name == "total" else 1)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("energy (mJ)")
    ax.set_title("Energies")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.suptitle(
        f"ANCF rope: L = {rope.length_m:g} m, d = {rope.diameter_m * 1e3:g} mm, "
        f"EI = {rope.bending_stiffness_nm2:.3g} N m², EA = {rope.axial_stiffness_n:.3g} N, "
        f"{trajectory.n_elements} elements"
    )
    try:
        fig.savefig(path, dpi=110)
    except OSError as exc:
        raise DataError(f"{path}: cannot write plot: {exc}") from exc
    finally:
        plt.close(fig)
