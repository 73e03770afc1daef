"""Evaluations of ropecam against ground truth: pipeline accuracy, calibration, the paper's Harris figure, the daemon
end to end, the robustness matrix (every method on every simulated scene), and `ropecam-device setup`'s configs.

    python tools/evaluate.py COMMAND [options]         python tools/evaluate.py COMMAND --help

Every figure is labelled with the scene it was measured on (synthetic frames, a simulator preset, a recorded set);
simulator figures are not the paper's real-frame figures.
"""

import sys

from ropecam_tools.cli import dispatch

COMMANDS = {
    "accuracy": "eval_accuracy",
    "band-snr": "eval_band_snr",
    "band-track": "eval_band_track",
    "calibration": "eval_calibration",
    "harris": "eval_harris",
    "e2e": "eval_e2e",
    "matrix": "matrix",
    "montage": "sim_montage",
    "setup": "eval_setup",
}
"""Subcommand -> module of `ropecam_tools` (with ``add_arguments(parser)`` and ``run(args) -> int``)."""

if __name__ == "__main__":
    sys.exit(dispatch(__doc__, COMMANDS))
