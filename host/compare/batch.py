"""Compare many recordings in parallel on Dask (a local cluster by default, or an existing scheduler)."""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ropecam.host.compare.run import compare_recording
from ropecam.shared.errors import RopecamError

__all__ = ["compare_batch"]


def _one(measurement: Path, out: Path, options: dict[str, Any]) -> dict[str, Any]:
    """Worker task: one recording. Any failure becomes that recording's entry; the other recordings go on."""
    try:
        return compare_recording(measurement, out=out, verbose=False, **options)
    except Exception as exc:  # one bad recording must not cost the batch the others
        return {"error": f"{type(exc).__name__}: {exc}"}


def compare_batch(
    recordings: Sequence[Path],
    out: Path,
    options: dict[str, Any],
    scheduler: str | None = None,
    workers: int = 2,
) -> dict[str, dict[str, Any]]:
    """Run `compare_recording` for every recording, each into ``out/<name>/``; return the summaries by name.

    Parameters
    ----------
    recordings
        Measurement files; their stems name the report folders (they must be unique).
    out
        Parent folder of the reports.
    options
        Keyword arguments of `compare_recording` shared by all recordings.
    scheduler
        Address of a running Dask scheduler; None starts a local cluster of `workers` processes.
    """
    from dask.distributed import Client, LocalCluster, as_completed

    names = [path.stem for path in recordings]
    if len(set(names)) != len(names):
        raise RopecamError("recordings in one batch must have distinct file names")
    if workers < 1:
        raise RopecamError(f"--workers must be >= 1, got {workers}")
    # Workers (maybe on other machines sharing the file system) must not resolve paths against their own cwd.
    recordings = [Path(path).resolve() for path in recordings]
    out = Path(out).resolve()
    options = {k: (v.resolve() if isinstance(v, Path) else v) for k, v in options.items()}
    out.mkdir(parents=True, exist_ok=True)
    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0")
        client = Client(cluster)
    else:
        client = Client(scheduler)
    results: dict[str, dict[str, Any]] = {}
    try:
        futures = {
            client.submit(_one, path, out / name, options, pure=False): name
            for path, name in zip(recordings, names, strict=True)
        }
        for done, future in enumerate(as_completed(futures), start=1):
            name = futures[future]
            try:
                results[name] = future.result()
            except Exception as exc:  # a lost worker: record it, keep the rest
                results[name] = {"error": f"{type(exc).__name__}: {exc}"}
            partial = {n: results[n] for n in names if n in results}
            (out / "summary.json").write_text(json.dumps(partial, indent=2) + "\n")  # finished work is never lost
            print(f"[{done}/{len(futures)}] {name} {'failed' if 'error' in results[name] else 'done'}",
                  file=sys.stderr, flush=True)  # fmt: skip
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return {name: results[name] for name in names}
