"""A slice of the 20-point sweep in one process: its time, and its rows to compare two versions.

Flies missions FIRST..LAST-1 of every point of a sweep file for each controller,
one after the other in this process (no Dask: the missions alone are timed, after
the kernels are loaded), prints the seconds and, with ``--rows``, writes every
row without its measured times (wall and compute) as JSON. ``--compare`` reads
such a file and says how many rows are identical, which is how a speed-up shows
that it changed no plan. Run it alone on the machine; alternate two versions
(``PYTHONPATH=<other checkout>``) to compare their times::

    .venv/bin/python benchmarks/sweep_sample.py --missions 10:13 --rows runs/sample_new.json
    PYTHONPATH=../old .venv/bin/python benchmarks/sweep_sample.py --missions 10:13 \\
        --rows runs/sample_old.json --compare runs/sample_new.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from dualpilot.evaluation.missions import CONTROLLERS, MEASURED_COLUMNS, Task, run_task
from dualpilot.evaluation.sweep import grid_points, load_grid
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.params import Timing
from dualpilot.warmup import warm_up


def main() -> int:
    here = Path(__file__).resolve().parent
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--grid", type=Path, default=here / "sweep_fig_r5.yaml")
    p.add_argument("--missions", default="10:13", help="FIRST:LAST (LAST excluded)")
    p.add_argument("--rows", type=Path, help="write the rows (without measured times) here")
    p.add_argument("--compare", type=Path, help="rows of another run to compare with")
    args = p.parse_args()
    first, last = (int(v) for v in args.missions.split(":"))
    doc = load_grid(args.grid)
    points = grid_points(doc.get("grid") or {}, doc.get("profile", "today"),
                         doc.get("points") or ())
    controllers = doc.get("controllers", CONTROLLERS)
    base = MissionConfig(timing=Timing(doc.get("timing", "paper")))
    tasks = [Task.of(i, int(doc.get("seed", 0)), c, pt.config(base), point=pt.index,
                     label=pt.label)
             for i in range(first, last) for pt in points for c in controllers]
    warm_up()
    t0 = time.perf_counter()
    rows = [run_task(t) for t in tasks]
    wall = time.perf_counter() - t0
    kept = [{k: str(v) for k, v in r.items() if k not in MEASURED_COLUMNS} for r in rows]
    print(f"{len(tasks)} missions in {wall:.2f} s ({1000 * wall / len(tasks):.1f} ms a mission)")
    if args.rows:
        args.rows.parent.mkdir(parents=True, exist_ok=True)
        args.rows.write_text(json.dumps(kept))
    if args.compare:
        other = json.loads(args.compare.read_text())
        same = sum(a == b for a, b in zip(kept, other, strict=False))
        print(f"{same}/{len(kept)} rows identical to {args.compare}"
              + ("" if len(other) == len(kept) else f" (it has {len(other)} rows)"))
        return 0 if same == len(kept) == len(other) else 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
