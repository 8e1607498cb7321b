"""One vehicle's companion: wait for the stack, fly the mission, write its records, announce it.

:func:`fly` is the body the supervisor runs per vehicle (in a thread of its own
for a fleet): it refuses a vehicle another supervisor holds, waits for the EWS,
the planners of its controller and the vehicle (liveliness tokens and a
MAVLink heartbeat), flies one mission (services/supervisor/session.py), writes
its records and announces the end on ``mission/event``; the exit code it
returns is :data:`~services.supervisor.options.EXIT_SUCCESS`,
``EXIT_ABORTED`` or ``EXIT_FAILED``. What it opens — the liveliness tracker,
the transport to the services and the vehicle's link — comes from a
:class:`Stack` (the process's: :class:`ZenohStack`), the seam a unit test
replaces (tests/unit/services/supervisor/test_companion.py).
"""

from __future__ import annotations

import logging
import time
from typing import Protocol

import zenoh

from services.common import bus, keys, rejections, wire
from services.common.clock import SimClock
from services.common.log import fields
from services.common.traffic import TRAFFIC

from .airlink import LinkWatch, WatchedTransport
from .link import LinkParams, VehicleLink
from .options import EXIT_ABORTED, EXIT_FAILED, EXIT_SUCCESS, Options
from .ports import StackBus, StackTransport, ZenohStackTransport
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


class Stack(Protocol):
    """What the companion opens to fly one vehicle."""

    def own_id(self) -> str:
        """This process's id among the services (its Zenoh session's)."""
        ...

    def holders(self, uav: str) -> list[str]:
        """The supervisors holding ``uav`` now ([] if none)."""
        ...

    def liveliness(self, uav: str) -> bus.Liveliness:
        """Who of ``uav``'s services is alive."""
        ...

    def transport(self) -> StackTransport:
        """The mission's transport to the services."""
        ...

    def link(self, params: LinkParams) -> VehicleLink:
        """The vehicle's MAVLink link (not started)."""
        ...


class ZenohStack:
    """The supervisor process's stack: its Zenoh session and MAVLink links."""

    def __init__(self, session: zenoh.Session):
        self.session = session

    def own_id(self) -> str:
        return str(self.session.info.zid())

    def holders(self, uav: str) -> list[str]:
        return other_supervisors(self.session, uav)

    def liveliness(self, uav: str) -> bus.Liveliness:
        return bus.Liveliness(self.session, uav)

    def transport(self) -> StackTransport:
        return ZenohStackTransport(self.session)

    def link(self, params: LinkParams) -> VehicleLink:
        return VehicleLink(params)


def _ready(ctx: bus.Context, opts: Options, k: int, link: VehicleLink,
           live: bus.Liveliness, own: str) -> int | None:
    """Wait for the services and the vehicle; None when ready, else the exit code."""
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
    if not link.status.wait_vehicle(opts.wait_services_s, ctx.stop):
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
        paths = record.write(r, mission.b.uav, stack_summary(
            mission, {"wall_time_s": round(wall_s, 3), "aborted": aborted or None}))
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


def stack_summary(mission: StackSession, extra: dict[str, object]) -> dict[str, object]:
    """summary.json's ``stack``: how the stack flew the mission."""
    pool = mission.planners.pool if mission.planners is not None else None
    link = mission.link
    return {
        "mission_id": mission.b.mission_id, "transport": "zenoh + mavlink",
        "speed_factor": mission.b.clock.speed_factor or "unpaced",
        "setpoints_sent": link.setpoints.sent,
        "rejected_messages": dict(rejections.REJECTED.by_label),
        "monitor_rejected": mission.observer.monitor_rejected,
        "untrusted": _untrusted_counts(), "faults": dict(mission.observer.faults.totals),
        "planner_failovers": pool.failovers if pool is not None else 0,
        "forecast": mission.fires.forecasts.summary() if mission.fires is not None else {},
        "forecast_resends": (mission.planners.forecast_resends
                             if mission.planners is not None else 0),
        "stream": link.setpoints.stats(),
        "link": (mission.observer.airlink.summary(TRAFFIC.snapshot())
                 if mission.observer.airlink is not None else {}),
        "vehicle_modes": [{"mode": c.mode, "armed": c.armed, "text": c.text}
                          for c in link.status.mode_changes], **extra,
    }


def _untrusted_counts() -> dict[str, int]:
    """Replies and liveliness claims refused as not from the token holder, per key."""
    return {key: reasons[bus.UNTRUSTED] for key, reasons in rejections.REJECTED.snapshot().items()
            if bus.UNTRUSTED in reasons}


def link_params(opts: Options, k: int) -> LinkParams:
    """Vehicle k's link: its MAVLink instance and system id (services/common/fleet.py)."""
    lo = opts.link
    return LinkParams(opts.mavlink_url(k), lo.sysid + k, lo.altitude_m, lo.rate_hz, key=lo.key,
                      lost_after_s=lo.lost_after_s, stream=lo.stream)


def fly(ctx: bus.Context, opts: Options, stack: Stack | None = None) -> int:
    """Vehicle ``ctx.settings.uav_id``'s mission; the exit code (``stack``: what it opens,
    default the process's Zenoh session and MAVLink)."""
    if stack is None:
        assert ctx.session is not None
        stack = ZenohStack(ctx.session)
    uav = ctx.settings.uav_id
    k = opts.uavs.index(uav)
    holders = stack.holders(uav)
    if holders:  # one supervisor per vehicle: never touch a vehicle another one flies
        log.error("another supervisor holds this vehicle: not starting", extra=fields(
            uav=uav, holders=",".join(holders)))
        return EXIT_ABORTED
    link = stack.link(link_params(opts, k))
    link.start()
    live = stack.liveliness(uav)
    ctx.announce()
    try:
        code = _ready(ctx, opts, k, link, live, stack.own_id())
        if code is not None:
            return code
        config = opts.config(k)
        transport = stack.transport()
        airlink = LinkWatch(opts.stack.link) if opts.stack.link.services else None
        if airlink is not None:  # the services behind the air–ground link: every wait timed
            transport = WatchedTransport(transport, airlink)
        b = StackBus(transport, uav, config.mission_id,
                     wire.Stamper("supervisor", uav), SimClock(opts.settings.speed_factor),
                     ctx.stop, opts.stack, live, dt_s=config.spec().dynamics.dt_s)
        record = RunRecord(opts.run_dir(k), config.mission_id, opts.stack.record_flush_s)
        mission = StackSession(b, link, config, record, opts.waypoints, airlink)
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
