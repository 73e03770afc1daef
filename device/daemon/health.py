"""What the daemon knows about its own health: frame rate, CPU load and SoC temperature."""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

__all__ = ["CpuLoadMeter", "RateMeter", "read_temperature_c"]

_THERMAL = Path("/sys/class/thermal/thermal_zone0/temp")


def read_temperature_c(path: Path = _THERMAL) -> float:
    """SoC temperature in degrees Celsius from the kernel's thermal zone; nan where the platform has none."""
    try:
        return int(path.read_text().strip()) / 1000.0
    except (OSError, ValueError):
        return math.nan


class CpuLoadMeter:
    """This process's CPU use since the last call as a FRACTION OF ALL CORES, 0..1 (Status.cpu_load).

    1.0 means every core busy with this process; 0.25 on a 4-core board is one core fully used. (The host monitor's
    own `ropecam.host.monitor.display.CpuMeter` shows percent of ONE core, like `top`; the two are not the same unit.)
    """

    def __init__(self) -> None:
        self._cores = os.cpu_count() or 1
        self._last_wall = time.monotonic()
        self._last_cpu = time.process_time()

    def sample(self) -> float:
        """Fraction of all cores used since the previous call (nan when no time has passed)."""
        wall, cpu = time.monotonic(), time.process_time()
        elapsed = wall - self._last_wall
        load = (cpu - self._last_cpu) / (elapsed * self._cores) if elapsed > 0 else math.nan
        self._last_wall, self._last_cpu = wall, cpu
        return min(max(load, 0.0), 1.0) if math.isfinite(load) else math.nan


class RateMeter:
    """Events per second since the last call."""

    def __init__(self) -> None:
        self._last_wall = time.monotonic()
        self._last_count = 0

    def sample(self, count: int) -> float:
        wall = time.monotonic()
        elapsed = wall - self._last_wall
        rate = (count - self._last_count) / elapsed if elapsed > 0 else 0.0
        self._last_wall, self._last_count = wall, count
        return max(rate, 0.0)
