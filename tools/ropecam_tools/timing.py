"""Timing helpers shared by the benchmarks: kernel timers, cache eviction, best-of and paired medians."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from types import ModuleType
from typing import Any

import numpy as np

_EVICT = np.zeros(8 << 20, np.uint8)
"""Written by `evict` (8 MiB: more than L2, as the rest of a frame's work between two calls of one kernel)."""


def evict() -> None:
    """Fill the CPU caches with other data (as a frame's other work does before a kernel's next call)."""
    np.add(_EVICT, 1, out=_EVICT)


def compiled_names(kernels: ModuleType) -> list[str]:
    """The names of the compiled (Numba) functions of a kernels package."""
    return sorted(name for name in dir(kernels) if hasattr(getattr(kernels, name), "py_func"))


class KernelTimer:
    """Wrap kernels of a `_kernels` package by name so that the time spent in each accumulates in `spent` (ns).

    Each wrapper adds ~0.1-0.3 us per call (counted on the kernel side). The pipeline calls its kernels through the
    package's attributes, so wrapping the attribute reaches every call. Use as a context manager, or call `restore`.

    Parameters
    ----------
    kernels : module
        The kernels package (``ropecam.device.pipeline._kernels`` or the reference tree's).
    names : Iterable[str], optional
        Kernels to wrap (default: every compiled one); names the package lacks are left out.
    """

    def __init__(self, kernels: ModuleType, names: Iterable[str] | None = None) -> None:
        self.kernels = kernels
        self.spent: dict[str, int] = {}
        self.originals: dict[str, Any] = {}
        for name in compiled_names(kernels) if names is None else names:
            function = getattr(kernels, name, None)
            if function is not None:
                self.originals[name] = function
                setattr(kernels, name, self._wrap(name, function))

    def _wrap(self, name: str, function: Any) -> Any:
        spent = self.spent

        def timed(*args: Any) -> Any:
            start = time.perf_counter_ns()
            try:
                return function(*args)
            finally:
                spent[name] = spent.get(name, 0) + time.perf_counter_ns() - start

        return timed

    @property
    def total_ns(self) -> int:
        """Time spent in the wrapped kernels since the last `clear`."""
        return sum(self.spent.values())

    def clear(self) -> None:
        """Forget the times spent so far."""
        self.spent.clear()

    def restore(self) -> None:
        """Put the original kernels back."""
        for name, function in self.originals.items():
            setattr(self.kernels, name, function)
        self.originals.clear()

    def __enter__(self) -> KernelTimer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.restore()


def best_of_us(fn: Callable[[Any], object], inputs: Sequence[Any], repeat: int, cold: bool = False) -> list[float]:
    """For each input, the fastest of `repeat` timed calls ``fn(item)`` (us); with `cold`, `evict` before each."""
    out = []
    for item in inputs:
        best = float("inf")
        for _ in range(repeat):
            if cold:
                evict()
            start = time.perf_counter_ns()
            fn(item)
            best = min(best, (time.perf_counter_ns() - start) / 1000)
        out.append(best)
    return out


def paired(mine: Sequence[float], theirs: Sequence[float]) -> tuple[float, float]:
    """Median of the per-item ratios mine / theirs and of the differences theirs - mine (the time saved).

    Each pair was measured on the same input under the same load, so the medians of the pairs hold on a busy
    machine where the medians of each side drift.
    """
    a, b = np.asarray(mine, float), np.asarray(theirs, float)
    if a.shape != b.shape or a.size == 0:
        raise ValueError(f"paired: need two equal, non-empty series, got {a.shape} and {b.shape}")
    return float(np.median(a / np.maximum(b, 1e-9))), float(np.median(b - a))


def format_table(header: Sequence[str], rows: Iterable[Sequence[object]], floats: str = ".1f") -> str:
    """A plain text table: the first column left-aligned, the others right-aligned, floats as `floats`."""
    text = [[f"{v:{floats}}" if isinstance(v, float) else str(v) for v in row] for row in rows]
    table = [list(header), *text]
    widths = [max(len(row[k]) for row in table) for k in range(len(header))]
    lines = [
        "  ".join(cell.ljust(widths[k]) if k == 0 else cell.rjust(widths[k]) for k, cell in enumerate(row))
        for row in table
    ]
    return "\n".join(lines)
