"""The Monte-Carlo runner: a grid of readings × controllers × N missions, on Dask distributed.

Configuration i (start, goal, fire and supervisor streams) is drawn from the
seed pair (S, i): identical for every controller and every grid point. One
task is one mission (:func:`run_task`, which never raises). Tasks run in this
process (``jobs=1``), on a ``LocalCluster`` of ``jobs`` worker processes with
one thread each, or on the cluster at ``scheduler`` (``tcp://HOST:8786``,
workers started with ``dask worker``). Rows are appended to ``results.csv``
and fsynced as they finish; a re-run with the same directory skips what is
recorded, so a killed run loses only the missions in flight. ``dualpilot
evaluate`` is the one-point case (:mod:`dualpilot.evaluate`).
"""

from __future__ import annotations

import csv
import itertools
import json
import logging
import math
import os
import sys
import time
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.mission.params import Timing, controller_of, uses_risk
from dualpilot.readings import Profile, get_profile, parse_value, settable
from dualpilot.spec import MissionSpec

CONTROLLERS = ("cc", "s1", "s2")
#: evaluate's results.csv (unchanged by the sweep)
COLUMNS = [
    "mission", "seed", "controller", "timing", "success", "failure_cause", "steps",
    "mission_time_s", "energy", "switches", "switch_energy", "fire_substeps", "s1_plans",
    "s2_plans",
    "planning_time_s_median", "planning_time_s_p95", "planning_time_s_total", "start_x",
    "start_y", "goal_x", "goal_y",
    "wall_s", "error",
]
#: the columns that are measured, not computed: they differ between any two runs
MEASURED_COLUMNS = frozenset({"wall_s", "planning_time_s_median", "planning_time_s_p95",
                              "planning_time_s_total"})
#: the sweep's tidy table: the grid point and every parameter value, then COLUMNS
SWEEP_COLUMNS = ["point", "label", "profile", *settable(), *COLUMNS]

Settings = tuple[tuple[str, Any], ...]


