"""Supervisor service: the cognitive controller's decision loop, the vehicle's offboard companion.

Waits for the EWS, the planners it needs and the vehicle (liveliness tokens
and a MAVLink heartbeat), takes the vehicle in MAVSDK/PX4 order (setpoints,
offboard mode, arm; services/supervisor/link.py), takes the vehicle's mission
as System 1's operator waypoints, flies one mission (services/supervisor/session.py),
writes its records to ``--out`` and announces the end on ``mission/event``.
It then keeps streaming the last setpoint until stopped, or, with
``--exit-after-mission``, exits: 0 when the mission succeeded, 1 when it was
aborted (or could not start), 3 when it ended in failure.

``--uav-ids`` makes one process the companion of several vehicles
(services/common/fleet.py): vehicle k (from 0) flies seed ``--seed`` + k (or
the k-th of ``--seeds``) on MAVLink instance k (the URL's port + k, system id
``--sysid`` + k), into ``--out`` with ``{uav}`` replaced by its id, each in a
thread of its own; one stream process keeps every vehicle's setpoints
beating. With ``--exit-after-mission`` the process exits when every mission
has ended, with the worst vehicle's code.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path

import zenoh

from dualpilot.mission.params import Controller, Timing
from dualpilot.model.geometry import Rect
from dualpilot.readings import PROFILES, get_profile
from dualpilot.spec import MissionSpec
from dualpilot.warmup import warm_up
from services.common import bus, fleet, keys, mav, protobuf_codec, rejections
from services.common import cli as common_cli
from services.common.clock import SimClock
from services.common.log import fields

from .link import VehicleLink
from .session import Aborted, StackParams, StackSession, VehicleGone
from .stream.client import close_stream_process

log = logging.getLogger("services.supervisor")


#: exit codes with ``--exit-after-mission`` (``docker compose up --exit-code-from supervisor``)
EXIT_SUCCESS, EXIT_ABORTED, EXIT_FAILED = 0, 1, 3


def needed_services(controller: Controller) -> set[str]:
    planners = {Controller.CC: {"system1", "system2"}, Controller.S1: {"system1"},
                Controller.S2: {"system2"}}[controller]
    return {"ews", "uavsim"} | planners


def other_supervisors(session: zenoh.Session, uav: str, timeout_s: float = 2.0) -> list[str]:
    """Sessions holding ``uav``'s supervisor tokens now (liveliness query; [] if none)."""
    found = []
    for reply in session.liveliness().get(keys.alive(uav, "supervisor") + "/**",
                                          timeout=timeout_s):
        if reply.ok is not None:
            found.append(str(reply.ok.key_expr).rsplit("/", 1)[-1])
    return found


def parse_goal(text: str) -> Rect:
    try:
        cx, cy, w, h = (float(v) for v in text.split(","))
    except ValueError as err:
        raise ValueError(f"--goal must be 'east,north,width,height', got {text!r}") from err
    return Rect(cx, cy, w, h)


