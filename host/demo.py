"""`ropecam demo`: ropecam end to end on a simulated rig, with a report at the end.

Steps (each is a command you can run yourself; the demo prints them):

1. `ropecam simulate rig-soft`: motion-blurred frames of a soft rope swinging in front of the paper's rig camera
   (1024x544, 119 FPS, 4 ms), with exact ground truth, plus a calibration set through the same camera.
2. `ropecam calibrate intrinsics` and `ropecam calibrate plane`: camera and motion plane from the checkerboards.
3. `ropecam monitor --record --plane` listens on UDP; `ropecam-device run` (the rig daemon) replays the frames as if
   they came from the camera at 30 FPS, measures each frame it gets (the rope at the start and at the end of each
   exposure) and streams the results to it over UDP on this machine. As with a camera, a frame that arrives while
   the daemon is still busy is overtaken by the next one (skipped); the daemon's closing line accounts for every
   frame (measured, skipped, dropped). The recording holds the shapes in pixels and in metres on the plane, the
   transforms between them and a Foxglove layout beside it (run.layout.json).
4. `ropecam compare run.mcap --fit ei`: the recorded material points in metres against the ANCF model, with the bending
   stiffness identified from a deliberately wrong start (3x the truth) and the release time estimated.

At the end the demo prints where every frame went and the identified stiffness, and writes them to demo.json.
"""

from __future__ import annotations

import argparse
import json
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from ropecam.shared.cli import declare_outputs

__all__ = ["register"]

TRUE_EI_NM2 = 1e-5  # the rig-soft preset's rope
MODEL_TOML = """# The rope of the rig-soft preset, with a wrong bending stiffness to start the identification from.
[rope]
length_m = 0.411
diameter_m = 0.001
ei_nm2 = {ei}
[solver]
elements = 16
step_s = 1e-3
"""


def register(subparsers: Any) -> None:
    """Add `ropecam demo` to the command line."""
    parser = subparsers.add_parser(
        "demo",
        help="run ropecam end to end on a simulated rig and write a report (start here)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--out", type=Path, default=Path("demo-out"), help="output folder (default ./demo-out)")
    parser.add_argument("--frames", type=int, default=60, help="frames to simulate (default 60: 0.5 s at 119 FPS)")
    parser.add_argument("--calibration-views", type=int, default=20, help="checkerboard views (default 20)")
    parser.add_argument("--quiet", action="store_true", help="less output")
    declare_outputs(parser, "out")  # with --force every step replaces its outputs in the folder
    parser.set_defaults(func=run_demo)


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _stream(frames: Path, recording: Path, plane: Path, port: int) -> dict[str, Any]:
    """Run the monitor (recording) and the daemon (replaying `frames`) as the two programs they are on a rig; return
    the daemon's account of the frames (`ropecam-device run --summary-json`: measured, skipped, dropped, statuses)."""
    from ropecam.host.monitor.process import MonitorProcess
    from ropecam.shared.errors import RopecamError

    accounting = recording.with_name("device-summary.json")
    monitor = MonitorProcess(["--source", f"udp://127.0.0.1:{port}", "--record", str(recording), "--plane", str(plane),
                              "--force", "--no-ui", "--duration-s", "600"])  # fmt: skip
    try:
        device = subprocess.run(
            [sys.executable, "-m", "ropecam.device.cli", "run", "--source", f"frames:{frames}?fps=30",
             "--sink", f"udp://127.0.0.1:{port}", "--summary-json", str(accounting)],
            capture_output=True, text=True, timeout=600,
        )  # fmt: skip
        print("   device: " + (device.stdout.strip().splitlines() or ["(no output)"])[-1], flush=True)
        if device.returncode != 0:
            raise RopecamError(f"ropecam-device run failed ({device.returncode}):\n{device.stdout}{device.stderr}")
        time.sleep(1.0)  # the last datagrams on their way through the loopback reach the monitor
    except BaseException:
        monitor.kill()
        raise
    code, out, err = monitor.stop()
    last = [line for line in out.splitlines() if line.strip()][-1:] or ["(no output)"]
    print("   monitor: " + last[0], flush=True)
    if code != 0:
        raise RopecamError(f"ropecam monitor failed ({code}):\n{err}{out}")
    return dict(json.loads(accounting.read_text()))


def _step(title: str, command: str) -> float:
    print(f"\n== {title}\n   $ {command}", flush=True)
    return time.perf_counter()


