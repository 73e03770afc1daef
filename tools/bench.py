"""Benchmarks of ropecam: the device pipeline against cv2.Canny, its kernels and glue, the wire protocol, the ANCF
model, the host monitor, capture, start-up (to the first result, and the first frames' latency) and the simulator.

    python tools/bench.py COMMAND [options]         python tools/bench.py COMMAND --help

Time on one core of a quiet machine (``taskset -c 1``) and read ratios measured in one run (paired); absolute
times drift with the load. The ledger of speed work and its method: docs/speed.md.
"""

import sys

from ropecam_tools.cli import dispatch

COMMANDS = {
    "device": "bench_device",
    "glue": "bench_glue",
    "cold": "bench_cold",
    "kernels": "bench_kernels",
    "bands": "bench_bands",
    "protocol": "bench_protocol",
    "ancf": "bench_ancf",
    "host": "bench_host",
    "capture": "bench_capture",
    "startup": "bench_startup",
    "first-frames": "bench_first_frames",
    "simulate": "bench_simulate",
    "boards": "bench_boards",
    "recording-size": "bench_recording_size",
    "wire-size": "bench_wire",
}
"""Subcommand -> module of `ropecam_tools` (with ``add_arguments(parser)`` and ``run(args) -> int``)."""

if __name__ == "__main__":
    sys.exit(dispatch(__doc__, COMMANDS))
