"""Load: several vehicles sharing one EWS and one pair of planner services (issue #7).

One Zenoh router, one EWS and one System 1 / System 2 pair serving every
vehicle id (``UAV_IDS``, services/common/fleet.py: one fire process and one
planner cache per vehicle), and per vehicle its own uavsim and supervisor
(services.launch.Fleet). Every vehicle flies the cognitive controller with
the paper's timing on its own seed, so each mission must end exactly as the
in-process mission of that seed does (``--check``). Prints, from the
supervisors' records (``latency.csv``: one row per step), the plan round trip
per step (request → reply, all plan requests of the step: Zenoh, the planner
service's queue and decode, the plan, the encode), the planners' compute time
and the part the shared planners' queues add.

    .venv/bin/python benchmarks/load_vehicles.py --vehicles 10 --speed-factor 200
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import harness  # the repository on the path: before its packages
import numpy as np

from dualpilot.mission.config import MissionConfig, Timing
from services import launch

SUCCESS_SEEDS = harness.SUCCESS_SEEDS
MISSION = MissionConfig.named("cc", timing=Timing.PAPER)  # each vehicle's, with its own seed


@dataclass
class LoadResult:
    vehicles: int
    wall_s: float
    outcomes: dict[str, launch.Outcome]
    seeds: dict[str, int]
    codes: dict[str, int]
    steps: int = 0
    round_trip_ms: list[float] = field(default_factory=list)     # per step, all requests
    per_request_ms: list[float] = field(default_factory=list)    # per step, wall / requests
    compute_ms: list[float] = field(default_factory=list)        # planners' compute per step
    queue_ms: list[float] = field(default_factory=list)          # round trip − service time
    recorded: dict[str, bool] = field(default_factory=dict)
    faults: dict[str, dict[str, int]] = field(default_factory=dict)  # summary.json, per vehicle
    failsafes: dict[str, int] = field(default_factory=dict)           # stream.json, per vehicle
    stream_max_ms: dict[str, float] = field(default_factory=dict)     # longest setpoint gap

    def stats(self) -> dict[str, dict[str, float]]:
        def s(v: list[float]) -> dict[str, float]:
            a = np.asarray(v) if v else np.zeros(1)
            return {"median_ms": round(float(np.median(a)), 2),
                    "p95_ms": round(float(np.percentile(a, 95)), 2),
                    "max_ms": round(float(a.max()), 2), "n": len(v)}
        return {"plan_round_trip_per_step": s(self.round_trip_ms),
                "plan_round_trip_per_request": s(self.per_request_ms),
                "planner_compute_per_step": s(self.compute_ms),
                "transport_and_queue_per_step": s(self.queue_ms)}


def read_latency(run_dir: Path, result: LoadResult) -> None:
    path = run_dir / "latency.csv"
    with path.open() as fh:
        for row in csv.DictReader(fh):
            n = int(row["requests"])
            wall = float(row["request_wall_s"]) * 1e3
            if n == 0:
                continue
            result.steps += 1
            result.round_trip_ms.append(wall)
            result.per_request_ms.append(wall / n)
            result.compute_ms.append(float(row["compute_s"]) * 1e3)
            result.queue_ms.append(wall - float(row["service_s"]) * 1e3)


def run_load(n_vehicles: int, out: Path, speed_factor: float = 200.0,
             seeds: tuple[int, ...] = SUCCESS_SEEDS, timeout_s: float = 600.0,
             quiet: bool = True, plan_deadline_s: str = "") -> LoadResult:
    """Fly ``n_vehicles`` missions at once through one shared EWS and planner pair
    (``plan_deadline_s``: the supervisors' PLAN_DEADLINE_S, "" their default)."""
    if not 1 <= n_vehicles <= len(seeds):
        raise ValueError(f"1..{len(seeds)} vehicles")
    uavs = [f"uav{k + 1}" for k in range(n_vehicles)]
    extra = {"supervisor": {"PLAN_DEADLINE_S": plan_deadline_s}} if plan_deadline_s else {}
    cfg = launch.StackConfig(run_dir=out, speed_factor=speed_factor, free_ports=True,
                             log_format="text", extra_env=extra)
    t0 = time.monotonic()
    with launch.Fleet(cfg, uavs) as fleet:
        mids = {}
        for k, uav in enumerate(uavs):
            v = fleet.start_vehicle(uav, seeds[k], out / uav, config=MISSION)
            mids[uav] = v.mission_id
        if not quiet:
            print(f"{n_vehicles} vehicles started; router {fleet.endpoint}", flush=True)
        outcomes = fleet.wait_end(mids, timeout_s)
        wall = time.monotonic() - t0
        codes: dict[str, int] = {}
        for uav in uavs:
            codes.update(fleet.stop_vehicle(uav))
    codes.update({p.name: int(p.popen.returncode) for p in fleet.stack.group.procs})
    result = LoadResult(n_vehicles, wall, outcomes, dict(zip(uavs, seeds, strict=False)), codes)
    for uav in uavs:
        run_dir = out / uav
        result.recorded[uav] = all((run_dir / f).is_file()
                                   for f in ("summary.json", "steps.csv", "latency.csv"))
        if (run_dir / "latency.csv").is_file():
            read_latency(run_dir, result)
        if (run_dir / "summary.json").is_file():
            stack = json.loads((run_dir / "summary.json").read_text()).get("stack", {})
            result.faults[uav] = dict(stack.get("faults", {}))
        if (run_dir / "stream.json").is_file():
            stream = json.loads((run_dir / "stream.json").read_text())
            result.failsafes[uav] = int(stream["failsafes"])
            result.stream_max_ms[uav] = float(stream["gaps"]["max_ms"])
    return result


def in_process(seed: int) -> Any:
    from dualpilot.mission.local import local_mission

    return local_mission(replace(MISSION, seed=seed)).run()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vehicles", type=int, default=10)
    p.add_argument("--speed-factor", type=float, default=200.0)
    p.add_argument("--timeout-s", type=float, default=600.0)
    p.add_argument("--out", default="", help="run directory (default: a temporary one)")
    p.add_argument("--check", action="store_true",
                   help="compare every mission with its in-process run (same seed)")
    args = p.parse_args(argv)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="load-"))
    result = run_load(args.vehicles, out.resolve(), args.speed_factor, timeout_s=args.timeout_s,
                      quiet=False)
    ok = True
    for uav, o in result.outcomes.items():
        line = (f"{uav} seed {result.seeds[uav]}: ended={o.ended} success={o.success} "
                f"steps={o.steps} recorded={result.recorded[uav]} {o.failure_cause or o.message}")
        if args.check:
            ref = in_process(result.seeds[uav])
            same = (ref.success == o.success and ref.steps == o.steps)
            line += f" | in-process success={ref.success} steps={ref.steps} same={same}"
            ok = ok and same
        ok = ok and o.ended and result.recorded[uav]
        print(line)
    bad = {n: c for n, c in result.codes.items() if c != 0}
    print(f"wall {result.wall_s:.1f} s for {result.vehicles} vehicles, {result.steps} steps; "
          f"non-zero exits: {bad or 'none'}; faults: "
          f"{ {u: f for u, f in result.faults.items() if f} or 'none'}; failsafes: "
          f"{sum(result.failsafes.values())}; longest setpoint gap: "
          f"{max(result.stream_max_ms.values(), default=0.0):.1f} ms")
    print(json.dumps(result.stats(), indent=1))
    print(f"run directory: {out}")
    return 0 if ok and not bad else 1


if __name__ == "__main__":
    sys.exit(main())
