"""``gait-biofeedback batch``: every recording of ``GLOB_OR_DIR`` analysed on Dask distributed, one
:func:`~gait_biofeedback.cohort.task.analyse_one` task per session (a local cluster of ``workers``
single-threaded processes on 127.0.0.1 by default, or the scheduler at ``scheduler``: then the workers
must see the same paths, e.g. a shared file system, and have this package installed). Sessions an
earlier run finished for the same recording are skipped; a failing one is reported and the others go
on; the cohort table (:mod:`.table`) holds them all."""

from __future__ import annotations

import logging
import os
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gait_biofeedback.cohort.sessions import Recording, find_recordings
from gait_biofeedback.cohort.table import write_cohort
from gait_biofeedback.cohort.task import BatchOptions, analyse_one, previous


@dataclass
class BatchResult:
    rows: list[dict[str, Any]]
    analysed: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    csv: Path | None = None
    parquet: Path | None = None


def default_workers() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def run_batch(spec: str, out: str | Path, options: BatchOptions | None = None, workers: int | None = None,
              scheduler: str | None = None, on_done: Callable[[dict[str, Any]], None] | None = None
              ) -> BatchResult:
    """Analyse every recording of ``spec`` into ``out`` (module docstring); ``on_done`` is called with
    each finished session's row (a progress bar)."""
    options = options or BatchOptions()
    out = Path(out)
    recordings = find_recordings(spec, exclude=out)
    out.mkdir(parents=True, exist_ok=True)
    result = BatchResult(rows=[])
    todo: list[Recording] = []
    for recording in recordings:
        row = previous(out, recording)
        if row is None:
            todo.append(recording)
        else:
            result.rows.append(row)
            result.skipped.append(recording.name)
    if todo:
        for row in _on_dask(todo, out, options, workers or default_workers(), scheduler, on_done):
            result.rows.append(row)
            if row["status"] == "done":
                result.analysed.append(row["session"])
            else:
                result.failed[row["session"]] = row["error"]
    result.csv, result.parquet = write_cohort(result.rows, out)
    return result


def _on_dask(todo: list[Recording], out: Path, options: BatchOptions, workers: int, scheduler: str | None,
             on_done: Callable[[dict[str, Any]], None] | None) -> list[dict[str, Any]]:
    from dask.distributed import Client, LocalCluster, as_completed

    if scheduler:
        cluster, client = None, Client(scheduler, timeout="30s")
    else:
        cluster = LocalCluster(n_workers=min(workers, len(todo)), threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
    run = uuid.uuid4().hex[:8]
    rows = []
    try:
        futures = {client.submit(analyse_one, r, str(out.resolve()), options, key=f"analyse-{r.name}-{run}",
                                 pure=False): r for r in todo}
        for future in as_completed(futures):
            try:
                row = future.result()
            except Exception as err:  # a worker that died with it: reported, the rest go on
                recording = futures[future]
                row = {"session": recording.name, "recording": str(recording.path), "status": "failed",
                       "error": f"the worker was lost ({type(err).__name__}: {err})"}
            rows.append(row)
            if on_done is not None:
                on_done(row)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return rows
