"""The supervisor's settings: flags whose defaults come from the environment, read once.

The mission's configuration takes the flags every entry point shares
(:func:`dualpilot.mission.config_args.add_config_arguments`); the environment's
mission names (``CONTROLLER``, ``MISSION_SEED``, ``READINGS_PROFILE``, …:
services/common/mission_env.py) are read as flags before the command line's,
so a flag wins. This is where a stack's mission configuration is built, once;
the planners, the EWS and uavsim receive it on the wire. The rest say how this
process talks to the stack and the vehicles (plan deadlines, the setpoint
stream, MAVLink signing, the fleet it serves), each flag with its own
environment variable. :func:`parse` checks them all and returns
:class:`Options`; a bad value is an argparse error, before anything is started.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.config_args import add_config_arguments, config_from_args
from dualpilot.model.dynamics import Array
from services.common import cli as common_cli
from services.common import fleet, keys, mav, mission_env
from services.common.clock import SimClock
from services.common.convert.vehicle import parse_waypoints
from services.common.stack_dims import check_stack_dimension

from .ports import StackParams
from .ports.params import AirLinkParams

#: exit codes with ``--exit-after-mission`` (``docker compose up --exit-code-from supervisor``)
EXIT_SUCCESS, EXIT_ABORTED, EXIT_FAILED = 0, 1, 3


@dataclass(frozen=True)
class LinkOptions:
    """How the supervisor talks MAVLink to its vehicle."""

    rate_hz: float = 20.0
    stream: str = "process"
    sysid: int = 1
    altitude_m: float = 50.0
    key: bytes | None = None
    lost_after_s: float = 3.0


@dataclass(frozen=True)
class Options:
    """Everything the supervisor process was told: per vehicle, :meth:`config` and :meth:`out`."""

    settings: common_cli.Settings
    mission: MissionConfig  # the fleet's first vehicle's; vehicle k: :meth:`config`
    stack: StackParams
    link: LinkOptions
    uavs: tuple[str, ...]
    seeds: tuple[int, ...]
    mission_ids: tuple[str, ...]
    out: str  # the run directory ({uav}: the vehicle id), "" none
    waypoints: Array | None
    stagger_s: float
    exit_after_mission: bool
    wait_services_s: float

    def config(self, k: int) -> MissionConfig:
        """Vehicle k's configuration: its seed, mission id and vehicle id."""
        return replace(self.mission, seed=self.seeds[k], mission_id=self.mission_ids[k],
                       uav_id=self.uavs[k])

    def run_dir(self, k: int) -> Path | None:
        return Path(fleet.per_vehicle(self.out, self.uavs[k])) if self.out else None

    def mavlink_url(self, k: int) -> str:
        return fleet.instance_url(self.settings.mavlink_url, k)


def _add_link_arguments(p: argparse.ArgumentParser) -> None:
    """The air–ground link's flags (a split deployment, docs/deployment.md)."""
    env = common_cli.env
    g = p.add_argument_group("the air–ground link (the supervisor on the UAV)")
    g.add_argument("--link-services", default=env("LINK_SERVICES", ""),
                   help="the services behind the air–ground link, comma-separated (a split "
                        "deployment, docs/deployment.md: ews,system2): their exchanges name "
                        "link_degraded and link_lost in the record; empty: all on this host "
                        "[LINK_SERVICES]")
    g.add_argument("--link-rtt-s", type=float, default=env("LINK_RTT_S", "0"),
                   help="the round trip the air–ground link adds (wall s): added to every "
                        "wait for a service behind it (plan deadlines, forecast and paced fire "
                        "waits) [LINK_RTT_S]")
    g.add_argument("--link-degraded-rtt-s", type=float,
                   default=env("LINK_DEGRADED_RTT_S", "1"),
                   help="a round trip across the link longer than this (wall s) is "
                        "link_degraded [LINK_DEGRADED_RTT_S]")
    g.add_argument("--fire-deadline-periods", type=float,
                   default=env("FIRE_DEADLINE_PERIODS", "0"),
                   help="at a speed factor > 0, a fire advance waits its pacing plus this many "
                        "control periods ΔT (and at most --fire-timeout-s); 0: "
                        "--fire-timeout-s alone [FIRE_DEADLINE_PERIODS]")


