"""The launcher's runs: one mission followed to its end, a fleet, or replicas joining a stack.

:func:`report` prints one mission's summary (services/launch/stack.py
``run_mission`` flies it); :func:`run_fleet` flies several vehicles through the
shared services; :func:`run_replicas` runs services of a stack that runs
elsewhere (``--join``).
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace
from pathlib import Path

from services.launch.fleet import Fleet
from services.launch.stack import Outcome, Stack, StackConfig


def report(cfg: StackConfig, outcome: Outcome, codes: dict[str, int], wall: float) -> int:
    """Print the mission's summary and how the services stopped; the exit code."""
    summary_path = cfg.run_dir / "summary.json"
    if summary_path.is_file():
        s = json.loads(summary_path.read_text())
        keep = ("controller_name", "controller", "seed", "timing", "success", "ending", "steps",
                "mission_time_s", "energy", "switches")
        print(json.dumps({k: s.get(k) for k in keep}))
        overhead = s.get("stack", {}).get("setpoint_overhead", {})
        if overhead:
            print(f"tick→setpoint overhead: median {overhead['median_ms']:.2f} ms, "
                  f"p99 {overhead['p99_ms']:.2f} ms")
    bad = {n: c for n, c in codes.items() if c != 0}
    print(f"wall time {wall:.1f} s; services stopped "
          f"({'all cleanly' if not bad else f'non-zero exits: {bad}'}); results in {cfg.run_dir}/")
    if not outcome.ended:
        print(f"launch: mission did not end: {outcome.message}", file=sys.stderr)
        return 1
    return 0


def run_replicas(cfg: StackConfig, uav_ids: str) -> int:
    """Services of a stack that runs elsewhere, on its router only (``--join``), or the
    ground host's part (``--role ground``: its router too): they serve ``uav_ids`` until
    Ctrl-C or SIGTERM (0), or until one of them exits (1)."""
    from services.common.fleet import uav_ids as checked_ids

    ids = ",".join(checked_ids(uav_ids, cfg.uav_id))
    names = cfg.services or tuple(Stack(cfg).service_names())
    cfg = replace(cfg, extra_env={name: {"UAV_IDS": ids} for name in names})
    cfg.run_dir.mkdir(parents=True, exist_ok=True)
    with Stack(cfg) as stack:
        names_up = ", ".join(p.name for p in stack.group.procs)
        where = (f"ground: router on {stack.router_listen}" if cfg.role == "ground"
                 else f"joined {cfg.join}")
        print(f"{where}: {names_up} serving {ids}; logs in {stack.logs}/", flush=True)
        try:
            while not (dead := stack.group.dead()):
                time.sleep(0.5)
        except KeyboardInterrupt:
            print("stopping", flush=True)
            return 0
        print(f"launch: {', '.join(p.name for p in dead)} exited; stopping the others",
              file=sys.stderr, flush=True)
        return 1


def run_fleet(cfg: StackConfig, n: int, timeout_s: float, compose: Path) -> int:
    """``n`` vehicles through the shared services, hosted; prints one line per vehicle."""
    uavs = [f"uav{k + 1}" for k in range(n)]
    cfg.run_dir.mkdir(parents=True, exist_ok=True)
    cfg = replace(cfg, uav_id=uavs[0])
    env = {"START_STAGGER_S": "0.5"}
    t0 = time.perf_counter()
    with Fleet(replace(cfg, run_dir=cfg.run_dir / "shared"), uavs, compose) as fleet:
        print(f"fleet: {n} vehicles, router {fleet.endpoint}, replicas "
              f"{cfg.scale or 'one of each'}; records in {cfg.run_dir}/<uav>/", flush=True)
        if fleet.stack.web_url():
            print(f"live view: {fleet.stack.web_url()} in a browser, "
                  f"{fleet.stack.viewer_url()} in Foxglove (every vehicle side by side)",
                  flush=True)
        seed = cfg.mission.seed
        vehicles = fleet.start_hosted(uavs, [seed + k for k in range(n)], cfg.run_dir,
                                      env=env, tag=cfg.mission_id, config=cfg.mission)
        outcomes = fleet.wait_end({v.uav_id: v.mission_id for v in vehicles}, timeout_s)
        codes = fleet.stop_vehicle(uavs[0])
    for v in vehicles:
        o = outcomes[v.uav_id]
        print(f"{v.uav_id} seed {v.seed}: ended={o.ended} success={o.success} steps={o.steps} "
              f"{o.failure_cause or o.message}")
    bad = {name: c for name, c in codes.items() if c not in (0, 3)}  # 3: a mission failed
    print(f"wall time {time.perf_counter() - t0:.1f} s; vehicle hosts "
          f"{'stopped cleanly' if not bad else f'non-zero exits: {bad}'}")
    return 0 if all(o.ended for o in outcomes.values()) and not bad else 1
