"""One vehicle's companion: wait for the stack, fly the mission, write its records, announce it.

:func:`fly` is the body the supervisor runs per vehicle (in a thread of its own
for a fleet): it refuses a vehicle another supervisor holds, waits for the EWS,
the planners of its controller and the vehicle (liveliness tokens and a
MAVLink heartbeat), flies one mission (services/supervisor/session.py), writes
its records and announces the end on ``mission/event``; the exit code it
returns is :data:`~services.supervisor.options.EXIT_SUCCESS`,
``EXIT_ABORTED`` or ``EXIT_FAILED``.
"""

from __future__ import annotations

import logging
import time

import zenoh

from services.common import bus, keys, rejections, wire
from services.common.clock import SimClock
from services.common.log import fields

from .link import VehicleLink
from .options import EXIT_ABORTED, EXIT_FAILED, EXIT_SUCCESS, Options
from .ports import Bus
from .record import RunRecord
from .session import Aborted, StackSession, VehicleGone

log = logging.getLogger("services.supervisor")


def other_supervisors(session: zenoh.Session, uav: str, timeout_s: float = 2.0) -> list[str]:
    """Sessions holding ``uav``'s supervisor tokens now (liveliness query; [] if none)."""
    found = []
    for reply in session.liveliness().get(keys.alive(uav, "supervisor") + "/**",
                                          timeout=timeout_s):
        if reply.ok is not None:
            found.append(str(reply.ok.key_expr).rsplit("/", 1)[-1])
    return found


def _ready(ctx: bus.Context, opts: Options, k: int, link: VehicleLink,
           live: bus.Liveliness) -> int | None:
    """Wait for the services and the vehicle; None when ready, else the exit code."""
    own = str(ctx.session.info.zid()) if ctx.session is not None else ""
    live.wait_for(["supervisor"], 5.0, ctx.stop)
    if live.holder("supervisor") not in ("", own):  # another started at the same time
        log.error("another supervisor claimed this vehicle first: not starting",
                  extra=fields(holder=live.holder("supervisor")))
        return EXIT_ABORTED
    needed = {"ews", "uavsim"} | {f"system{s}" for s in opts.mission.systems()}
    log.info("waiting for services", extra=fields(services=",".join(sorted(needed))))
    if not live.wait_for(needed, opts.wait_services_s, ctx.stop):
        if ctx.stop.is_set():
            return EXIT_SUCCESS
        log.error("services missing", extra=fields(missing=",".join(sorted(live.missing(needed)))))
        return EXIT_ABORTED
    if ctx.stop.wait(k * opts.stagger_s):
        return EXIT_SUCCESS
    if not link.wait_vehicle(opts.wait_services_s, ctx.stop):
        if ctx.stop.is_set():
            return EXIT_SUCCESS
        log.error("no heartbeat from the vehicle", extra=fields(url=opts.mavlink_url(k)))
        return EXIT_ABORTED
    return None


def _fly_session(ctx: bus.Context, opts: Options, mission: StackSession) -> tuple[str, float]:
    """Fly the session's mission; (why it was aborted, "" when it was not; wall s)."""
    t0 = time.perf_counter()
    aborted = ""
    try:
        mission.run()
    except VehicleGone as err:  # the mission ends (an end line), not aborted
        mission.end_lost(str(err))
    except Aborted as err:
        aborted = str(err)
        if not ctx.stop.is_set():
            log.error("mission aborted", extra=fields(reason=aborted))
    finally:
        mission.close()
    return aborted, time.perf_counter() - t0


def _write_records(mission: StackSession, aborted: str, wall_s: float) -> None:
    record, r = mission.record, mission.result
    if record.dir is None or r is None or not r.records:
        return
    if mission.planners is not None:  # requests answered after the last step's record
        record.latency.requests.extend(mission.planners.pool.take_answered())
    try:
        paths = record.write(r, mission.b.uav, mission.stack_summary(
            {"wall_time_s": round(wall_s, 3), "aborted": aborted or None}))
        log.info("records written", extra=fields(files=",".join(p.name for p in paths)))
    except OSError as err:  # a full or read-only disk: logged, the end announced
        rejections.rejected("records", rejections.invalid(f"records not written: {err}"), log,
                            key="storage/records", reason="write_error")


def _summary(mission: StackSession, wall_s: float) -> None:
    r = mission.result
    if r is None:
        return
    log.info("summary", extra=fields(
        success=r.success, cause=r.failure_cause, steps=r.steps,
        mission_time_s=r.mission_time_s, energy=round(r.energy, 3), switches=r.switches,
        wall_s=round(wall_s, 2), **{f"overhead_{k}": round(v, 3)
                                    for k, v in mission.record.latency.overhead_ms().items()}))


def fly(ctx: bus.Context, opts: Options) -> int:
    """Vehicle ``ctx.settings.uav_id``'s mission; the exit code."""
    assert ctx.session is not None
    uav = ctx.settings.uav_id
    k = opts.uavs.index(uav)
    holders = other_supervisors(ctx.session, uav)
    if holders:  # one supervisor per vehicle: never touch a vehicle another one flies
        log.error("another supervisor holds this vehicle: not starting", extra=fields(
            uav=uav, holders=",".join(holders)))
        return EXIT_ABORTED
    lo = opts.link
    link = VehicleLink(opts.mavlink_url(k), lo.sysid + k, lo.altitude_m, lo.rate_hz, key=lo.key,
                       lost_after_s=lo.lost_after_s, stream=lo.stream)
    link.start()
    live = bus.Liveliness(ctx.session, uav)
    ctx.announce()
    try:
        code = _ready(ctx, opts, k, link, live)
        if code is not None:
            return code
        config = opts.config(k)
        b = Bus(ctx.session, uav, config.mission_id, wire.Stamper("supervisor", uav),
                SimClock(opts.settings.speed_factor), ctx.stop, opts.stack, live,
                dt_s=config.spec().dynamics.dt_s)
        record = RunRecord(opts.run_dir(k), config.mission_id, opts.stack.record_flush_s)
        mission = StackSession(b, link, config, record, opts.waypoints)
        aborted, wall = _fly_session(ctx, opts, mission)
        _write_records(mission, aborted, wall)
        mission.announce_end(str(opts.run_dir(k) or ""), aborted)
        if not aborted:
            _summary(mission, wall)
        code = EXIT_ABORTED if aborted and not ctx.stop.is_set() else EXIT_SUCCESS
        if not opts.exit_after_mission:
            ctx.stop.wait()  # the stream keeps the last setpoint until the supervisor stops
        elif not aborted and mission.result is not None and not mission.result.success:
            code = EXIT_FAILED
        return code
    finally:
        link.close()
