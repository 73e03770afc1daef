"""Time ropecam's ANCF solver against Exudyn's ANCFCable2D on the paper's rope, alternating runs in one process.

For each element count N and step h: median solve time of ours and (when `exudyn` is importable, ``pip install
".[bench]"``) of Exudyn with the same model and generalized-alpha settings, their ratio, and the largest tip error
of each over the run against the best reference (Exudyn, N = 64, h = 1e-4, in ../shared/reference/ancf).

    python tools/bench.py ancf                  # N = 8, 16, 32; h = 1e-3 and 1e-4; 5 repeats
    python tools/bench.py ancf --elements 16 --steps 1e-3 --repeats 3 --json
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from ropecam.host.model import CableModel, RopeConfig, SolverConfig

REFERENCE = Path(__file__).resolve().parents[1].parent / "shared" / "reference" / "ancf"


def ours(rope: RopeConfig, elements: int, step_s: float, duration_s: float) -> tuple[float, np.ndarray]:
    """Return (solve seconds, tip samples every 1 ms as (t, x, y-down))."""
    model = CableModel(rope, SolverConfig(elements=elements, step_s=step_s, duration_s=duration_s))
    trajectory, stats = model.run()
    tip = trajectory.tip()
    return stats.solve_time_s, np.column_stack([trajectory.times_s, tip])


def exudyn_run(rope: RopeConfig, elements: int, step_s: float, duration_s: float) -> tuple[float, np.ndarray]:
    """Build the same rope in Exudyn (pinned node 0, gravity, generalized-alpha rho = 0.9) and solve it."""
    import exudyn as exu
    from exudyn.itemInterface import (
        LoadMassProportional,
        MarkerBodyMass,
        MarkerNodeCoordinate,
        NodePoint2DSlope1,
        NodePointGround,
        ObjectANCFCable2D,
        ObjectConnectorCoordinate,
        SensorNode,
    )

    system = exu.SystemContainer()
    mbs = system.AddSystem()
    le = rope.length_m / elements
    nodes = [mbs.AddNode(NodePoint2DSlope1(referenceCoordinates=[i * le, 0.0, 1.0, 0.0])) for i in range(elements + 1)]
    for i in range(elements):
        cable = mbs.AddObject(
            ObjectANCFCable2D(
                length=le,
                massPerLength=rope.mass_per_length_kg_m,
                bendingStiffness=rope.bending_stiffness_nm2,
                axialStiffness=rope.axial_stiffness_n,
                nodeNumbers=[nodes[i], nodes[i + 1]],
            )
        )
        marker = mbs.AddMarker(MarkerBodyMass(bodyNumber=cable))
        mbs.AddLoad(LoadMassProportional(markerNumber=marker, loadVector=[0.0, -rope.gravity_m_s2, 0.0]))
    ground = mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
    ground_marker = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=ground, coordinate=0))
    for coordinate in (0, 1):
        marker = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nodes[0], coordinate=coordinate))
        mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[ground_marker, marker]))
    sensor = mbs.AddSensor(
        SensorNode(nodeNumber=nodes[-1], storeInternal=True, outputVariableType=exu.OutputVariableType.Position)
    )
    mbs.Assemble()
    settings = exu.SimulationSettings()
    settings.timeIntegration.numberOfSteps = round(duration_s / step_s)
    settings.timeIntegration.endTime = duration_s
    settings.timeIntegration.generalizedAlpha.spectralRadius = 0.9
    settings.timeIntegration.newton.relativeTolerance = 1e-6
    settings.timeIntegration.newton.absoluteTolerance = 1e-8
    settings.timeIntegration.newton.useModifiedNewton = True
    settings.timeIntegration.verboseMode = 0
    settings.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    settings.solution.file.write = False
    settings.solution.sensors.writePeriod = 1e-3
    settings.show.computationTime = False
    settings.show.statistics = False
    start = time.perf_counter()
    mbs.SolveDynamic(settings)
    elapsed = time.perf_counter() - start
    data = np.asarray(mbs.GetSensorStoredData(sensor))
    return elapsed, np.column_stack([data[:, 0], data[:, 1], -data[:, 2]])


def tip_error_m(samples: np.ndarray, reference: np.ndarray) -> float:
    """Largest distance of the tip from the reference at the reference's times (linear interpolation)."""
    x = np.interp(reference[:, 0], samples[:, 0], samples[:, 1])
    y = np.interp(reference[:, 0], samples[:, 0], samples[:, 2])
    return float(np.max(np.hypot(x - reference[:, 1], y + reference[:, 2])))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--elements", type=int, nargs="+", default=[8, 16, 32], help="element counts N")
    parser.add_argument("--steps", type=float, nargs="+", default=[1e-3, 1e-4], help="time steps h in s")
    parser.add_argument("--duration-s", type=float, default=2.0, help="simulated time (reference covers 2 s)")
    parser.add_argument("--repeats", type=int, default=5, help="alternating runs per case (median reported)")
    parser.add_argument("--no-exudyn", action="store_true", help="time ours only")
    parser.add_argument("--json", action="store_true", help="print one JSON document instead of a table")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    try:
        import exudyn  # noqa: F401

        have_exudyn = not args.no_exudyn
    except ImportError:
        have_exudyn = False
        print("exudyn not importable (pip install '.[bench]'): timing ours only", file=sys.stderr)
    reference = np.loadtxt(REFERENCE / "exudyn_paper_rope_n64_h1e-4.csv", delimiter=",", skiprows=1)
    reference = reference[reference[:, 0] <= args.duration_s + 1e-9]
    rope = RopeConfig()
    ours(rope, 2, 1e-3, 0.01)  # warm-up (kernels load from the cache at import)
    rows = []
    for elements in args.elements:
        for step in args.steps:
            times: dict[str, list[float]] = {"ours": [], "exudyn": []}
            errors: dict[str, float] = {}
            for _ in range(args.repeats):
                elapsed, tip = ours(rope, elements, step, args.duration_s)
                times["ours"].append(elapsed)
                errors["ours"] = tip_error_m(tip, reference)
                if have_exudyn:
                    elapsed, tip = exudyn_run(rope, elements, step, args.duration_s)
                    times["exudyn"].append(elapsed)
                    errors["exudyn"] = tip_error_m(tip, reference)
            row = {"elements": elements, "step_s": step, "ours_s": statistics.median(times["ours"])}
            row["ours_tip_error_m"] = errors["ours"]
            if have_exudyn:
                row["exudyn_s"] = statistics.median(times["exudyn"])
                row["ratio"] = row["ours_s"] / row["exudyn_s"]
                row["exudyn_tip_error_m"] = errors["exudyn"]
            rows.append(row)
            if not args.json:
                line = f"N={elements:3d} h={step:.0e}  ours {row['ours_s'] * 1e3:8.1f} ms"
                line += f"  err {errors['ours'] * 1e6:8.2f} um"
                if have_exudyn:
                    line += (
                        f"  exudyn {row['exudyn_s'] * 1e3:8.1f} ms  err {errors['exudyn'] * 1e6:8.2f} um"
                        f"  ratio ours/exudyn {row['ratio']:.3f}"
                    )
                print(line, flush=True)
    if args.json:
        print(json.dumps({"duration_s": args.duration_s, "repeats": args.repeats, "cases": rows}, indent=2))
    return 0
