"""Scale-out of the sweep runner: the same missions on a LocalCluster of 1, then n workers.

Efficiency = T(1) / (n · T(n)). Each run gets a fresh output directory, so
nothing is skipped. Usage (not a test; run it alone on the machine)::

    .venv/bin/python benchmarks/sweep_scaleout.py --missions 20 --workers 1,2 --profile fig-r5
"""

from __future__ import annotations

import argparse
import json
import logging
import tempfile
import time
from pathlib import Path

from distributed import Client, LocalCluster

from dualpilot.evaluation.sweep import grid_points, sweep
from dualpilot.mission.config import MissionConfig
from dualpilot.warmup import warm_up


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--missions", type=int, default=20)
    p.add_argument("--workers", default="1,2")
    p.add_argument("--profile", default="fig-r5")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    points = grid_points({}, args.profile)
    walls: dict[int, float] = {}
    for n in (int(v) for v in args.workers.split(",")):
        with tempfile.TemporaryDirectory() as tmp, LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                silence_logs=logging.ERROR) as cluster:
            with Client(cluster) as client:  # every worker compiled/loaded before the clock
                client.run(warm_up)
            t0 = time.perf_counter()
            sweep(points, args.missions, Path(tmp), MissionConfig(seed=args.seed),
                  progress=False, scheduler=cluster.scheduler_address)
            walls[n] = time.perf_counter() - t0
        print(f"{n} worker(s): {walls[n]:.1f} s", flush=True)
    base = walls[min(walls)]
    eff = {n: base * min(walls) / (n * w) for n, w in walls.items()}
    print(json.dumps({"missions": 3 * args.missions, "profile": args.profile,
                      "wall_s": walls, "efficiency": eff}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
