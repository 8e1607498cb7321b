"""Run the whole stack locally: a Zenoh router and every service of docker-compose.yml as processes.

``python -m services.launch`` flies the default mission (``make run``;
dualpilot.mission.config.DEFAULT_MISSION), ``--seed 3 --controller cc --timing paper`` another
(every controller of dualpilot evaluate by its name: cc, s1, s2,
concurrent, lookahead, each with +risk; the mission's flags are those of ``dualpilot mission``);
``--vehicles 10 --scale system2=2`` a fleet of ten on a planner pool.
A split deployment runs each host's part (docs/deployment.md): ``--role ground --listen
tcp/0.0.0.0:7447`` on the ground server (the router, the EWS, System 2, until stopped),
``--role air --join tcp/GROUND:7447 --seed 7`` on the UAV's companion computer (its router,
uavsim, the supervisor and System 1; one mission).
"""

from __future__ import annotations

import argparse
import re
import signal
import sys
import time
from dataclasses import replace
from pathlib import Path

from dualpilot.mission.config_args import add_config_arguments, config_from_args
from services.common import keys
from services.common.stack_dims import check_stack_dimension
from services.launch.compose import COMPOSE, REPO
from services.launch.roles import AIR_CONCURRENT, ROLES
from services.launch.runs import report, run_fleet, run_replicas
from services.launch.stack import StackConfig, parse_scale, run_mission

_ENDPOINT = r"tcp/[^\s:/]+:\d{1,5}"


def parser() -> argparse.ArgumentParser:
    """The launcher's flags: the mission's (those of dualpilot mission and the supervisor:
    dualpilot.mission.config_args) and how to run the stack."""
    p = argparse.ArgumentParser(prog="python -m services.launch",
                                description=__doc__.splitlines()[0])
    add_config_arguments(p)
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
                        "until stopped (Ctrl-C, SIGTERM); with --role air: the ground's router, "
                        "which the air host's router joins")
    g.add_argument("--role", default="", choices=["", *ROLES],
                   help="run this host's part of a split deployment (docker-compose.<role>.yml): "
                        "air (uavsim, the supervisor, System 1 and a router joining --join; one "
                        "mission) or ground (the router on --listen, the EWS, System 2, the "
                        "viewer with --viewer; until stopped)")
    g.add_argument("--listen", default="", metavar="ENDPOINT",
                   help="with --role ground: where the router listens (default "
                        "tcp/0.0.0.0:7447, or a free port with --free-ports)")
    g.add_argument("--services", default="",
                   help="with --join or --role ground: the services to run, comma-separated "
                        "(default: --join's system2, the ground's all)")
    g.add_argument("--uav-ids", default="",
                   help="with --join or --role ground: the vehicle ids the services serve, "
                        "comma-separated (a fleet's: uav1,…,uavN; default --uav-id's, uav1)")
    g.add_argument("--uav-id", default="uav1",
                   help="the vehicle's id (one mission, or --role air): the key its services "
                        "use, so that vehicles on shared ground services stay apart")
    g.add_argument("--timeout-s", type=float, default=600.0)
    g.add_argument("--log-format", choices=["json", "text"], default="json")
    g.add_argument("--no-figures", action="store_true")
    g.add_argument("--quiet", action="store_true")
    return p


def stack_config(args: argparse.Namespace) -> StackConfig:
    """The stack to run (ValueError for a bad flag)."""
    if args.role == "air" and not any(item.partition("=")[0].strip() == "s2_unavailable"
                                      for item in args.concurrent):
        # the air host flies onboard while System 2 is behind a dead link: System 1 plans
        # (docs/deployment.md; ``--concurrent s2_unavailable=keep`` says otherwise)
        args.concurrent = [*AIR_CONCURRENT, *args.concurrent]
    mission = config_from_args(args)
    check_stack_dimension(mission)
    scale = parse_scale(args.scale)
    if not 1 <= args.vehicles <= 64:
        raise ValueError("--vehicles must be in 1..64")
    services = tuple(n.strip() for n in args.services.split(",") if n.strip())
    _check_role(args, services)
    if args.join and not re.fullmatch(_ENDPOINT, args.join):
        raise ValueError(f"--join takes a Zenoh TCP endpoint tcp/HOST:PORT, got {args.join!r}")
    run_id = f"{time.strftime('%Y%m%d-%H%M%S')}-{mission.controller_name}-s{mission.seed}"
    run_dir = (Path(args.out) if args.out else REPO / "runs" / run_id).resolve()
    mission_id = mission.mission_id or re.sub(r"[^A-Za-z0-9_\-]", "-", run_dir.name)[:64]
    return StackConfig(run_dir=run_dir, mission=replace(mission, mission_id=mission_id),
                       uav_id=keys.check_id(args.uav_id),
                       speed_factor=args.speed_factor, waypoints=args.waypoints,
                       free_ports=args.free_ports, log_format=args.log_format,
                       tls=args.tls or args.tls_dir is not None,
                       tls_dir=args.tls_dir.resolve() if args.tls_dir else None,
                       scale=scale, profiles=("viewer",) if args.viewer else (),
                       join=args.join, role=args.role, listen=args.listen,
                       services=services or (("system2",) if args.join and not args.role
                                             else ()))


def _check_role(args: argparse.Namespace, services: tuple[str, ...]) -> None:
    """The flags that go with ``--role`` and ``--join`` (ValueError)."""
    hosts = bool(args.join and not args.role) or args.role == "ground"
    if (services or args.uav_ids) and not hosts:
        raise ValueError("--services and --uav-ids go with --join or --role ground")
    if args.role == "air" and not args.join:
        raise ValueError("--role air needs --join tcp/GROUND:PORT, the ground's router")
    if args.role == "ground" and args.join:
        raise ValueError("--role ground runs the router the air host joins: no --join")
    if args.listen and args.role != "ground":
        raise ValueError("--listen goes with --role ground")
    if args.listen and not re.fullmatch(_ENDPOINT, args.listen):
        raise ValueError(f"--listen takes tcp/HOST:PORT, got {args.listen!r}")
    if args.role == "air" and args.viewer:
        raise ValueError("the live view runs on the ground host: --role ground --viewer")
    if args.role and args.vehicles > 1:
        raise ValueError("--vehicles goes with the whole stack on one host, not --role")


def _terminated(signum: int, frame: object) -> None:
    """SIGTERM (``kill``, ``timeout``) stops the stack as Ctrl-C does: every service too."""
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: list[str] | None = None) -> int:
    signal.signal(signal.SIGTERM, _terminated)
    # SIGINT too, explicitly: a launcher started by a background job of a shell inherits
    # SIGINT ignored, and Python then installs no handler (it would not stop, nor its services)
    signal.signal(signal.SIGINT, _terminated)
    p = parser()
    args = p.parse_args(argv)
    try:
        cfg = stack_config(args)
    except ValueError as err:
        p.error(str(err))
    if cfg.role == "ground" or (cfg.join and not cfg.role):
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


if __name__ == "__main__":
    sys.exit(main())
