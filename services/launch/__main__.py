"""Run the whole stack locally: a Zenoh router and every service of docker-compose.yml as processes.

``python -m services.launch --seed 7 --speed-factor 20 --controller cc --timing paper``
flies one mission (every controller of dualpilot evaluate by its name: cc, s1, s2,
concurrent, lookahead, each with +risk; the mission's flags are those of ``dualpilot mission``);
``--vehicles 10 --scale system2=2`` a fleet of ten on a planner pool.
"""

from __future__ import annotations

import argparse
import json
import re
import signal
import sys
import time
from dataclasses import replace
from pathlib import Path

from dualpilot.mission.config_args import add_config_arguments, config_from_args
from services.launch.compose import COMPOSE, REPO
from services.launch.fleet import Fleet
from services.launch.stack import Outcome, Stack, StackConfig, parse_scale, run_mission


def parser() -> argparse.ArgumentParser:
    """The launcher's flags: the mission's (those of dualpilot mission and the supervisor:
    dualpilot.mission.config_args) and how to run the stack."""
    p = argparse.ArgumentParser(prog="python -m services.launch",
                                description=__doc__.splitlines()[0])
    add_config_arguments(p, seed=7)
    g = p.add_argument_group("the stack")
    g.add_argument("--speed-factor", type=float, default=20.0,
                   help="simulated s per wall s (0 or inf: unpaced)")
    g.add_argument("--waypoints", default="", help="System 1 operator waypoints 'e1,n1;e2,n2'")
    g.add_argument("--out", default="",
                   help="run directory (default runs/<time>-<controller>-s<seed>)")
    g.add_argument("--compose", type=Path, default=COMPOSE)
    g.add_argument("--free-ports", action="store_true",
                   help="free local ports instead of the published 7447 / 14550")
    g.add_argument("--tls", action="store_true",
                   help="mutual TLS and the router's access control (ZENOH_TLS_DIR); "
                        "certificates made in <out>/tls unless --tls-dir is given")
    g.add_argument("--tls-dir", type=Path, default=None,
                   help="certificates of python -m services.certs (implies --tls)")
    g.add_argument("--vehicles", type=int, default=1,
                   help="fly a fleet: N vehicles (seeds --seed .. --seed + N - 1) sharing the "
                        "EWS and planners, hosted by one uavsim and one supervisor process; "
                        "each vehicle's records in <out>/uav<k>/")
    g.add_argument("--scale", action="append", default=[], metavar="SERVICE=N",
                   help="run N replicas of a planner service (a pool: system1, system2), as "
                        "docker compose up --scale; repeatable")
    g.add_argument("--viewer", action="store_true",
                   help="also run the live view (services/viewer, compose profile 'viewer'): "
                        "a web page on http://127.0.0.1:8766/ and Foxglove WebSocket on "
                        "ws://127.0.0.1:8765 (or the free ports printed)")
    g.add_argument("--join", default="", metavar="ENDPOINT",
                   help="join the router of a stack that runs elsewhere (tcp/HOST:7447) and run "
                        "only --services there, e.g. more planner replicas on another machine, "
                        "until stopped (Ctrl-C, SIGTERM)")
    g.add_argument("--services", default="",
                   help="with --join: the services to run, comma-separated (default system2)")
    g.add_argument("--uav-ids", default="",
                   help="with --join: the vehicle ids the services serve, comma-separated "
                        "(a fleet's: uav1,…,uavN; default --uav-id's, uav1)")
    g.add_argument("--timeout-s", type=float, default=600.0)
    g.add_argument("--log-format", choices=["json", "text"], default="json")
    g.add_argument("--no-figures", action="store_true")
    g.add_argument("--quiet", action="store_true")
    return p


def stack_config(args: argparse.Namespace) -> StackConfig:
    """The stack to run (ValueError for a bad flag)."""
    mission = config_from_args(args)
    scale = parse_scale(args.scale)
    if not 1 <= args.vehicles <= 64:
        raise ValueError("--vehicles must be in 1..64")
    services = tuple(n.strip() for n in args.services.split(",") if n.strip())
    if (services or args.uav_ids) and not args.join:
        raise ValueError("--services and --uav-ids go with --join")
    if args.join and not re.fullmatch(r"tcp/[^\s:/]+:\d{1,5}", args.join):
        raise ValueError(f"--join takes a Zenoh TCP endpoint tcp/HOST:PORT, got {args.join!r}")
    run_id = f"{time.strftime('%Y%m%d-%H%M%S')}-{mission.controller_name}-s{mission.seed}"
    run_dir = (Path(args.out) if args.out else REPO / "runs" / run_id).resolve()
    mission_id = mission.mission_id or re.sub(r"[^A-Za-z0-9_\-]", "-", run_dir.name)[:64]
    return StackConfig(run_dir=run_dir, mission=replace(mission, mission_id=mission_id),
                       speed_factor=args.speed_factor, waypoints=args.waypoints,
                       free_ports=args.free_ports, log_format=args.log_format,
                       tls=args.tls or args.tls_dir is not None,
                       tls_dir=args.tls_dir.resolve() if args.tls_dir else None,
                       scale=scale, profiles=("viewer",) if args.viewer else (),
                       join=args.join, services=services or (("system2",) if args.join else ()))


def report(cfg: StackConfig, outcome: Outcome, codes: dict[str, int], wall: float) -> int:
    """Print the mission's summary and how the services stopped; the exit code."""
    summary_path = cfg.run_dir / "summary.json"
    if summary_path.is_file():
        s = json.loads(summary_path.read_text())
        keep = ("controller", "seed", "timing", "success", "failure_cause", "steps",
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


def _terminated(signum: int, frame: object) -> None:
    """SIGTERM (``kill``, ``timeout``) stops the stack as Ctrl-C does: every service too."""
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: list[str] | None = None) -> int:
    signal.signal(signal.SIGTERM, _terminated)
    p = parser()
    args = p.parse_args(argv)
    try:
        cfg = stack_config(args)
    except ValueError as err:
        p.error(str(err))
    if cfg.join:
        try:
            return run_replicas(cfg, args.uav_ids)
        except ValueError as err:
            p.error(str(err))
    if args.vehicles > 1:
        try:
            return run_fleet(cfg, args.vehicles, args.timeout_s, args.compose)
        except KeyboardInterrupt:
            print("interrupted: the fleet's services are stopped", file=sys.stderr)
            return 130
    t0 = time.perf_counter()
    try:
        outcome, codes = run_mission(cfg, args.timeout_s, not args.no_figures, args.quiet,
                                     args.compose)
    except ValueError as err:
        print(f"launch: error: {err}", file=sys.stderr)
        return 2
    return report(cfg, outcome, codes, time.perf_counter() - t0)


def run_replicas(cfg: StackConfig, uav_ids: str) -> int:
    """Services of a stack that runs elsewhere, on its router only (``--join``): they serve
    ``uav_ids`` until Ctrl-C or SIGTERM (0), or until one of them exits (1)."""
    from services.common.fleet import uav_ids as checked_ids

    ids = ",".join(checked_ids(uav_ids, cfg.uav_id))
    cfg = replace(cfg, extra_env={name: {"UAV_IDS": ids} for name in cfg.services})
    cfg.run_dir.mkdir(parents=True, exist_ok=True)
    with Stack(cfg) as stack:
        names = ", ".join(p.name for p in stack.group.procs)
        print(f"joined {cfg.join}: {names} serving {ids}; logs in {stack.logs}/", flush=True)
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


if __name__ == "__main__":
    sys.exit(main())