def main(argv: list[str] | None = None) -> int:
    env = common_cli.env
    p = common_cli.parser("supervisor", __doc__.splitlines()[0],
                          mavlink_default="udpout:127.0.0.1:14540")
    g = p.add_argument_group("mission")
    g.add_argument("--controller", default=env("CONTROLLER", "cc"),
                   choices=[c.value for c in Controller], help="[CONTROLLER]")
    g.add_argument("--seed", type=int, default=env("MISSION_SEED", "7"), help="[MISSION_SEED]")
    g.add_argument("--seeds", default=env("MISSION_SEEDS", ""),
                   help="with --uav-ids: each vehicle's seed, comma-separated (default: --seed "
                        "+ k) [MISSION_SEEDS]")
    g.add_argument("--timing", default=env("TIMING", "paper"), choices=[t.value for t in Timing],
                   help="planning time T_s: the paper's 155 ms / 5 s or measured [TIMING]")
    g.add_argument("--goal", default=env("GOAL", "900,900,100,100"),
                   help="goal rectangle 'east,north,width,height' in m [GOAL]")
    g.add_argument("--area-size-m", type=float, default=env("AREA_SIZE_M", "1000"),
                   help="[AREA_SIZE_M]")
    g.add_argument("--max-steps", type=int, default=env("MAX_STEPS", "150"),
                   help="[MAX_STEPS]")
    g.add_argument("--ignition-clearance", type=float,
                   default=env("IGNITION_CLEARANCE_M", "") or None,
                   help="no front ignites within this distance (m) of the UAV; unset: anywhere "
                        "[IGNITION_CLEARANCE_M]")
    g.add_argument("--supervisor", default=env("SUPERVISOR", "paper"),
                   choices=["paper", "concurrent"],
                   help="the cognitive controller's supervisor: the paper's, or the concurrent "
                        "one (System 2 deliberates while the UAV flies; System 1 prepared with "
                        "the Δu tracker, rrt+du) [SUPERVISOR]")
    r = p.add_argument_group("readings (dualpilot profiles; a flag overrides the profile)")
    r.add_argument("--profile", default=env("READINGS_PROFILE", "today"), choices=list(PROFILES),
                   help="[READINGS_PROFILE]")
    for flag, name, var in (("--d-t-reading", "d_t_reading", "D_T_READING"),
                            ("--failure-rule", "failure_rule", "FAILURE_RULE"),
                            ("--fire-substeps-per-motion", "fire_substeps_per_motion",
                             "FIRE_SUBSTEPS_PER_MOTION"),
                            ("--fire-life-base", "life_base", "FIRE_LIFE_BASE"),
                            ("--fire-extent", "extent", "FIRE_EXTENT"),
                            ("--redraw-clearance", "redraw_clearance", "FIRE_REDRAW_CLEARANCE"),
                            ("--attention-draw", "attention_draw", "ATTENTION_DRAW"),
                            ("--speed-limit", "speed_limit", "SPEED_LIMIT"),
                            ("--fire-scenario", "scenario", "FIRE_SCENARIO")):
        r.add_argument(flag, dest=f"reading_{name}", default=env(var, ""),
                       help=f"{name} [{var}]")
    g.add_argument("--waypoints", default=env("OPERATOR_WAYPOINTS", ""),
                   help="System 1's operator waypoints 'e1,n1;e2,n2' [OPERATOR_WAYPOINTS]")
    g.add_argument("--mission-id", default=env("MISSION_ID", ""),
                   help="default: <uav>-<seed>-<unix time> [MISSION_ID]")
    g.add_argument("--out", default=env("RUN_DIR", ""),
                   help="write summary.json, steps.csv, trace.json, latency.csv here; {uav} is "
                        "the vehicle id [RUN_DIR]")
    fleet.add_argument(g, "one companion process for several vehicles: instance k on the "
                          "MAVLink URL's port + k, system id --sysid + k")
    g.add_argument("--start-stagger-s", type=float, default=env("START_STAGGER_S", "0"),
                   help="with --uav-ids: vehicle k takes off k times this many wall seconds "
                        "after the first (a fleet launched one vehicle after another) "
                        "[START_STAGGER_S]")
    g.add_argument("--exit-after-mission", action="store_true",
                   default=env("EXIT_AFTER_MISSION", "0") == "1",
                   help=f"exit when the mission ends: {EXIT_SUCCESS} success, {EXIT_ABORTED} "
                        f"aborted (or could not start), {EXIT_FAILED} ended in failure, as "
                        "docker compose --exit-code-from supervisor reports it "
                        "[EXIT_AFTER_MISSION=1]")
    s = p.add_argument_group("stack")
    s.add_argument("--wait-services-s", type=float, default=env("WAIT_SERVICES_S", "120"),
                   help="how long to wait for the other services [WAIT_SERVICES_S]")
    s.add_argument("--plan-deadline-s", default=env("PLAN_DEADLINE_S", ""),
                   help="'s1,s2' wall seconds a plan request waits [PLAN_DEADLINE_S]")
    s.add_argument("--setpoint-rate-hz", type=float, default=env("SETPOINT_RATE_HZ", "20"),
                   help="setpoint stream rate, >= 10 [SETPOINT_RATE_HZ]")
    s.add_argument("--setpoint-stream", default=env("SETPOINT_STREAM", "process"),
                   choices=["process", "thread"],
                   help="who sends the setpoint stream: a process of its own with raised "
                        "priority (UDP links), or a thread of the supervisor (the comparison "
                        "of benchmarks/stream_gaps.py) [SETPOINT_STREAM]")
    s.add_argument("--sysid", type=int, default=env("MAV_SYSID", "1"),
                   help="the vehicle's MAVLink system id [MAV_SYSID]")
    s.add_argument("--altitude-m", type=float, default=env("UAV_ALTITUDE_M", "50"),
                   help="[UAV_ALTITUDE_M]")
    s.add_argument("--signing-passphrase", default=env("MAVLINK_SIGNING_PASSPHRASE", ""),
                   help="sign the offboard link [MAVLINK_SIGNING_PASSPHRASE]")
    s.add_argument("--signing-key-file", default=env("MAVLINK_SIGNING_KEY_FILE", ""),
                   help="sign the offboard link: 32 raw bytes, or a passphrase (sha256, as "
                        "MAVProxy) [MAVLINK_SIGNING_KEY_FILE]")
    s.add_argument("--vehicle-lost-s", type=float, default=env("VEHICLE_LOST_S", "3"),
                   help="pause the mission after this long without a vehicle heartbeat "
                        "[VEHICLE_LOST_S]")
    args = p.parse_args(argv)
    try:
        settings = common_cli.settings("supervisor", args)
        controller, timing = Controller(args.controller), Timing(args.timing)
        goal = parse_goal(args.goal)
        waypoints = protobuf_codec.parse_waypoints(args.waypoints)
        # default: tied to the control period (StackParams.plan_deadline_periods)
        deadlines = tuple(float(v) for v in args.plan_deadline_s.split(",")) if (
            args.plan_deadline_s) else StackParams().plan_deadline_periods
        if len(deadlines) != 2 or min(deadlines) <= 0:
            raise ValueError("--plan-deadline-s must be two positive numbers 's1,s2'")
        chosen: dict[str, object] = {k.removeprefix("reading_"): v for k, v in vars(args).items()
                                     if k.startswith("reading_") and v}
        chosen["max_steps"] = args.max_steps
        if args.ignition_clearance is not None:
            chosen["ignition_clearance_m"] = args.ignition_clearance
        reading = get_profile(args.profile).with_settings(chosen)
        params = reading.mission
        # the start is the vehicle's position when the mission starts (StackSession.start)
        spec = reading.spec(MissionSpec(goal=goal, area_size_m=args.area_size_m, seed=args.seed))
        stack = StackParams(plan_deadline_s=(deadlines[0], deadlines[1]) if (
                                args.plan_deadline_s) else None,
                            altitude_m=args.altitude_m)
        SimClock(settings.speed_factor)
        key = mav.resolve_key(args.signing_passphrase, args.signing_key_file)
        if not args.vehicle_lost_s > 0:
            raise ValueError("--vehicle-lost-s must be > 0")
        if not 0 <= args.start_stagger_s <= 600:
            raise ValueError("--start-stagger-s must be in [0, 600]")
        uavs = fleet.uav_ids(args.uav_ids, settings.uav_id)
        seeds = ([int(v) for v in args.seeds.split(",")] if args.seeds
                 else [args.seed + k for k in range(len(uavs))])
        if len(seeds) != len(uavs):
            raise ValueError(f"--seeds gives {len(seeds)} seeds for {len(uavs)} vehicles")
        if len(uavs) > 1:
            for flag, value in (("--out", args.out), ("--mission-id", args.mission_id)):
                if value and "{uav}" not in value:
                    raise ValueError(f"{flag} must contain {{uav}} to fly several vehicles")
            fleet.instance_url(settings.mavlink_url, len(uavs) - 1)
            if args.sysid + len(uavs) - 1 > 255:
                raise ValueError(f"--sysid {args.sysid} + {len(uavs)} vehicles passes 255")
    except (ValueError, OSError) as err:
        p.error(str(err))
    started = int(time.time())
    mission_ids = {uav: fleet.per_vehicle(args.mission_id, uav)
                   or f"{uav}-{seed}-{started}" for uav, seed in zip(uavs, seeds, strict=True)}
    for mid in mission_ids.values():
        keys.check_id(mid)
    codes: dict[str, int] = {}

    def body(ctx: bus.Context) -> None:
        assert ctx.session is not None
        uav = ctx.settings.uav_id
        k = uavs.index(uav)
        seed, mission_id, sysid = seeds[k], mission_ids[uav], args.sysid + k
        out = Path(fleet.per_vehicle(args.out, uav)) if args.out else None
        url = fleet.instance_url(settings.mavlink_url, k)
        holders = other_supervisors(ctx.session, uav)
        if holders:  # one supervisor per vehicle: never touch a vehicle another one flies
            log.error("another supervisor holds this vehicle: not starting", extra=fields(
                uav=uav, holders=",".join(holders)))
            codes[uav] = EXIT_ABORTED
            return
        link = VehicleLink(url, sysid, args.altitude_m,
                           args.setpoint_rate_hz, key=key, lost_after_s=args.vehicle_lost_s,
                           stream=args.setpoint_stream)
        link.start()
        live = bus.Liveliness(ctx.session, uav)
        ctx.announce()
        try:
            own = str(ctx.session.info.zid())
            live.wait_for(["supervisor"], 5.0, ctx.stop)
            if live.holder("supervisor") not in ("", own):  # another started at the same time
                log.error("another supervisor claimed this vehicle first: not starting",
                          extra=fields(holder=live.holder("supervisor")))
                codes[uav] = EXIT_ABORTED
                return
            needed = needed_services(controller)
            log.info("waiting for services", extra=fields(services=",".join(sorted(needed))))
            if not live.wait_for(needed, args.wait_services_s, ctx.stop):
                if not ctx.stop.is_set():
                    log.error("services missing", extra=fields(
                        missing=",".join(sorted(live.missing(needed)))))
                    codes[uav] = EXIT_ABORTED
                return
            if ctx.stop.wait(k * args.start_stagger_s):
                return
            if not link.wait_vehicle(args.wait_services_s, ctx.stop):
                if not ctx.stop.is_set():
                    log.error("no heartbeat from the vehicle", extra=fields(url=url))
                    codes[uav] = EXIT_ABORTED
                return
            mission = StackSession(
                ctx.session, link, uav, mission_id, controller, replace(spec, seed=seed),
                timing, SimClock(settings.speed_factor), ctx.stop, waypoints=waypoints,
                params=params, fire_params=reading.fire, supervisor_params=reading.supervisor,
                supervisor=args.supervisor, stack=stack, live=live, record_dir=out)
            t0 = time.perf_counter()
            aborted = ""
            try:
                mission.run()
            except VehicleGone as err:  # the mission ends (an end line), not aborted
                mission.end_lost("vehicle_lost", str(err))
            except Aborted as err:
                aborted = str(err)
                if not ctx.stop.is_set():
                    log.error("mission aborted", extra=fields(reason=aborted))
                    codes[uav] = EXIT_ABORTED
            finally:
                mission.close_record()
            wall = time.perf_counter() - t0
            if out is not None and mission.result is not None and mission.result.records:
                try:
                    paths = mission.write(out, {"wall_time_s": round(wall, 3),
                                                "aborted": aborted or None})
                    log.info("records written", extra=fields(
                        files=",".join(p.name for p in paths)))
                except OSError as err:  # a full or read-only disk: logged, the end announced
                    rejections.rejected("records",
                                        rejections.invalid(f"records not written: {err}"),
                                        log, key="storage/records", reason="write_error")
            mission.announce_end(str(out or ""), aborted)
            r = mission.result
            if r is not None and not aborted:
                log.info("summary", extra=fields(
                    success=r.success, cause=r.failure_cause, steps=r.steps,
                    mission_time_s=r.mission_time_s, energy=round(r.energy, 3),
                    switches=r.switches, wall_s=round(wall, 2),
                    **{f"overhead_{k}": round(v, 3)
                       for k, v in mission.latency.overhead_ms().items()}))
            if not args.exit_after_mission:
                ctx.stop.wait()
            elif r is not None and not aborted and not r.success:
                codes[uav] = EXIT_FAILED
        finally:
            link.close()

    def serve(ctx: bus.Context) -> None:
        # the compiled kernels the step's checks use (hulls, the monitor), loaded before the
        # first mission: else the step that meets the first fire waits for them
        warm_up()
        try:
            fleet.for_each(ctx, uavs, body)
        finally:
            close_stream_process()  # every link is closed: its vehicles' streams end here
        ctx.exit_code = max([ctx.exit_code, *codes.values()])

    return bus.run_service(settings, serve)


if __name__ == "__main__":
    bus.leave(main())
