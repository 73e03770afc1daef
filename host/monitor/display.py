"""What the monitor shows: a rich live table (one row per device) or one plain summary line per second."""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, TextIO

from ropecam.host.monitor.stats import DeviceRow

if TYPE_CHECKING:
    from ropecam.host.session import Session

__all__ = ["CpuMeter", "PlainDisplay", "RichDisplay", "format_row"]


class CpuMeter:
    """CPU time of this process (all threads) as a percentage of one core since the previous reading."""

    def __init__(self) -> None:
        self._cpu = time.process_time()
        self._wall = time.monotonic()

    def percent(self) -> float:
        """Return the load since the last call (or since creation)."""
        cpu, wall = time.process_time(), time.monotonic()
        load = 100.0 * (cpu - self._cpu) / max(wall - self._wall, 1e-9)
        self._cpu, self._wall = cpu, wall
        return load


def _num(value: float, fmt: str) -> str:
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, fmt)


def _tip(row: DeviceRow, compact: bool = False) -> str:
    if row.tip_px is None:
        return "-"
    if compact:  # table column "tip px (mm)"
        text = f"{row.tip_px[0]:.0f},{row.tip_px[1]:.0f}"
        if row.tip_plane_m is not None:
            text += f" ({row.tip_plane_m[0] * 1e3:.0f},{row.tip_plane_m[1] * 1e3:.0f})"
        return text
    text = f"({row.tip_px[0]:.1f}, {row.tip_px[1]:.1f}) px"
    if row.tip_plane_m is not None:
        text += f" ({row.tip_plane_m[0] * 1e3:.1f}, {row.tip_plane_m[1] * 1e3:.1f}) mm"
    return text


def _recording(session: Session) -> str:
    recorder = session.recorder
    if recorder is None:
        return "not recording"
    if recorder.error:
        return f"RECORDING STOPPED: {recorder.error}"
    parts = f" (part {len(recorder.parts)})" if len(recorder.parts) > 1 else ""
    return f"recording {recorder.path}{parts}: {recorder.messages} messages"


def format_row(row: DeviceRow) -> str:
    """One device as compact text (the --no-ui line)."""
    text = (
        f"dev{row.device_id} {_num(row.rate_hz, '.1f')} Hz jit {_num(row.period_jitter_ms, '.2f')} ms "
        f"rx {row.received} lost {row.lost} dup {row.duplicates} reord {row.reordered} "
        f"bad {row.crc_errors + row.decode_errors} devdrop {row.device_dropped} "
        f"{_num(row.bytes_per_s / 1e3, '.1f')} kB/s "
        f"lat {_num(row.latency_ms, '.1f')} ms pipe {_num(row.pipeline_p50_us, '.0f')}/"
        f"{_num(row.pipeline_p99_us, '.0f')} us tip {_tip(row)} conf {_num(row.order_confidence, '.2f')}"
    )
    if not math.isnan(row.model_error_mm):
        text += f" model {row.model_error_mm:.1f} mm"
    if row.warnings:
        text += " !" + ",".join(row.warnings)
    return text


class PlainDisplay:
    """One line per second: elapsed time, then every device (for scripts, CI and log files)."""

    period_s = 1.0

    def __init__(self, stream: TextIO = sys.stdout) -> None:
        self._stream = stream
        self._start = time.monotonic()
        self._cpu = CpuMeter()

    def update(self, session: Session, rows: list[DeviceRow]) -> None:
        """Print the line for this second."""
        elapsed = time.monotonic() - self._start
        devices = " | ".join(format_row(row) for row in rows) or "no device yet"
        extra = f" | {session.stats.bad_packets} unreadable packets" if session.stats.bad_packets else ""
        recording = session.recorder
        if recording is not None and recording.error:
            extra += f" | {_recording(session)}"
        if session.skipped_decodes:
            extra += f" | {session.skipped_decodes} frames not decoded (host busy, raw recorded)"
        print(f"t={elapsed:6.1f}s cpu {self._cpu.percent():3.0f}% {devices}{extra}", file=self._stream, flush=True)

    def close(self) -> None:
        """Nothing to release."""