def run_demo(args: argparse.Namespace) -> int:
    """Run the demo; returns the exit code."""
    from ropecam.host.cli import main as host_main
    from ropecam.host.recording.layout import layout_path
    from ropecam.shared.errors import DataError

    out: Path = args.out.resolve()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(f"{out}: cannot create the demo folder: {exc}") from exc
    quiet = ["-q"] if args.quiet else []
    force = ["--force"] if args.force else []
    started = time.perf_counter()
    timings: dict[str, float] = {}

    rig = out / "rig"
    command = ["simulate", "rig-soft", "--out", str(rig), "--frames", str(args.frames), "--first-exposure-ms", "50",
               "--calibration-views", str(args.calibration_views), *force, *quiet]  # fmt: skip
    t = _step("1. simulate the rig (frames, ground truth, calibration set)", "ropecam " + " ".join(command))
    if (code := host_main(command)) != 0:
        return code
    timings["simulate_s"] = time.perf_counter() - t

    calib = rig / "calibration"
    truth = json.loads((calib / "truth.json").read_text())
    board = ["--board", "8x7", "--square-mm", "20"]
    views = sorted(str(p) for p in calib.glob("view_*.png"))
    command = ["calibrate", "intrinsics", *views, *board, "--out", str(out / "camera.yaml"), *force]
    t = _step("2. calibrate the camera and the motion plane", f"ropecam calibrate intrinsics {calib}/view_*.png ...")
    if (code := host_main(command)) != 0:
        return code
    origin = "{:g},{:g}".format(*truth["origin_mm"])
    planes = [str(calib / "plane.png"), *sorted(str(p) for p in calib.glob("plane_0*.png"))]
    command = ["calibrate", "plane", *planes, "--camera", str(out / "camera.yaml"), *board, f"--origin-mm={origin}",
               "--out", str(out / "plane.yaml"), *force]  # fmt: skip
    print(f"   $ ropecam calibrate plane {' '.join(planes[:1])} ... --origin-mm={origin}", flush=True)
    if (code := host_main(command)) != 0:
        return code
    timings["calibrate_s"] = time.perf_counter() - t

    recording = out / "run.mcap"
    port = _free_udp_port()
    t = _step(
        "3. stream: the rig daemon measures every frame and streams over UDP into the monitor's recording",
        f"ropecam monitor --source udp://127.0.0.1:{port} --record {recording} --plane {out / 'plane.yaml'} --no-ui"
        "   (and, meanwhile:)\n"
        f"   $ ropecam-device run --source frames:{rig}?fps=30 --sink udp://127.0.0.1:{port}",
    )
    device = _stream(rig, recording, out / "plane.yaml", port)
    timings["stream_s"] = time.perf_counter() - t

    model = out / "rope.toml"
    model.write_text(MODEL_TOML.format(ei=3 * TRUE_EI_NM2))
    report = out / "report"
    command = ["compare", str(recording), "--plane", str(out / "plane.yaml"), "--model", str(model), "--fit", "ei",
               "--out", str(report), *force]  # fmt: skip
    t = _step("4. compare with the ANCF model, identify EI from 3x the truth", "ropecam " + " ".join(command))
    code = host_main(command)
    timings["compare_s"] = time.perf_counter() - t
    summary = json.loads((report / "summary.json").read_text()) if (report / "summary.json").exists() else {}
    fitted = summary.get("fit", {}).get("values", {}).get("ei")
    total = time.perf_counter() - started
    frames = {key: device[key] for key in ("frames", "measured", "skipped", "dropped")}
    demo = {"frames_rendered": args.frames, "device": {**frames, "statuses": device["statuses"]},
            "measured_samples": summary.get("measured_samples"), "ei_nm2": fitted, "true_ei_nm2": TRUE_EI_NM2,
            "timings_s": {k[:-2]: round(v, 2) for k, v in timings.items()}}  # fmt: skip
    (out / "demo.json").write_text(json.dumps(demo, indent=1) + "\n")
    print(f"\n== done in {total:.0f} s ({', '.join(f'{k[:-2]} {v:.0f} s' for k, v in timings.items())})")
    print(f"   frames: {args.frames} rendered, {frames['measured']} measured "
          f"({', '.join(f'{k} {v}' for k, v in device['statuses'].items()) or 'none'}), {frames['skipped']} skipped "
          f"(the daemon was late: a newer frame overtook them), {frames['dropped']} dropped; "
          f"{summary.get('measured_samples')} shapes recorded")  # fmt: skip
    if fitted is not None:
        print(f"   bending stiffness: started at {3 * TRUE_EI_NM2:.3g}, identified {fitted:.4g} N m^2 "
              f"(simulated truth {TRUE_EI_NM2:.3g}, {100 * (fitted / TRUE_EI_NM2 - 1):+.1f} %)")  # fmt: skip
    print(f"   report: {report / 'index.html'}  (plots, summary.json); this summary: {out / 'demo.json'}")
    print(f"   frames and ground truth: {rig}; calibration: {out / 'camera.yaml'}, {out / 'plane.yaml'}")
    print(f"   the live recording: {recording} (open it in Foxglove with the layout {layout_path(recording)}, or "
          f"`ropecam replay {recording}`)")  # fmt: skip
    sys.stdout.flush()
    return code
