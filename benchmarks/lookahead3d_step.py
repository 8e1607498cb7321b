"""The lookahead supervisor's planning time per step in 3-D over low fronts (docs/three_d.md §8).

``lookahead`` missions of the ``today-3d`` profile on the paper's process with fronts
U[5, 40] m tall, paper timing, seeds ``--first`` .. ``--first + --missions − 1``. Per
step, the wall time of the supervisor's choice (``LookaheadSupervisor.choose``: the known
future, the concurrent choice's check and, when it fails, the space-time search) and of
each space-time search alone; the missions' endings; the seeds whose UAV crosses a
front's footprint at least d_safe above a top that d_safe would put above 50 m (a climb
over it). Run from the tree to measure (``PYTHONPATH=.``) under the heavy lock; the
machine is shared, so the numbers are one run's.

    PYTHONPATH=. .venv/bin/python benchmarks/lookahead3d_step.py --missions 131
    PYTHONPATH=. .venv/bin/python benchmarks/lookahead3d_step.py --missions 131 \\
        --set risk_zone_height=fire
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Timing
from dualpilot.mission.result import MissionResult
from dualpilot.supervisor.lookahead import planning

LOW: tuple[tuple[str, object], ...] = (
    ("fire_height", "uniform"), ("fire_height_min_m", 5.0), ("fire_height_max_m", 40.0))


def _timed(times: list[float], method: Callable[..., Any]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return method(*args, **kwargs)
        finally:
            times.append(time.perf_counter() - t0)
    return wrapper


def _climbs(result: MissionResult) -> bool:
    d = result.spec.flight_d_safe_m
    return any(hull.distance(r.state[:2]) == 0.0 and top + d > 50.0 and r.state[2] >= top + d
               for r in result.records
               for hull, top in zip(r.snapshot.hulls, r.snapshot.hull_tops_m, strict=True))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=131)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--set", action="append", default=[], help="name=value (a float if it "
                    "parses)")
    args = ap.parse_args()
    extra: list[tuple[str, object]] = []
    for item in args.set:
        key, value = item.split("=", 1)
        try:
            extra.append((key, float(value)))
        except ValueError:
            extra.append((key, value))
    times: dict[str, list[float]] = {"choose": [], "search": []}
    cls = planning.LookaheadSupervisor
    cls.choose = _timed(times["choose"], cls.choose)  # type: ignore[method-assign]
    cls.search = _timed(times["search"], cls.search)  # type: ignore[method-assign]
    ends: Counter[str] = Counter()
    climbs = []
    for seed in range(args.first, args.first + args.missions):
        config = MissionConfig.named("lookahead", seed=seed, timing=Timing.PAPER,
                                     profile="today-3d", settings=LOW + tuple(extra))
        result = local_mission(config).run()
        ends[str(result.ending)] += 1
        if _climbs(result):
            climbs.append(seed)
    print("endings:", dict(ends))
    print("climbed over a footprint:", climbs)
    for name, values in times.items():
        v = np.array(values)
        print(f"{name}: {len(v)} calls, median {np.median(v):.4f} s, "
              f"p95 {np.percentile(v, 95):.4f} s, largest {v.max():.4f} s")


if __name__ == "__main__":
    main()
