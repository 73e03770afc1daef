"""Progress display for long host jobs: a rich progress bar on a terminal, periodic plain lines otherwise."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Protocol

__all__ = ["ProgressCallback", "fit_progress", "progress_bar"]

PLAIN_INTERVAL_S = 2.0
"""Seconds between progress lines when stderr is not a terminal (a log file, a pipe, a CI job)."""


class ProgressCallback(Protocol):
    """Called with the amount of work done so far (same unit as the total)."""

    def __call__(self, done: float) -> None: ...


@contextmanager
def progress_bar(description: str, total: float, unit: str = "", enabled: bool = True) -> Iterator[ProgressCallback]:
    """Yield a callback that reports `done` out of `total`; a rich bar on a TTY, a line every 2 s elsewhere.

    Output goes to stderr so that stdout stays clean for results.
    """
    if not enabled:
        yield lambda done: None
        return
    if sys.stderr.isatty():
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

        columns = (
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed:.3g}/{task.total:.3g} " + unit),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
        )
        with Progress(*columns, transient=False) as progress:
            task = progress.add_task(description, total=total)
            yield lambda done: progress.update(task, completed=done)
        return
    last = [time.monotonic()]

    def report(done: float) -> None:
        now = time.monotonic()
        if now - last[0] >= PLAIN_INTERVAL_S or done >= total:
            last[0] = now
            print(f"{description}: {done:.4g}/{total:.4g} {unit}".rstrip(), file=sys.stderr, flush=True)

    yield report


def fit_progress(enabled: bool = True) -> Callable[[int, float], None]:
    """Return a reporter of a model fit's progress: ``report(model_runs, rms_m)``.

    On a terminal one line is rewritten in place; elsewhere a line is printed at most every `PLAIN_INTERVAL_S`
    (the first run's is printed at once), so a log never gets one endless line of carriage returns. Callers end a
    terminal line with a newline on stderr when the fit is done.
    """
    tty = sys.stderr.isatty()
    last: list[float | None] = [None]

    def report(evaluations: int, rms_m: float) -> None:
        if not enabled:
            return
        line = f"  model runs {evaluations}: RMS {rms_m * 1e3:.3f} mm"
        if tty:
            print(line, file=sys.stderr, end="\r", flush=True)
            return
        now = time.monotonic()
        if last[0] is None or now - last[0] >= PLAIN_INTERVAL_S:
            last[0] = now
            print(line, file=sys.stderr, flush=True)

    return report