_WIDE_COLUMNS = 100
"""Narrower terminals leave out jitter, bytes/s and latency (the --no-ui lines always have everything)."""
_COLUMNS: list[tuple[str, str, bool, Callable[[DeviceRow], str]]] = [  # name, justify, wide only, cell
    ("dev", "right", False, lambda r: str(r.device_id)),
    ("Hz", "right", False, lambda r: _num(r.rate_hz, ".1f")),
    ("jit ms", "right", True, lambda r: _num(r.period_jitter_ms, ".2f")),
    ("rx", "right", False, lambda r: str(r.received)),
    ("lost/dup/re", "right", False, lambda r: f"{r.lost}/{r.duplicates}/{r.reordered}"),
    ("bad/drop", "right", False, lambda r: f"{r.crc_errors + r.decode_errors}/{r.device_dropped}"),
    ("kB/s", "right", True, lambda r: _num(r.bytes_per_s / 1e3, ".1f")),
    ("lat ms", "right", True, lambda r: _num(r.latency_ms, ".1f")),
    ("pipe us", "right", False, lambda r: f"{_num(r.pipeline_p50_us, '.0f')}/{_num(r.pipeline_p99_us, '.0f')}"),
    ("tip px (mm)", "left", False, lambda r: _tip(r, compact=True)),
    ("conf", "right", False, lambda r: _num(r.order_confidence, ".2f")),
    ("model mm", "right", False, lambda r: _num(r.model_error_mm, ".1f")),
]


class RichDisplay:
    """A live table refreshed at `period_s` (4 Hz), with the recording state and the latest device log lines."""

    period_s = 0.25

    def __init__(self, source: str) -> None:
        from rich.console import Console
        from rich.live import Live

        self._source = source
        self._cpu = CpuMeter()
        self._console = Console(stderr=False)
        self._live = Live(console=self._console, auto_refresh=False, transient=False)
        self._live.start()

    def update(self, session: Session, rows: list[DeviceRow]) -> None:
        """Redraw the table."""
        from rich import box
        from rich.console import Group
        from rich.table import Table
        from rich.text import Text

        table = Table(
            title=f"ropecam monitor: {self._source}",
            caption="lost/dup/re: sequence gaps, duplicates, reordered; bad: CRC/decode errors; drop: frames the "
            "device dropped; pipe: device pipeline p50/p99; conf: order confidence",
            expand=False,
            box=box.SIMPLE_HEAD,
        )
        wide = self._console.width >= _WIDE_COLUMNS
        columns = [c for c in _COLUMNS if (wide or not c[2]) and (c[0] != "model mm" or session.model is not None)]
        for name, justify, _, _ in columns:
            wraps = name == "tip px (mm)"
            table.add_column(name, justify=justify, no_wrap=not wraps, min_width=8 if wraps else None)  # type: ignore[arg-type]
        for row in rows:
            table.add_row(*(cell(row) for _, _, _, cell in columns), style="bold red" if row.warnings else "")
        lines: list[Table | Text] = [table]
        for row in rows:
            if row.warnings:
                lines.append(Text(f"dev{row.device_id}: " + ", ".join(row.warnings), style="bold red"))
        recorder = session.recorder
        record_style = "bold red" if recorder is not None and recorder.error else "green"
        lines.append(Text(_recording(session), style=record_style))
        lines.append(Text(f"host CPU {self._cpu.percent():.0f}% of one core", style="dim"))
        if session.stats.bad_packets or session.skipped_decodes:
            lines.append(
                Text(
                    f"{session.stats.bad_packets} unreadable packets, {session.skipped_decodes} frames not decoded "
                    "(host busy; raw bytes recorded)",
                    style="yellow",
                )
            )
        describe = getattr(session.model, "describe", None)
        if describe is not None:
            lines.append(Text(describe(), style="cyan"))
        for device_id, level, text in session.recent_logs:
            lines.append(Text(f"dev{device_id} [{level}] {text}", style="red" if level >= 30 else "dim"))
        self._live.update(Group(*lines), refresh=True)

    def close(self) -> None:
        """Leave the last table on screen."""
        self._live.stop()
