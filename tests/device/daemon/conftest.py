"""A small simulated rig recording, and a helper that runs the daemon in a thread."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from ropecam.device.daemon.runner import Daemon


@pytest.fixture(scope="package")
def rig_set(rig_frames: Path) -> Path:
    """Twelve frames of the simulated rig (1024x544, 4 ms) while the rope swings fast (`rig_frames`)."""
    return rig_frames


class RunningDaemon:
    """A daemon running in a thread; `stop()` returns its exit code."""

    def __init__(self, daemon: Daemon) -> None:
        self.daemon = daemon
        self.stop_event = threading.Event()
        self.code: int | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        self.code = self.daemon.run(self.stop_event)

    def stop(self, timeout_s: float = 20.0) -> int | None:
        self.stop_event.set()
        self.thread.join(timeout_s)
        return self.code

    def wait(self, timeout_s: float = 60.0) -> int | None:
        self.thread.join(timeout_s)
        return self.code


@contextmanager
def running(daemon: Daemon) -> Iterator[RunningDaemon]:
    handle = RunningDaemon(daemon)
    try:
        yield handle
    finally:
        handle.stop()
