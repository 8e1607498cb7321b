"""Running tasks: in this process, on a Dask ``LocalCluster`` or on a cluster's scheduler.

Tasks run in this process (``jobs=1``), on a ``LocalCluster`` of ``jobs``
worker processes with one thread each, or on the cluster at ``scheduler``
(``tcp://HOST:8786``, workers started with ``dask worker``). :func:`run`
appends each finished row to ``results.csv`` and skips the rows already there,
so a killed run loses only the missions in flight.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from dualpilot.evaluation.missions import Task, run_task
from dualpilot.evaluation.results import ResultsFile, read_results
from dualpilot.mission.result import Ending


def progress_line(done: int, total: int, t0: float, skipped: int) -> None:
    """A progress bar with the rate of this run's missions and the time left."""
    elapsed = time.perf_counter() - t0
    rate = (done - skipped) / elapsed if elapsed > 0 and done > skipped else 0.0
    left = (total - done) / rate if rate > 0 else float("nan")
    width = 30
    filled = int(width * done / max(total, 1))
    eta = f"{left / 60:5.1f} min left" if math.isfinite(left) else "   ?  min left"
    sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} {eta}")
    sys.stderr.flush()


def _error_row(task: Any, err: BaseException) -> dict[str, object]:
    if not isinstance(task, Task):
        return {"task": repr(task), "error": f"worker lost: {type(err).__name__}: {err}"}
    return {**task.identity(), "success": 0, "failure_cause": Ending.ERROR.value,
            "error": f"worker lost: {type(err).__name__}: {err}"}


def execute(tasks: Sequence[Any], jobs: int = 1, scheduler: str | None = None,
            processes: bool = True,
            fn: Callable[[Any], dict[str, object]] = run_task) -> Iterator[dict[str, object]]:
    """``fn(task)`` for each task as it finishes: here, on a LocalCluster or on ``scheduler``.

    ``fn`` must not raise; a task whose worker died yields an error row.
    """
    if not tasks:
        return
    if scheduler is None and jobs <= 1:
        for task in tasks:
            yield fn(task)
        return
    from distributed import Client, LocalCluster, as_completed

    if scheduler is not None:
        client = Client(scheduler)
        cluster = None
    else:
        cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=processes,
                               dashboard_address=":0", silence_logs=logging.ERROR)
        client = Client(cluster)
    try:
        futures = client.map(fn, list(tasks), pure=False)
        owner = {f.key: t for f, t in zip(futures, tasks, strict=True)}
        # results fetched by the client's event loop as tasks finish, taken here a batch at
        # a time (a blocking result() per future costs this process a few ms each)
        done = as_completed(futures, with_results=True, raise_errors=False)
        for batch in done.batches():
            for fut, result in batch:
                if fut.status == "error":  # a worker died: the row says so
                    yield _error_row(owner[fut.key], fut.exception())
                else:
                    yield result
                fut.release()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run(tasks: list[Task], path: Path, columns: Sequence[str], key: Sequence[str],
        jobs: int = 1, scheduler: str | None = None, progress: bool = True,
        processes: bool = True) -> float:
    """Run the tasks not yet recorded in ``path`` (matched on the ``key`` columns).

    Returns the wall time (s). Rows are appended and fsynced as they finish.
    """
    def task_key(t: Task) -> tuple[str, ...]:
        row = t.identity()
        return tuple(str(row[k]) for k in key)

    done_keys = {tuple(r[k] for k in key) for r in read_results(path)}
    todo = [t for t in tasks if task_key(t) not in done_keys]
    total = len(tasks)
    skipped = total - len(todo)
    writer = ResultsFile(path, columns)
    t0 = time.perf_counter()
    done = skipped
    try:
        for row in execute(todo, jobs, scheduler, processes):
            writer.append(row)
            done += 1
            if progress:
                progress_line(done, total, t0, skipped)
    finally:
        writer.close()
        if progress:
            sys.stderr.write("\n")
    return time.perf_counter() - t0
