"""`ropecam monitor` as a child process, for programs that drive a whole rig on one machine (demo, tests, benchmarks).

The monitor writes its output into files (a pipe nobody reads would fill up and stall it), and `MonitorProcess`
returns only once the monitor printed its ``receiving on`` line, i.e. its port is bound: no fixed sleep that a cold
Numba cache or a busy machine outlasts.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Final

from ropecam.shared.errors import RopecamError

__all__ = ["READY_TEXT", "MonitorProcess"]

READY_TEXT: Final = "receiving on"
"""What the monitor prints on stderr once its transport is open."""


class MonitorProcess:
    """Start ``python -m ropecam.host.cli monitor ARGS`` and wait until it receives.

    Parameters
    ----------
    args
        Monitor arguments (``--source ... --record ...``).
    log_dir
        Where ``monitor.out`` and ``monitor.err`` go (default: a temporary folder removed by `finish`).
    start_timeout_s
        How long to wait for the ``receiving on`` line.

    Raises
    ------
    RopecamError
        The monitor exited, or did not report receiving within `start_timeout_s` (it is killed; the message holds
        its output).
    """

    def __init__(self, args: list[str], log_dir: Path | None = None, start_timeout_s: float = 120.0) -> None:
        self._tmp = tempfile.TemporaryDirectory(prefix="ropecam-monitor-") if log_dir is None else None
        folder = Path(self._tmp.name) if self._tmp is not None else Path(log_dir)
        self.stdout_path = folder / "monitor.out"
        self.stderr_path = folder / "monitor.err"
        self._output: tuple[str, str] | None = None  # (stdout, stderr) once the monitor exited
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        with open(self.stdout_path, "w") as out, open(self.stderr_path, "w") as err:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "ropecam.host.cli", "monitor", *args], stdout=out, stderr=err, text=True, env=env
            )
        deadline = time.monotonic() + start_timeout_s
        while READY_TEXT not in self.stderr_path.read_text():
            if self.process.poll() is not None:
                _, out_text, err_text = self._collect()
                raise RopecamError(f"the monitor stopped at once ({self.process.returncode}):\n{err_text}{out_text}")
            if time.monotonic() > deadline:
                self.process.kill()
                _, out_text, err_text = self._collect(timeout_s=10.0)
                raise RopecamError(f"the monitor did not start within {start_timeout_s:g} s:\n{err_text}{out_text}")
            time.sleep(0.02)

    @property
    def pid(self) -> int:
        """Process id of the monitor."""
        return self.process.pid

    def _collect(self, timeout_s: float | None = None) -> tuple[int | None, str, str]:
        if timeout_s is not None:
            self.process.wait(timeout_s)
        if self._output is None:
            out, err = self.stdout_path.read_text(), self.stderr_path.read_text()
            if self.process.poll() is None:
                return None, out, err
            self._output = (out, err)  # final: the temporary folder may go
            if self._tmp is not None:
                self._tmp.cleanup()
                self._tmp = None
        return self.process.returncode, *self._output

    def finish(self, timeout_s: float = 60.0) -> tuple[int, str, str]:
        """Wait for the monitor to exit (killed after `timeout_s`); return (exit code, stdout, stderr).

        Raises
        ------
        RopecamError
            It had to be killed (the message holds its output).
        """
        try:
            self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            _, out, err = self._collect(timeout_s=10.0)
            raise RopecamError(f"the monitor did not exit within {timeout_s:g} s and was killed:\n{err}{out}") from None
        code, out, err = self._collect()
        return int(code if code is not None else -1), out, err

    def stop(self, timeout_s: float = 60.0) -> tuple[int, str, str]:
        """Ask the monitor to stop (SIGTERM: it records what it received and closes the file); see `finish`."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        return self.finish(timeout_s)

    def kill(self) -> None:
        """Kill the monitor if it still runs (cleanup after a failure)."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        self._collect()
