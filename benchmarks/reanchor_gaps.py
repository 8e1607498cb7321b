"""How far the UAV is from where the concurrent supervisor's plans expected it (docs/plant.md).

    flock /tmp/dualpilot-heavy.lock .venv/bin/python benchmarks/reanchor_gaps.py \\
        --missions 20 --controllers lookahead+risk --set plant=multirotor --winds 10 \\
        --set turbulence=moderate --set gps_sigma_m=1.5

Flies configurations 0..N−1 of ``--seed`` in this process (paper timing, ``--profile``, the
``--set`` readings, ``--concurrent`` parameters), by each of ``--controllers`` and at each
mean wind of ``--winds`` (``wind_speed_mps``; none: the readings'), and records, pooled,
every call of the concurrent supervisor's re-anchoring
(:func:`dualpilot.supervisor.concurrent.rule.reanchor`, wrapped here to record its arguments
and its answer; nothing else changes): for the System 2 plans
due (``due``) and for the flown plan's remainder (``kept``), the distance (m) and the speed
difference (m/s) between the UAV's measured state and the plan's start, and whether the plan
was re-anchored. Prints the missions' success, mean time of the completed ones, steps flown
per system, the answers of the records (``s2:stale_start`` among them) and the gaps'
percentiles 10 / 50 / 90 / 99 / 99.9 / max.
"""

from __future__ import annotations

import argparse
import collections
import json
from collections.abc import Callable
from typing import Any

import harness  # noqa: F401 - the repository on the path
import numpy as np

import dualpilot.supervisor.concurrent.planning as planning
from dualpilot.evaluation.missions import Task
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.config_args import concurrent_params
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Timing

#: (kind, position gap m, velocity gap m/s, re-anchored)
Gap = tuple[str, float, float, bool]


def record(gaps: list[Gap]) -> None:
    """Wrap the supervisor's ``reanchor`` and its two callers to append to ``gaps``."""
    kind = {"now": ""}
    reanchor = planning.reanchor

    def recorded(plan: Any, state: Any, params: Any, spec: Any) -> Any:
        n = spec.dynamics.dim
        d = np.asarray(state, dtype=float) - plan.states[0]
        out = reanchor(plan, state, params, spec)
        gaps.append((kind["now"], float(np.linalg.norm(d[:n])), float(np.linalg.norm(d[n:])),
                     out is not None))
        return out

    def tagged(method: Callable[..., Any], name: str) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            kind["now"] = name
            try:
                return method(*args, **kwargs)
            finally:
                kind["now"] = ""
        return call

    planning.reanchor = recorded  # type: ignore[assignment]
    cls = planning.ConcurrentSupervisor
    cls._collect = tagged(cls._collect, "due")  # type: ignore[method-assign]
    cls._kept = tagged(cls._kept, "kept")  # type: ignore[method-assign]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--controllers", default="lookahead+risk")
    ap.add_argument("--winds", default="", help="mean winds (m/s), comma-separated")
    ap.add_argument("--profile", default="today")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--concurrent", action="append", default=[], metavar="NAME=VALUE")
    args = ap.parse_args()
    gaps: list[Gap] = []
    record(gaps)
    settings = tuple(item.split("=", 1) for item in args.set)
    base = MissionConfig(timing=Timing.PAPER, profile=args.profile, settings=settings,
                         concurrent=concurrent_params(args.concurrent))
    winds = [base] if not args.winds else [
        base.with_settings({"wind_speed_mps": w}) for w in args.winds.split(",")]
    answers: collections.Counter[str] = collections.Counter()
    systems: collections.Counter[int] = collections.Counter()
    times: list[float] = []
    flights = [(i, name, config) for config in winds for name in args.controllers.split(",")
               for i in range(args.missions)]
    for i, name, config in flights:
        result = local_mission(Task.of(i, args.seed, name, config).mission()).run()
        if result.success:
            times.append(result.mission_time_s)
        for rec in result.records:
            systems[rec.system] += 1
            answers.update(f"s{a.system}:{a.status.value}" for a in rec.answers)
    print(json.dumps({"missions": len(flights), "success": len(times),
                      "mean_time_s": round(float(np.mean(times)), 2) if times else None,
                      "steps_by_system": dict(sorted(systems.items())),
                      "answers": dict(answers.most_common())}))
    for kind in ("due", "kept"):
        rows = np.array([(p, v, ok) for k, p, v, ok in gaps if k == kind]).reshape(-1, 3)
        if not len(rows):
            continue
        q = [10, 50, 90, 99, 99.9, 100]
        print(f"{kind}: {len(rows)} plans, {int(rows[:, 2].sum())} re-anchored; position gap "
              f"(m) {np.round(np.percentile(rows[:, 0], q), 3).tolist()}; velocity gap (m/s) "
              f"{np.round(np.percentile(rows[:, 1], q), 3).tolist()} "
              "(p10, p50, p90, p99, p99.9, max)")


if __name__ == "__main__":
    main()
