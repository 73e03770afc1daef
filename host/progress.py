"""Progress display for long host jobs: a rich progress bar on a terminal, periodic plain lines otherwise."""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Protocol

__all__ = ["ProgressCallback", "progress_bar"]


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
        if now - last[0] >= 2.0 or done >= total:
            last[0] = now
            print(f"{description}: {done:.4g}/{total:.4g} {unit}".rstrip(), file=sys.stderr, flush=True)

    yield report
