"""ropecam's host side: receiver, calibration, ANCF model, rig simulator, comparison, recording, monitor, replay."""