def _add_stack_arguments(p: argparse.ArgumentParser) -> None:
    env = common_cli.env
    g = p.add_argument_group("the supervisor process")
    g.add_argument("--seeds", default=env("MISSION_SEEDS", ""),
                   help="with --uav-ids: each vehicle's seed, comma-separated (default: --seed "
                        "+ k) [MISSION_SEEDS]")
    g.add_argument("--waypoints", default=env("OPERATOR_WAYPOINTS", ""),
                   help="System 1's operator waypoints 'e1,n1;e2,n2' [OPERATOR_WAYPOINTS]")
    g.add_argument("--out", default=env("RUN_DIR", ""),
                   help="write summary.json, steps.csv, trace.json, latency.csv here; {uav} is "
                        "the vehicle id [RUN_DIR]")
    fleet.add_argument(g, "one companion process for several vehicles: instance k on the "
                          "MAVLink URL's port + k, system id --sysid + k")
    g.add_argument("--start-stagger-s", type=float, default=env("START_STAGGER_S", "0"),
                   help="with --uav-ids: vehicle k takes off k times this many wall seconds "
                        "after the first [START_STAGGER_S]")
    g.add_argument("--exit-after-mission", action="store_true",
                   default=env("EXIT_AFTER_MISSION", "0") == "1",
                   help=f"exit when the mission ends: {EXIT_SUCCESS} success, {EXIT_ABORTED} "
                        f"aborted (or could not start), {EXIT_FAILED} ended in failure "
                        "[EXIT_AFTER_MISSION=1]")
    g.add_argument("--wait-services-s", type=float, default=env("WAIT_SERVICES_S", "120"),
                   help="how long to wait for the other services [WAIT_SERVICES_S]")
    g.add_argument("--plan-deadline-s", default=env("PLAN_DEADLINE_S", ""),
                   help="'s1,s2' wall seconds a plan request waits [PLAN_DEADLINE_S]")
    g.add_argument("--fire-timeout-s", type=float, default=env("FIRE_TIMEOUT_S", "30"),
                   help="how long a fire command to the EWS waits (wall s); past it the fire "
                        "data ages (fire_stale) [FIRE_TIMEOUT_S]")
    g.add_argument("--forecast-timeout-s", type=float, default=env("FORECAST_TIMEOUT_S", "10"),
                   help="how long a risk-aware step waits for the EWS's forecast (wall s); "
                        "past it the step flies without (forecast_stale) [FORECAST_TIMEOUT_S]")
    g.add_argument("--forecast-deadline-periods", type=float,
                   default=env("FORECAST_DEADLINE_PERIODS", "0.5"),
                   help="at a speed factor > 0, a step waits for the forecast at most this many "
                        "control periods ΔT of wall time, as the plan deadlines (and at most "
                        "--forecast-timeout-s) [FORECAST_DEADLINE_PERIODS]")
    g.add_argument("--forecast-by-reference", default=env("FORECAST_BY_REFERENCE", "system2"),
                   help="the planners whose risk-aware plan requests name their forecast (its "
                        "fire revision and digest) instead of carrying it: they take it from "
                        "the EWS on their own side of the link; comma-separated system1, "
                        "system2, or none [FORECAST_BY_REFERENCE]")
    g.add_argument("--setpoint-rate-hz", type=float, default=env("SETPOINT_RATE_HZ", "20"),
                   help="setpoint stream rate, >= 10 [SETPOINT_RATE_HZ]")
    g.add_argument("--setpoint-stream", default=env("SETPOINT_STREAM", "process"),
                   choices=["process", "thread"],
                   help="who sends the setpoint stream: a process of its own with raised "
                        "priority, or a thread of the supervisor [SETPOINT_STREAM]")
    g.add_argument("--sysid", type=int, default=env("MAV_SYSID", "1"),
                   help="the vehicle's MAVLink system id [MAV_SYSID]")
    g.add_argument("--altitude-m", type=float, default=env("UAV_ALTITUDE_M", "50"),
                   help="[UAV_ALTITUDE_M]")
    g.add_argument("--signing-passphrase", default=env("MAVLINK_SIGNING_PASSPHRASE", ""),
                   help="sign the offboard link [MAVLINK_SIGNING_PASSPHRASE]")
    g.add_argument("--signing-key-file", default=env("MAVLINK_SIGNING_KEY_FILE", ""),
                   help="sign the offboard link: 32 raw bytes, or a passphrase (sha256, as "
                        "MAVProxy) [MAVLINK_SIGNING_KEY_FILE]")
    g.add_argument("--vehicle-lost-s", type=float, default=env("VEHICLE_LOST_S", "3"),
                   help="pause the mission after this long without a vehicle heartbeat "
                        "[VEHICLE_LOST_S]")


def parser(doc: str) -> argparse.ArgumentParser:
    p = common_cli.parser("supervisor", doc, mavlink_default="udpin:127.0.0.1:14540")
    add_config_arguments(p)
    _add_stack_arguments(p)
    _add_link_arguments(p)
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = mission_env.help_text()
    return p


