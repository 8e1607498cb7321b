"""Supervisor service: the cognitive controller's decision loop, the vehicle's offboard companion.

Waits for the EWS, the planners it needs and the vehicle (liveliness tokens
and a MAVLink heartbeat), takes the vehicle in MAVSDK/PX4 order (setpoints,
offboard mode, arm; services/supervisor/link.py), takes the vehicle's mission
as System 1's operator waypoints, flies one mission (services/supervisor/session.py),
writes its records to ``--out`` and announces the end on ``mission/event``.
It then keeps streaming the last setpoint until stopped, or, with
``--exit-after-mission``, exits: 0 when the mission succeeded, 1 when it was
aborted (or could not start), 3 when it ended in failure.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import zenoh

from dualpilot.mission.params import Controller, Timing
from dualpilot.model.geometry import Rect
from dualpilot.readings import PROFILES, get_profile
from dualpilot.spec import MissionSpec
from services.common import bus, codec, keys, mav
from services.common import cli as common_cli
from services.common.clock import SimClock
from services.common.log import fields

from .link import VehicleLink
from .session import Aborted, StackParams, StackSession, VehicleGone

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
                            ("--speed-limit", "speed_limit", "SPEED_LIMIT")):
        r.add_argument(flag, dest=f"reading_{name}", default=env(var, ""),
                       help=f"{name} [{var}]")
    g.add_argument("--waypoints", default=env("OPERATOR_WAYPOINTS", ""),
                   help="System 1's operator waypoints 'e1,n1;e2,n2' [OPERATOR_WAYPOINTS]")
    g.add_argument("--mission-id", default=env("MISSION_ID", ""),
                   help="default: <uav>-<seed>-<unix time> [MISSION_ID]")
    g.add_argument("--out", default=env("RUN_DIR", ""),
                   help="write summary.json, steps.csv, trace.json, latency.csv here [RUN_DIR]")
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
        waypoints = codec.parse_waypoints(args.waypoints)
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
    except (ValueError, OSError) as err:
        p.error(str(err))
    mission_id = args.mission_id or f"{settings.uav_id}-{args.seed}-{int(time.time())}"
    keys.check_id(mission_id)

    def body(ctx: bus.Context) -> None:
        assert ctx.session is not None
        holders = other_supervisors(ctx.session, settings.uav_id)
        if holders:  # one supervisor per vehicle: never touch a vehicle another one flies
            log.error("another supervisor holds this vehicle: not starting", extra=fields(
                uav=settings.uav_id, holders=",".join(holders)))
            ctx.exit_code = EXIT_ABORTED
            return
        link = VehicleLink(settings.mavlink_url, args.sysid, args.altitude_m,
                           args.setpoint_rate_hz, key=key, lost_after_s=args.vehicle_lost_s,
                           stream=args.setpoint_stream)
        link.start()
        live = bus.Liveliness(ctx.session, settings.uav_id)
        ctx.announce()
        try:
            own = str(ctx.session.info.zid())
            live.wait_for(["supervisor"], 5.0, ctx.stop)
            if live.holder("supervisor") not in ("", own):  # another started at the same time
                log.error("another supervisor claimed this vehicle first: not starting",
                          extra=fields(holder=live.holder("supervisor")))
                ctx.exit_code = EXIT_ABORTED
                return
            needed = needed_services(controller)
            log.info("waiting for services", extra=fields(services=",".join(sorted(needed))))
            if not live.wait_for(needed, args.wait_services_s, ctx.stop):
                if not ctx.stop.is_set():
                    log.error("services missing", extra=fields(
                        missing=",".join(sorted(live.missing(needed)))))
                    ctx.exit_code = EXIT_ABORTED
                return
            if not link.wait_vehicle(args.wait_services_s, ctx.stop):
                if not ctx.stop.is_set():
                    log.error("no heartbeat from the vehicle",
                              extra=fields(url=settings.mavlink_url))
                    ctx.exit_code = EXIT_ABORTED
                return
            mission = StackSession(
                ctx.session, link, settings.uav_id, mission_id, controller, spec, timing,
                SimClock(settings.speed_factor), ctx.stop, waypoints=waypoints, params=params,
                fire_params=reading.fire, supervisor_params=reading.supervisor,
                supervisor=args.supervisor, stack=stack, live=live,
                record_dir=Path(args.out) if args.out else None)
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
                    ctx.exit_code = EXIT_ABORTED
            finally:
                mission.close_record()
            wall = time.perf_counter() - t0
            out = Path(args.out) if args.out else None
            if out is not None and mission.result is not None and mission.result.records:
                try:
                    paths = mission.write(out, {"wall_time_s": round(wall, 3),
                                                "aborted": aborted or None})
                    log.info("records written", extra=fields(
                        files=",".join(p.name for p in paths)))
                except OSError as err:  # a full or read-only disk: logged, the end announced
                    codec.rejected("records", codec.invalid(f"records not written: {err}"),
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
                ctx.exit_code = EXIT_FAILED
        finally:
            link.close()

    return bus.run_service(settings, body)


if __name__ == "__main__":
    bus.leave(main())
