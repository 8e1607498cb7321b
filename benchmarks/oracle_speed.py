"""The oracle's cost per mission, on the Dask sweep's runner, for each reading of the tables.

For every reading, the oracle's verdicts on configurations 0..N−1 of ``--seed`` are
computed as ``dualpilot evaluate --controllers oracle`` computes them: one Dask task a
mission on a ``LocalCluster`` of ``--jobs`` single-threaded workers
(dualpilot/evaluation/runner.py). Per mission, the time its task took inside the worker
(``wall_s``: the fire future, certificate, search and the witness's flight); per reading
the median, p90 and largest, the verdicts and the batch's wall time. ``--dim 3`` judges
the same missions in 3-D and ``--set NAME=VALUE`` adds a reading's setting to every one
(``--set fire_height=above-ceiling`` on a scenario: fronts taller than any UAV flies, the
3-D missions the oracle judges, dualpilot/oracle/reduction.py). ::

    .venv/bin/python benchmarks/oracle_speed.py --missions 200 --jobs 2 --out runs/oracle_speed.json
    .venv/bin/python benchmarks/oracle_speed.py --missions 200 --jobs 2 --dim 3 \
        --readings today,grass-15 --set fire_height=above-ceiling
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

import harness
import numpy as np

from dualpilot.evaluation.missions import ORACLE, Task
from dualpilot.evaluation.runner import execute
from dualpilot.mission.config import MissionConfig

READINGS = {"today": ("today", ()), "fig-r5": ("fig-r5", ()), "literal": ("literal", ()),
            "grass-5": ("today", (("scenario", "grass-5"),)),
            "grass-15": ("today", (("scenario", "grass-15"),)),
            "shrub": ("today", (("scenario", "shrub"),))}


def measure(name: str, missions: int, seed: int, jobs: int,
            extra: tuple[tuple[str, str], ...] = ()) -> dict[str, object]:
    profile, settings = READINGS[name]
    base = MissionConfig(profile=profile, settings=settings + extra)
    tasks = [Task.of(i, seed, ORACLE, base) for i in range(missions)]
    t0 = time.perf_counter()
    rows = list(execute(tasks, jobs))
    batch = time.perf_counter() - t0
    walls = [float(str(r["wall_s"])) for r in rows]
    verdicts = Counter("feasible" if r["success"] == 1 else str(r["failure_cause"])
                       for r in rows)
    return {"reading": name, "settings": dict(extra), "missions": missions, "jobs": jobs,
            "wall_s_per_mission": harness.quantiles(walls, (50, 90), 3),
            "mean_s": round(float(np.mean(walls)), 3), "batch_wall_s": round(batch, 1),
            "verdicts": dict(verdicts), "errors": sum(1 for r in rows if r.get("error"))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--readings", default=",".join(READINGS))
    ap.add_argument("--dim", type=int, choices=(2, 3), default=2)
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a reading's setting for every mission (repeatable)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    extra: tuple[tuple[str, str], ...] = (("dim", "3"),) if args.dim == 3 else ()
    for item in args.set:
        name, _, value = item.partition("=")
        extra += ((name, value),)
    results = [measure(name, args.missions, args.seed, args.jobs, extra)
               for name in args.readings.split(",")]
    harness.emit({"oracle_speed": results}, args.out)


if __name__ == "__main__":
    main()