def _stack_params(args: argparse.Namespace) -> StackParams:
    if not (args.forecast_timeout_s > 0 and args.fire_timeout_s > 0
            and args.forecast_deadline_periods > 0):
        raise ValueError("--fire-timeout-s, --forecast-timeout-s and "
                         "--forecast-deadline-periods must be positive")
    base = StackParams(altitude_m=args.altitude_m, fire_timeout_s=args.fire_timeout_s,
                       fire_deadline_periods=args.fire_deadline_periods,
                       link=_link_params(args),
                       forecast_timeout_s=args.forecast_timeout_s,
                       forecast_deadline_periods=args.forecast_deadline_periods,
                       forecast_by_reference=systems_of(args.forecast_by_reference,
                                                        "--forecast-by-reference"))
    if not args.plan_deadline_s:  # default: tied to the control period (plan_deadline_periods)
        return base
    deadlines = tuple(float(v) for v in args.plan_deadline_s.split(","))
    if len(deadlines) != 2 or min(deadlines) <= 0:
        raise ValueError("--plan-deadline-s must be two positive numbers 's1,s2'")
    return replace(base, plan_deadline_s=(deadlines[0], deadlines[1]))


def _link_params(args: argparse.Namespace) -> AirLinkParams:
    """The air–ground link's flags (ValueError: an unknown service, a negative time)."""
    names = frozenset(n.strip() for n in args.link_services.split(",") if n.strip())
    bad = sorted(names - {"ews", "system1", "system2"})
    if bad:
        raise ValueError(f"--link-services takes ews, system1, system2, got {', '.join(bad)}")
    if not (args.link_rtt_s >= 0 and args.link_degraded_rtt_s > 0
            and args.fire_deadline_periods >= 0):
        raise ValueError("--link-rtt-s and --fire-deadline-periods must be >= 0, "
                         "--link-degraded-rtt-s positive")
    return AirLinkParams(names, args.link_rtt_s, args.link_degraded_rtt_s)


def systems_of(text: str, flag: str) -> frozenset[int]:
    """``"system1,system2"`` → {1, 2}; ``"none"`` or "" → {} (ValueError for anything else)."""
    names = [n.strip() for n in text.split(",") if n.strip() and n.strip() != "none"]
    bad = [n for n in names if n not in ("system1", "system2")]
    if bad:
        raise ValueError(f"{flag} takes system1, system2 or none, got {', '.join(bad)}")
    return frozenset(int(n[-1]) for n in names)


def _fleet(args: argparse.Namespace, settings: common_cli.Settings, seed: int
           ) -> tuple[tuple[str, ...], tuple[int, ...], tuple[str, ...]]:
    """(vehicle ids, their seeds, their mission ids)."""
    uavs = fleet.uav_ids(args.uav_ids, settings.uav_id)
    seeds = ([int(v) for v in args.seeds.split(",")] if args.seeds
             else [seed + k for k in range(len(uavs))])
    if len(seeds) != len(uavs):
        raise ValueError(f"--seeds gives {len(seeds)} seeds for {len(uavs)} vehicles")
    if len(uavs) > 1:
        for flag, value in (("--out", args.out), ("--mission-id", args.mission_id)):
            if value and "{uav}" not in value:
                raise ValueError(f"{flag} must contain {{uav}} to fly several vehicles")
        fleet.instance_url(settings.mavlink_url, len(uavs) - 1)
        if args.sysid + len(uavs) - 1 > 255:
            raise ValueError(f"--sysid {args.sysid} + {len(uavs)} vehicles passes 255")
    started = int(time.time())
    mids = tuple(fleet.per_vehicle(args.mission_id, uav) or f"{uav}-{s}-{started}"
                 for uav, s in zip(uavs, seeds, strict=True))
    for mid in mids:
        keys.check_id(mid)
    return uavs, tuple(seeds), mids


def parse(argv: list[str] | None, doc: str,
          environ: Mapping[str, str] | None = None) -> Options:
    """The supervisor's options: the mission's flags of ``environ`` (default: this process's
    environment), then ``argv`` (default: the command line); argparse exits with the reason
    for a bad one."""
    p = parser(doc)
    given = sys.argv[1:] if argv is None else list(argv)
    args = p.parse_args(mission_env.env_argv(os.environ if environ is None else environ)
                        + given)
    try:
        settings = common_cli.settings("supervisor", args)
        mission = config_from_args(args)
        check_stack_dimension(mission)
        SimClock(settings.speed_factor)
        if not args.vehicle_lost_s > 0:
            raise ValueError("--vehicle-lost-s must be > 0")
        if not 0 <= args.start_stagger_s <= 600:
            raise ValueError("--start-stagger-s must be in [0, 600]")
        uavs, seeds, mids = _fleet(args, settings, mission.seed)
        link = LinkOptions(args.setpoint_rate_hz, args.setpoint_stream, args.sysid,
                           args.altitude_m,
                           mav.resolve_key(args.signing_passphrase, args.signing_key_file),
                           args.vehicle_lost_s)
        return Options(settings, mission, _stack_params(args), link, uavs, seeds, mids,
                       args.out, parse_waypoints(args.waypoints), args.start_stagger_s,
                       args.exit_after_mission, args.wait_services_s)
    except (ValueError, OSError) as err:
        p.error(str(err))