def mission_seed(seed: int, index: int) -> int:
    """The seed of configuration ``index`` in a run seeded with ``seed``."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def mission_spec(seed: int, index: int) -> MissionSpec:
    """The spec of configuration ``index``: its start, goal and seed."""
    mseed = mission_seed(seed, index)
    return MissionSpec.random(np.random.default_rng(mseed), seed=mseed)


@dataclass(frozen=True)
class Task:
    """One mission: configuration ``index`` of ``seed``, one controller, one reading."""

    index: int
    seed: int
    controller: str
    timing: str
    s2_method: str
    ignition_clearance_m: float | None = None  # set (not None): overrides the profile's
    profile: str = "today"
    settings: Settings = ()
    point: int = 0
    label: str = ""

    def reading(self) -> Profile:
        extra = dict(self.settings)
        if self.ignition_clearance_m is not None:
            extra["ignition_clearance_m"] = self.ignition_clearance_m
        return get_profile(self.profile).with_settings(extra)


def run_task(task: Task) -> dict[str, object]:
    """Fly one mission; never raises (an exception becomes an error row)."""
    from dualpilot.mission.local import local_mission

    config = mission_spec(task.seed, task.index)
    row: dict[str, object] = {
        "point": task.point, "label": task.label, "profile": task.profile,
        "mission": task.index, "seed": config.seed, "controller": task.controller,
        "timing": task.timing, "start_x": config.start[0], "start_y": config.start[1],
        "goal_x": config.goal.center_x, "goal_y": config.goal.center_y, "error": "",
    }
    t0 = time.perf_counter()
    try:
        reading = task.reading()
        row.update(reading.values())
        controller, supervisor = controller_of(task.controller)
        result = local_mission(
            controller, reading.spec(config), timing=Timing(task.timing),
            params=reading.mission, fire_params=reading.fire,
            supervisor_params=reading.supervisor, system2_method=task.s2_method,
            supervisor=supervisor, risk=uses_risk(task.controller),
        ).run()
        times = result.planning_time_s["s1"] + result.planning_time_s["s2"]
        row.update(
            success=int(result.success), failure_cause=result.failure_cause,
            steps=result.steps, mission_time_s=result.mission_time_s,
            energy=round(result.energy, 6), switches=result.switches,
            switch_energy=round(result.switch_energy, 6),
            fire_substeps=sum(r.fire_substeps for r in result.records)
            + reading.mission.fire_substeps_per_motion * result.steps,
            s1_plans=len(result.planning_time_s["s1"]),
            s2_plans=len(result.planning_time_s["s2"]),
            planning_time_s_median=float(np.median(times)) if times else "",
            planning_time_s_p95=float(np.percentile(times, 95)) if times else "",
            planning_time_s_total=float(np.sum(times)),
        )
    except Exception as err:  # noqa: BLE001 - recorded, the run goes on
        row.update(success=0, failure_cause="error", error=f"{type(err).__name__}: {err}")
        traceback.print_exc(file=sys.stderr)
    row["wall_s"] = round(time.perf_counter() - t0, 3)
    return row


# -- the grid ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Point:
    """One grid point: a profile and the settings applied on top of it."""

    index: int
    profile: str
    settings: Settings

    @property
    def label(self) -> str:
        parts = [f"profile={self.profile}"] + [f"{k}={_text(v)}" for k, v in self.settings]
        return " ".join(parts)


def _text(v: Any) -> str:
    return "none" if v is None else str(v).lower() if isinstance(v, bool) else str(v)


def _value(name: str, v: Any) -> Any:
    return parse_value(name, _text(v))


def grid_points(axes: Mapping[str, Sequence[Any]], profile: str = "today",
                points: Sequence[Mapping[str, Any]] = ()) -> list[Point]:
    """The cartesian product of ``axes`` (name → values; "profile" may be one), then ``points``.

    Each point's settings are checked by building its profile.
    """
    out: list[Point] = []
    combos: list[dict[str, Any]] = []
    if axes:
        names = list(axes)
        combos = [dict(zip(names, vals, strict=True))
                  for vals in itertools.product(*(axes[n] for n in names))]
    elif not points:
        combos = [{}]
    for combo in [*combos, *points]:
        combo = dict(combo)
        prof = str(combo.pop("profile", profile))
        settings = tuple((k, _value(k, v)) for k, v in combo.items())
        p = Point(len(out), prof, settings)
        get_profile(prof).with_settings(dict(settings))  # raises on a bad value
        out.append(p)
    return out


def parse_axes(items: Sequence[str]) -> dict[str, list[str]]:
    """Repeated ``--set name=v1,v2`` flags as grid axes."""
    axes: dict[str, list[str]] = {}
    for item in items:
        key, sep, values = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"a grid axis is 'name=v1,v2,...', got {item!r}")
        axes[key.strip()] = [v.strip() for v in values.split(",")]
    return axes


def load_grid(path: Path) -> dict[str, Any]:
    """A sweep file (YAML): ``profile``, ``grid`` (name → values), ``points`` (list of dicts),
    and optionally ``missions``, ``controllers``, ``seed``, ``timing``."""
    import yaml

    doc = yaml.safe_load(path.read_text()) or {}
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: a sweep file is a mapping")
    unknown = set(doc) - {"profile", "grid", "points", "missions", "controllers", "seed",
                          "timing", "s2_method"}
    if unknown:
        raise ValueError(f"{path}: unknown keys {sorted(unknown)}")
    return doc


# -- results ----------------------------------------------------------------------------------
def read_results(path: Path) -> list[dict[str, str]]:
    if not path.exists():
        return []
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


class ResultsFile:
    """Append-only CSV; each row is flushed and fsynced as soon as it is written.

    A row cut short by a kill (no final newline) is dropped when the file is reopened.
    """

    def __init__(self, path: Path, columns: Sequence[str] = COLUMNS):
        self.path = path
        _drop_partial_line(path)
        new = not path.exists() or path.stat().st_size == 0
        if not new:
            with path.open(newline="") as fh:
                header = next(csv.reader(fh), [])
            if header != list(columns):
                raise ValueError(f"{path} has other columns; use another --out")
        self.fh = path.open("a", newline="")
        self.writer = csv.DictWriter(self.fh, fieldnames=list(columns), extrasaction="ignore")
        if new:
            self.writer.writeheader()
            self._sync()

    def _sync(self) -> None:
        self.fh.flush()
        os.fsync(self.fh.fileno())

    def append(self, row: Mapping[str, object]) -> None:
        self.writer.writerow(row)
        self._sync()

    def close(self) -> None:
        self.fh.close()


def _drop_partial_line(path: Path) -> None:
    if not path.exists() or path.stat().st_size == 0:
        return
    data = path.read_bytes()
    if not data.endswith(b"\n"):
        with path.open("r+b") as fh:
            fh.truncate(data.rfind(b"\n") + 1)


def write_parquet(csv_path: Path, out: Path) -> Path:
    """The CSV table as Parquet (types inferred by pyarrow)."""
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    pq.write_table(pacsv.read_csv(csv_path), out)
    return out


# -- running ----------------------------------------------------------------------------------
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
    return {"point": task.point, "label": task.label, "profile": task.profile,
            "mission": task.index, "seed": mission_seed(task.seed, task.index),
            "controller": task.controller, "timing": task.timing, "success": 0,
            "failure_cause": "error", "error": f"worker lost: {type(err).__name__}: {err}"}


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
        row = {"point": t.point, "label": t.label, "mission": t.index, "controller": t.controller}
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


def check_config(out: Path, config: Mapping[str, Any]) -> None:
    """Refuse to resume a run directory made with another configuration."""
    path = out / "run.json"
    if path.exists():
        old = json.loads(path.read_text())
        diff = {k for k in set(old) | set(config) if old.get(k) != config.get(k)}
        if diff:
            raise ValueError(f"{out} holds a run with other {', '.join(sorted(diff))} "
                             f"({', '.join(f'{k}={old.get(k)!r}' for k in sorted(diff))}); "
                             "use another --out")
    path.write_text(json.dumps(config, indent=2) + "\n")


def sweep(points: Sequence[Point], missions: int, out: Path, seed: int = 0,
          timing: str = "paper", controllers: Sequence[str] = CONTROLLERS,
          s2_method: str = "fast", jobs: int | None = None, scheduler: str | None = None,
          progress: bool = True, processes: bool = True,
          figures: bool = True) -> dict[str, Any]:
    """Run (or resume) the sweep in ``out``: results.csv/.parquet, summary.json, figures."""
    from dualpilot.evaluate import summarize

    out.mkdir(parents=True, exist_ok=True)
    config = {"seed": seed, "timing": timing, "s2_method": s2_method,
              "points": [p.label for p in points]}
    check_config(out, {k: v for k, v in config.items() if k != "points"})
    tasks = [Task(i, seed, c, timing, s2_method, profile=p.profile, settings=p.settings,
                  point=p.index, label=p.label)
             for i in range(missions) for p in points for c in controllers]
    path = out / "results.csv"
    wall = run(tasks, path, SWEEP_COLUMNS, ("label", "mission", "controller"),
               jobs or os.cpu_count() or 1, scheduler, progress, processes)
    rows = read_results(path)
    write_parquet(path, out / "results.parquet")
    summary: dict[str, Any] = {**config, "missions": missions, "wall_s": wall,
                               "controllers": list(controllers), "points": []}
    for p in points:
        mine = [r for r in rows if r["label"] == p.label and int(r["mission"]) < missions]
        s = summarize(mine, missions, timing)
        summary["points"].append({"point": p.index, "label": p.label, "profile": p.profile,
                                  "settings": dict(p.settings),
                                  "controllers": s["controllers"]})
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if figures:
        from dualpilot.viz.sweep import plot_sweep

        summary["figure"] = str(plot_sweep(summary, out / "fig_sweep.png"))
    return summary
