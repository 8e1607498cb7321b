"""Monte-Carlo evaluation of Sec. IV (Fig. r5): CC, S1 and S2 on the same random missions.

Configuration i (start, goal and fire stream) is drawn from the seed pair
(S, i) and flown by every controller, so the three see identical missions.
Rows are appended to ``results.csv`` as missions finish (flushed and synced),
so an interrupted run loses nothing already finished and a re-run with the
same directory skips what is recorded. A mission that raises becomes an error
row with its message.
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
import time
import traceback
from collections.abc import Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.spec import MissionSpec

CONTROLLERS = ("cc", "s1", "s2")
COLUMNS = [
    "mission",
    "seed",
    "controller",
    "timing",
    "success",
    "failure_cause",
    "steps",
    "mission_time_s",
    "energy",
    "switches",
    "s1_plans",
    "s2_plans",
    "planning_time_s_median",
    "planning_time_s_p95",
    "planning_time_s_total",
    "start_x",
    "start_y",
    "goal_x",
    "goal_y",
    "wall_s",
    "error",
]


def mission_seed(seed: int, index: int) -> int:
    """The seed of configuration ``index`` in a run seeded with ``seed``."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def mission_spec(seed: int, index: int) -> MissionSpec:
    """The spec of configuration ``index``: its start, goal and seed."""
    mseed = mission_seed(seed, index)
    return MissionSpec.random(np.random.default_rng(mseed), seed=mseed)


@dataclass(frozen=True)
class Task:
    index: int
    seed: int
    controller: str
    timing: str
    s2_method: str
    ignition_clearance_m: float | None = None


def run_task(task: Task) -> dict[str, object]:
    """Fly one mission; never raises (an exception becomes an error row)."""
    from dualpilot.mission.local import local_mission

    config = mission_spec(task.seed, task.index)
    row: dict[str, object] = {
        "mission": task.index,
        "seed": config.seed,
        "controller": task.controller,
        "timing": task.timing,
        "start_x": config.start[0],
        "start_y": config.start[1],
        "goal_x": config.goal.center_x,
        "goal_y": config.goal.center_y,
        "error": "",
    }
    t0 = time.perf_counter()
    try:
        result = local_mission(
            Controller(task.controller),
            config,
            timing=Timing(task.timing),
            params=MissionParams(ignition_clearance_m=task.ignition_clearance_m),
            system2_method=task.s2_method,
        ).run()
        times = result.planning_time_s["s1"] + result.planning_time_s["s2"]
        row.update(
            success=int(result.success),
            failure_cause=result.failure_cause,
            steps=result.steps,
            mission_time_s=result.mission_time_s,
            energy=round(result.energy, 6),
            switches=result.switches,
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


def read_results(path: Path) -> list[dict[str, str]]:
    if not path.exists():
        return []
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


class ResultsFile:
    """Append-only CSV; each row is flushed and fsynced as soon as it is written."""

    def __init__(self, path: Path):
        self.path = path
        new = not path.exists() or path.stat().st_size == 0
        self.fh = path.open("a", newline="")
        self.writer = csv.DictWriter(self.fh, fieldnames=COLUMNS, extrasaction="ignore")
        if new:
            self.writer.writeheader()
            self._sync()

    def _sync(self) -> None:
        self.fh.flush()
        os.fsync(self.fh.fileno())

    def append(self, row: dict[str, object]) -> None:
        self.writer.writerow(row)
        self._sync()

    def close(self) -> None:
        self.fh.close()


def _progress(done: int, total: int, t0: float, skipped: int) -> None:
    elapsed = time.perf_counter() - t0
    rate = (done - skipped) / elapsed if elapsed > 0 and done > skipped else 0.0
    left = (total - done) / rate if rate > 0 else float("nan")
    width = 30
    filled = int(width * done / max(total, 1))
    eta = f"{left / 60:5.1f} min left" if math.isfinite(left) else "   ?  min left"
    sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} {eta}")
    sys.stderr.flush()


