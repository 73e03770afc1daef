"""`ropecam model simulate`: simulate a rope with the ANCF model and write its free tip's trajectory."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from ropecam.shared.cli import EXIT_USAGE, declare_outputs

__all__ = ["register"]

EPILOG = """\
examples:
  # The paper's rope (Kevlar, L = 1 m, d = 1 mm) released horizontally, 2 s, tip every 1 ms:
  ropecam model simulate --length-m 1 --diameter-m 0.001 --youngs-modulus-pa 1.24e11 \\
      --density-kg-m3 1440 --elements 16 --step-s 1e-3 --duration-s 2 --out tip.csv --plot tip.png

  # Everything from a file, one value overridden:
  ropecam model simulate --config rope.toml --duration-s 0.5 --out tip.csv

rope.toml holds two tables whose keys are the long options without dashes, with underscores:
  [rope]    length_m, diameter_m, youngs_modulus_pa, density_kg_m3, ei_nm2, ea_n, fixed_end, angle_deg,
            initial_angular_velocity_rad_s, gravity_m_s2, drag_coefficient, air_density_kg_m3,
            mass_damping_per_s, material_damping_s, [rope.fixed_end_motion] amplitude_x_m, amplitude_y_m,
            frequency_hz, phase_rad
  [solver]  elements, step_s, duration_s, output_every_s, spectral_radius, newton_tolerance_m,
            max_iterations, adaptive
Command-line options override the file. Plane frame: x horizontal, y down (along gravity), origin at the
fixed end, metres. The CSV has the header t,x,y (free tip).
"""

ROPE_OPTIONS = (
    ("length_m", float, "unstretched rope length L (default 1.0)"),
    ("diameter_m", float, "rope diameter (default 0.001)"),
    ("youngs_modulus_pa", float, "Young's modulus E (default 1.24e11, Kevlar)"),
    ("density_kg_m3", float, "density (default 1440)"),
    ("ei_nm2", float, "bending stiffness EI override (default E pi d^4 / 64)"),
    ("ea_n", float, "axial stiffness EA override (default E pi d^2 / 4)"),
    ("angle_deg", float, "initial direction from +x towards +y (down) (default 0: horizontal)"),
    ("gravity_m_s2", float, "gravity along +y (default 9.81)"),
    ("drag_coefficient", float, "aerodynamic drag coefficient Cd (default 0: off; the paper's rope 1.122)"),
    ("air_density_kg_m3", float, "air density (default 1.204)"),
    ("mass_damping_per_s", float, "viscous mass-proportional damping (default 0)"),
    ("material_damping_s", float, "Kelvin-Voigt material damping time (default 0)"),
)
SOLVER_OPTIONS = (
    ("elements", int, "number of ANCF elements N (default 16)"),
    ("step_s", float, "time step h (default 1e-3)"),
    ("duration_s", float, "simulated time (default 2.0)"),
    ("output_every_s", float, "spacing of the CSV rows (default 1e-3)"),
    ("spectral_radius", float, "generalized-alpha rho_inf in [0, 1] (default 0.9)"),
)


def register(subparsers: Any) -> None:
    """Add `ropecam model ...` to the command line."""
    model = subparsers.add_parser("model", help="ANCF cable model: simulate a rope", description=__doc__)
    commands = model.add_subparsers(title="model commands", metavar="COMMAND")
    parser = commands.add_parser(
        "simulate",
        help="simulate a rope released from rest and write the free tip's trajectory",
        description="Simulate a rope with the 2D ANCF cable model (generalized-alpha, Newton, banded LU) and "
        "write the free tip's trajectory as CSV.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", type=Path, help="TOML file with [rope] and [solver] tables")
    for name, kind, text in ROPE_OPTIONS + SOLVER_OPTIONS:
        parser.add_argument("--" + name.replace("_", "-"), dest=name, type=kind, help=text)
    parser.add_argument("--fixed-end", choices=("pinned", "clamped"), help="support of node 0 (default pinned)")
    parser.add_argument("--out", type=Path, required=True, help="CSV file to write (t,x,y of the free tip)")
    parser.add_argument("--plot", type=Path, help="also write a PNG plot of the tip trajectory and energies")
    parser.add_argument("--trajectory", type=Path, help="also write the full trajectory (.npz, all nodes)")
    parser.add_argument("--quiet", action="store_true", help="no progress display")
    declare_outputs(parser, "out", "plot", "trajectory")
    parser.set_defaults(func=run_simulate)
    model.set_defaults(func=lambda args: model.print_help() or EXIT_USAGE)


def load_model_config(path: Path | None, args: argparse.Namespace | None = None) -> tuple[Any, Any]:
    """Build (RopeConfig, SolverConfig) from an optional TOML file and command-line overrides."""
    from ropecam.host.model.config import RopeConfig, SolverConfig
    from ropecam.shared.config import load_tables

    rope_over = {n: getattr(args, n, None) for n, _, _ in ROPE_OPTIONS} if args else {}
    if args is not None:
        rope_over["fixed_end"] = args.fixed_end
    solver_over = {n: getattr(args, n, None) for n, _, _ in SOLVER_OPTIONS} if args else {}
    configs = load_tables(path, {"rope": RopeConfig, "solver": SolverConfig}, rope=rope_over, solver=solver_over)
    return configs["rope"], configs["solver"]


def run_simulate(args: argparse.Namespace) -> int:
    """Run `ropecam model simulate`."""
    import numpy as np

    from ropecam.host.model.solver import CableModel
    from ropecam.host.progress import progress_bar
    from ropecam.shared.errors import DataError, UsageError

    rope, solver = load_model_config(args.config, args)
    for target in (args.out, args.plot, args.trajectory):
        if target is not None and not target.parent.exists():
            raise UsageError(f"{target}: folder {target.parent} does not exist")
    started = time.perf_counter()
    model = CableModel(rope, solver)
    with progress_bar("simulating", solver.duration_s, "s", enabled=not args.quiet) as report:
        trajectory, stats = model.run(report)
    tip = trajectory.tip()
    table = np.column_stack([trajectory.times_s, tip])
    try:
        np.savetxt(args.out, table, delimiter=",", header="t,x,y", comments="", fmt=("%.6f", "%.10f", "%.10f"))
        if args.trajectory is not None:
            trajectory.save(args.trajectory)
    except OSError as exc:
        raise DataError(f"cannot write results: {exc}") from exc
    if args.plot is not None:
        from ropecam.host.model.plot import plot_simulation

        plot_simulation(trajectory, rope, args.plot)
    total = time.perf_counter() - started
    drift = trajectory.energies["total"] - trajectory.energies["total"][0]
    print(
        f"simulated {solver.duration_s:g} s of a {rope.length_m:g} m rope with {solver.elements} elements "
        f"(h = {solver.step_s:g} s): solve {stats.solve_time_s:.3f} s, {stats.steps} steps, "
        f"{stats.newton_iterations} Newton iterations, total {total:.3f} s",
        file=sys.stdout,
    )
    print(f"energy drift (max |E - E0|): {np.max(np.abs(drift)):.3e} J = "
          f"{np.max(np.abs(drift)) / rope.potential_scale_j:.2e} of m g L / 2")  # fmt: skip
    print(f"wrote {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0
