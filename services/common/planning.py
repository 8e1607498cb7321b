"""The planner services' shared loop: a Zenoh queryable around a core :class:`Planner`.

A PlanRequest carries everything the plan depends on — the mission (id, seed,
goal, initial operator waypoints), the vehicle state the supervisor read over
MAVLink, the EWS fire state it decided on, the objective and u_{t|t} — so a
planner answers for exactly the state and fires of that step, with no race
between subscriptions. The service keeps one planner per mission (System 1
reuses its RRT path between steps; System 2 builds its cvxpy problem once),
seeded from the mission's seed as :mod:`dualpilot.planners` does in-process.

Replies: a Plan (any status, with the planner's compute time) for a valid
request — a planner's ValueError becomes INVALID_INPUT, as in the in-process
loop; an Error reply for a malformed or invalid request, or a crash.
"""

from __future__ import annotations

import logging
import time
from collections import OrderedDict
from collections.abc import Callable

import numpy as np
import zenoh

from dualpilot.plan import Plan, Planner, PlanStatus
from services.msgs import common_pb2, plan_pb2, vehicle_pb2

from . import bus, codec, keys
from .log import fields

log = logging.getLogger(__name__)

PlannerMaker = Callable[[codec.MissionSpec], Planner]


def _same(a: codec.Array | None, b: codec.Array | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return a.shape == b.shape and bool(np.array_equal(a, b))


class PlannerService:
    """Answers plan requests for one system with planners made per mission."""

    def __init__(self, system: int, make: PlannerMaker, uav: str, keep_missions: int = 2):
        self.system = system
        self.make = make
        self.stamper = codec.Stamper(f"system{system}", uav)
        self.key = keys.plan(uav, system)  # where its rejections are counted
        self.planners: OrderedDict[str, Planner] = OrderedDict()
        self.keep = keep_missions
        self.waypoints: codec.Array | None = None
        self.waypoints_changed = False
        self.requested: dict[str, codec.Array | None] = {}  # last requests' waypoints

    def planner_for(self, mission: codec.MissionSpec) -> Planner:
        """The mission's planner (made on its first request), with operator waypoints applied
        whenever they change: the requests' (each carries the supervisor's current ones; a
        new planner, e.g. after a restart of this service, gets them at once) and, between
        two requests, an update on ``operator/waypoints`` (kept until the requests' change)."""
        mid = mission.mission_id
        planner = self.planners.get(mid)
        fresh = planner is None
        if planner is None:
            planner = self.make(mission)
            self.planners[mid] = planner
            while len(self.planners) > self.keep:
                old, _ = self.planners.popitem(last=False)
                self.requested.pop(old, None)
            log.info("planner ready", extra=fields(mission=mid, seed=mission.seed))
        if not hasattr(planner, "set_waypoints"):
            return planner
        if fresh or not _same(mission.waypoints, self.requested.get(mid)):
            self.requested[mid] = None if mission.waypoints is None else mission.waypoints.copy()
            if mission.waypoints is not None or not fresh:
                planner.set_waypoints(mission.waypoints)
        if self.waypoints_changed:  # an operator update on operator/waypoints
            planner.set_waypoints(self.waypoints)
            self.waypoints_changed = False
        return planner

    def set_operator_waypoints(self, wps: codec.Array | None) -> None:
        """Operator update: applied to the current mission's planner at its next plan."""
        self.waypoints = wps
        self.waypoints_changed = True

    def plan(self, req: codec.PlanRequest) -> Plan:
        if req.system != self.system:
            raise codec.invalid(f"request for system {req.system} sent to system {self.system}")
        try:
            planner = self.planner_for(req.mission)
        except ValueError as err:
            raise codec.invalid(f"cannot plan for this mission: {err}") from err
        t0 = time.perf_counter()
        try:
            plan = planner.plan(req.state, req.fires.hulls, req.objective, req.prev_control)
        except ValueError as err:  # bad input to the planner: not flyable, not fatal
            plan = Plan.failed(self.system, PlanStatus.INVALID_INPUT, time.perf_counter() - t0,
                               str(err))
        return plan

    def handle(self, payload: bytes, encoding: str) -> plan_pb2.Plan | common_pb2.Error:
        """Decode, plan, encode: a Plan, or an Error for a bad request or a crash."""
        t_in = time.perf_counter()
        try:
            req = codec.plan_request_from_msg(codec.parse(payload, plan_pb2.PlanRequest, encoding))
        except codec.CodecError as err:
            codec.rejected("PlanRequest", err, log, key=self.key)
            return codec.error_msg(self.stamper, err.code, str(err))
        if req.prepare:
            try:
                self.planner_for(req.mission)
            except ValueError as err:
                codec.rejected("PlanRequest", err, log, key=self.key)
                return codec.error_msg(self.stamper, common_pb2.ERROR_CODE_INVALID, str(err))
            prepared = plan_pb2.Plan(step=req.step, system=self.system,
                                     status=plan_pb2.PLAN_STATUS_OK, message="prepared",
                                     request_seq=req.seq)
            self.stamper.stamp(prepared.header)
            return prepared
        t0 = time.perf_counter()
        try:
            plan = self.plan(req)
        except codec.CodecError as err:
            codec.rejected("PlanRequest", err, log, key=self.key)
            return codec.error_msg(self.stamper, err.code, str(err))
        except Exception as err:  # a planner bug must not take the service down
            log.exception("planner failed", extra=fields(step=req.step))
            return codec.error_msg(self.stamper, common_pb2.ERROR_CODE_INTERNAL,
                                   f"{type(err).__name__}: {err}")
        wall = time.perf_counter() - t0
        if wall > req.deadline_s:
            log.warning("plan later than the request's deadline", extra=fields(
                step=req.step, wall_s=round(wall, 4), deadline_s=req.deadline_s))
        log.debug("plan", extra=fields(step=req.step, status=plan.status.value,
                                       compute_s=round(plan.compute_time_s, 4)))
        msg = codec.plan_to_msg(plan, req.step, req.seq, self.stamper)
        msg.service_time_s = time.perf_counter() - t_in
        return msg


def run(ctx: bus.Context, system: int, make: PlannerMaker) -> None:
    """The body of a planner service: queryable ``<ns>/plan/system<k>`` until stopped."""
    assert ctx.session is not None
    session: zenoh.Session = ctx.session
    uav = ctx.settings.uav_id
    service = PlannerService(system, make, uav)
    queries = bus.Inbox()
    operator = bus.Inbox()
    queryable = session.declare_queryable(keys.plan(uav, system), queries.on_query)
    sub = session.declare_subscriber(keys.waypoints(uav), operator.on_sample)
    ctx.announce()
    while not ctx.stop.is_set():
        item = queries.get(timeout=0.2)
        while (wp := operator.get(timeout=0)) is not None:
            try:
                msg = codec.parse(wp.payload, vehicle_pb2.OperatorWaypoints, wp.encoding)
                service.set_operator_waypoints(codec.waypoints_from_msg(msg))
                log.info("operator waypoints", extra=fields(n=len(msg.waypoints)))
            except codec.CodecError as err:
                codec.rejected("OperatorWaypoints", err, log, key=keys.waypoints(uav))
        if item is None or item.query is None:
            continue
        out = service.handle(item.payload, item.encoding)
        if isinstance(out, common_pb2.Error):
            bus.reply_error(item.query, out)
        else:
            bus.reply(item.query, out)
    queryable.undeclare()
    sub.undeclare()