def _run_pool(tasks: list[Task], jobs: int) -> Iterator[dict[str, object]]:
    if jobs <= 1:
        for task in tasks:
            yield run_task(task)
        return
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        pending: set[Future[dict[str, object]]] = set()
        queue = iter(tasks)
        for task in queue:
            pending.add(pool.submit(run_task, task))
            if len(pending) >= 2 * jobs:
                break
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                yield fut.result()
                nxt = next(queue, None)
                if nxt is not None:
                    pending.add(pool.submit(run_task, nxt))


def evaluate(
    missions: int,
    out: Path,
    seed: int = 0,
    timing: str = "paper",
    jobs: int | None = None,
    controllers: Iterable[str] = CONTROLLERS,
    s2_method: str = "fast",
    progress: bool = True,
    ignition_clearance_m: float | None = None,
) -> dict[str, object]:
    """Run (or resume) the evaluation in ``out``; returns the summary it writes."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.csv"
    controllers = tuple(controllers)
    recorded = read_results(path)
    for row in recorded:
        if row.get("timing") != timing:
            raise ValueError(f"{path} holds timing={row.get('timing')!r}; use another --out")
    done_keys = {(int(r["mission"]), r["controller"]) for r in recorded}
    tasks = [
        Task(i, seed, c, timing, s2_method, ignition_clearance_m)
        for i in range(missions)
        for c in controllers
        if (i, c) not in done_keys
    ]
    total = missions * len(controllers)
    skipped = total - len(tasks)
    jobs = jobs or os.cpu_count() or 1
    writer = ResultsFile(path)
    t0 = time.perf_counter()
    done = skipped
    try:
        for new_row in _run_pool(tasks, jobs):
            writer.append(new_row)
            done += 1
            if progress:
                _progress(done, total, t0, skipped)
    finally:
        writer.close()
        if progress:
            sys.stderr.write("\n")
    rows = [r for r in read_results(path) if int(r["mission"]) < missions]
    summary = summarize(rows, missions, timing, wall_s=time.perf_counter() - t0)
    summary["ignition_clearance_m"] = ignition_clearance_m
    summary["s2_method"] = s2_method
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    from dualpilot.viz.evaluation import plot_fig_r5

    plot_fig_r5(summary, out / "fig_r5.png")
    return summary


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (centre - half, centre + half)


def mean_interval(values: list[float], z: float = 1.96) -> tuple[float, float, float]:
    """Mean and its 95 % normal-approximation interval."""
    if not values:
        return (float("nan"), float("nan"), float("nan"))
    arr = np.asarray(values, dtype=float)
    m = float(arr.mean())
    half = z * float(arr.std(ddof=1)) / math.sqrt(len(arr)) if len(arr) > 1 else 0.0
    return (m, m - half, m + half)


def summarize(
    rows: list[dict[str, str]], missions: int, timing: str, wall_s: float = float("nan")
) -> dict[str, object]:
    """summary.json: per controller success rate, mission time, energy, planning time, with CIs."""
    result: dict[str, object] = {"missions": missions, "timing": timing, "wall_s": wall_s}
    ctrl: dict[str, object] = {}
    for c in CONTROLLERS:
        rs = [r for r in rows if r["controller"] == c]
        if not rs:
            continue
        ok = [r for r in rs if r["success"] == "1"]
        lo, hi = wilson_interval(len(ok), len(rs))
        t_mean, t_lo, t_hi = mean_interval([float(r["mission_time_s"]) for r in ok])
        e_mean, e_lo, e_hi = mean_interval([float(r["energy"]) for r in ok])
        plan_t = [float(r["planning_time_s_median"]) for r in rs if r["planning_time_s_median"]]
        causes: dict[str, int] = {}
        for r in rs:
            if r["success"] != "1":
                causes[r["failure_cause"]] = causes.get(r["failure_cause"], 0) + 1
        ctrl[c] = {
            "n": len(rs),
            "success_rate": len(ok) / len(rs),
            "success_rate_ci95": [lo, hi],
            "mission_time_s_mean": t_mean,
            "mission_time_s_ci95": [t_lo, t_hi],
            "energy_mean": e_mean,
            "energy_ci95": [e_lo, e_hi],
            "planning_time_s_median": float(np.median(plan_t)) if plan_t else float("nan"),
            "errors": sum(1 for r in rs if r["error"]),
            "failure_causes": causes,
        }
    result["controllers"] = ctrl
    return result
