"""The planner services' shared loop: a Zenoh queryable around a core :class:`Planner`.

Several processes of one system are replicas of a pool: each answers on
its own key ``plan/system<k>/<zid>`` as well as the shared one, and the
supervisor asks one of them (services/supervisor/ports/planners.py: StackPlanners).

A mission is prepared once: the prepare request carries its frozen spec
(dualpilot.spec.MissionSpec) and the service builds the mission's planner
from it (System 1 reuses its RRT path between steps; System 2 builds its
problem once), seeded from the spec as in-process. A plan request then names
the mission and carries only what changes per step: the vehicle state, the
obstacles the step chose (one per front), the objective, u_{t|t}, the
operator-waypoint revision it needs and, for a risk-aware method, the fire
forecast the step planned on (its grid and windows, or the grid named by reference, taken
from the EWS nearby: services/common/plan_forecasts.py; checked here against the
prepared mission: its T_f, and no older fire revision than one already seen).
Operator waypoints travel on their own key (``operator/waypoints``) with a
revision number.

Replies: a Plan (any status, with the planner's compute time) for a valid
request — a planner's ValueError becomes INVALID_INPUT, as in the in-process
loop; an Error reply for a malformed or invalid request, or a crash; an
UNPREPARED Error for a mission the service was not prepared for (it was
restarted) or a waypoint revision it has not received, so the supervisor
prepares again or re-sends the waypoints.
"""

from __future__ import annotations

import logging
import math
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import zenoh

from dualpilot.mission.config import MissionConfig
from dualpilot.model.geometry import Polytope
from dualpilot.model.risk import ForecastView
from dualpilot.plan import ForecastPlanner, Plan, Planner, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.warmup import warm_up
from services.msgs import common_pb2, plan_pb2, vehicle_pb2

from . import bus, keys, rejections, wire
from .convert import common as common_convert
from .convert import config as config_convert
from .convert import plan as plan_convert
from .convert import vehicle as vehicle_convert
from .effective import EFFECTIVE
from .log import fields
from .plan_forecasts import ForecastSource, ResolvedForecasts, ZenohForecasts

log = logging.getLogger(__name__)

#: (spec, configuration) -> the mission's planner of this service's system
PlannerMaker = Callable[[MissionSpec, MissionConfig], Planner]


@dataclass
class _Prepared:
    spec: MissionSpec
    config: MissionConfig
    planner: Planner
    waypoints_revision: int = 0  # the revision applied to the planner
    forecast_revision: int = -1  # the newest fire revision a forecast came from


class PlannerService:
    """Answers plan requests for one system with planners made per mission."""

    def __init__(self, system: int, make: PlannerMaker, uav: str, keep_missions: int = 2,
                 forecasts: ForecastSource | None = None):
        self.system = system
        #: forecasts named by reference, taken from the EWS (``forecasts``) and kept
        self.resolved = ResolvedForecasts(forecasts)
        self.make = make
        self.uav = uav
        self.stamper = wire.Stamper(f"system{system}", uav)
        self.key = keys.plan(uav, system)  # where its rejections are counted
        self.missions: OrderedDict[str, _Prepared] = OrderedDict()
        self.keep = keep_missions
        # newest per mission
        self.waypoints: OrderedDict[str, vehicle_convert.Waypoints] = OrderedDict()

    def prepare(self, mission_id: str, spec: MissionSpec, config: MissionConfig) -> _Prepared:
        """The mission's planner, built afresh from its spec and configuration: a prepare
        begins a flight (or rejoins one on a service that lost it), so the planner starts as
        the in-process one does (its seeded generator, no previous path, no fire revision
        seen), even when a mission of the same id and configuration flew here before.
        Raises ValueError for an unknown method (or one with no risk-aware variant under
        risk)."""
        planner = self.make(spec, config)
        EFFECTIVE.record(mission_id, self.uav, config_convert.config_to_json(config),
                         method=getattr(planner, "method", ""),
                         params=getattr(planner, "params", None), dynamics=spec.dynamics)
        held = _Prepared(spec, config, planner)
        self.missions[mission_id] = held
        while len(self.missions) > self.keep:
            self.missions.popitem(last=False)
        log.info("planner ready", extra=fields(mission=mission_id, seed=spec.seed))
        return held

    def set_operator_waypoints(self, w: vehicle_convert.Waypoints) -> None:
        """Keep the newest revision of a mission's waypoints (applied at its next plan)."""
        held = self.waypoints.get(w.mission_id)
        if held is None or w.revision > held.revision:
            self.waypoints[w.mission_id] = w
            while len(self.waypoints) > self.keep:
                self.waypoints.popitem(last=False)

    @staticmethod
    def _unprepared(message: str) -> rejections.CodecError:
        return rejections.CodecError(common_pb2.ERROR_CODE_UNPREPARED, message)

    def planner_for(self, req: plan_convert.PlanQuery) -> Planner:
        """The prepared planner, with the request's waypoint revision applied."""
        held = self.missions.get(req.mission_id)
        if held is None:
            raise self._unprepared(f"mission {req.mission_id!r} is not prepared here")
        plan_convert.check_in_area(req.request, held.spec)
        if req.waypoints_revision != held.waypoints_revision:
            w = self.waypoints.get(req.mission_id)
            if w is None or w.revision < req.waypoints_revision:
                have = 0 if w is None else w.revision
                raise self._unprepared(f"operator waypoints revision {req.waypoints_revision} "
                                       f"not received (have {have})")
            if not hasattr(held.planner, "set_waypoints"):
                raise rejections.invalid(f"system {self.system} takes no operator waypoints")
            try:
                held.planner.set_waypoints(w.points)
            except ValueError as err:
                raise rejections.invalid(f"operator waypoints: {err}") from err
            held.waypoints_revision = w.revision
        return held.planner

    def check_forecast(self, query: plan_convert.PlanQuery) -> ForecastView | None:
        """The request's forecast, if its planner takes one and it fits the prepared mission
        (CodecError: a forecast for a planner that takes none, another T_f, an older fire
        revision than one already planned on)."""
        view = query.request.forecast
        held = self.missions[query.mission_id]
        if view is None:
            return None  # a risk-aware planner without one plans as its paper method
        if not getattr(held.planner, "uses_forecast", False):
            raise rejections.invalid(f"System {self.system}'s method "
                                     f"{held.config.methods()[self.system]!r} takes no forecast")
        fc = view.forecast
        t_f = held.config.reading().fire.substep_s
        if not math.isclose(fc.substep_s, t_f, rel_tol=1e-12, abs_tol=0.0):
            raise rejections.invalid(f"the forecast's T_f {fc.substep_s:g} s is not the "
                                     f"mission's {t_f:g} s", rejections.Reason.OUT_OF_RANGE)
        if fc.issued_substep < held.forecast_revision:
            raise rejections.invalid(
                f"the forecast starts from fire revision {fc.issued_substep}, older than "
                f"{held.forecast_revision} already planned on", rejections.Reason.STALE)
        held.forecast_revision = fc.issued_substep
        return view

    def plan(self, query: plan_convert.PlanQuery) -> Plan:
        req = query.request
        if req.system != self.system:
            raise rejections.invalid(
                f"request for system {req.system} sent to system {self.system}")
        planner = self.planner_for(query)
        query = self.resolved.resolve(query)
        view = self.check_forecast(query)
        t0 = time.perf_counter()
        try:
            # the mission's kind (check_in_area): polygons in 2-D, prisms in 3-D
            obstacles = cast(tuple[Polytope, ...], req.obstacles)
            if view is not None:
                plan = cast(ForecastPlanner, planner).plan(
                    req.state, obstacles, req.objective, req.prev_control, forecast=view)
            else:
                plan = planner.plan(req.state, obstacles, req.objective, req.prev_control)
        except ValueError as err:  # bad input to the planner: not flyable, not fatal
            plan = Plan.failed(self.system, PlanStatus.INVALID_INPUT, time.perf_counter() - t0,
                               str(err))
        return plan

    def handle(self, payload: bytes, encoding: str) -> plan_pb2.Plan | common_pb2.Error:
        """Decode, plan, encode: a Plan, or an Error for a bad request or a crash."""
        t_in = time.perf_counter()
        try:
            req = plan_convert.plan_request_from_msg(wire.parse(payload, plan_pb2.PlanRequest,
                                                                encoding))
        except rejections.CodecError as err:
            rejections.rejected("PlanRequest", err, log, key=self.key)
            return common_convert.error_msg(self.stamper, err.code, str(err))
        if isinstance(req, plan_convert.Prepare):
            return self._prepared(req)
        try:
            plan = self.plan(req)
        except rejections.CodecError as err:
            if err.code != common_pb2.ERROR_CODE_UNPREPARED:  # a forecast it cannot have too:
                rejections.rejected("PlanRequest", err, log, key=self.key)  # refused, counted
            else:
                log.info("plan request for what is not here", extra=fields(error=str(err)))
            return common_convert.error_msg(self.stamper, err.code, str(err))
        except Exception as err:  # a planner bug must not take the service down
            log.exception("planner failed", extra=fields(step=req.request.t))
            return common_convert.error_msg(self.stamper, common_pb2.ERROR_CODE_INTERNAL,
                                            f"{type(err).__name__}: {err}")
        wall = time.perf_counter() - t_in
        if wall > req.deadline_s:
            log.warning("plan later than the request's deadline", extra=fields(
                step=req.request.t, wall_s=round(wall, 4), deadline_s=req.deadline_s))
        log.debug("plan", extra=fields(step=req.request.t, status=plan.status.value,
                                       compute_s=round(plan.compute_time_s, 4)))
        msg = plan_convert.plan_to_msg(plan, req.request.t, req.seq, self.stamper)
        msg.service_time_s = time.perf_counter() - t_in
        return msg

    def _prepared(self, req: plan_convert.Prepare) -> plan_pb2.Plan | common_pb2.Error:
        """Build the mission's planner; the reply says it is ready (or why it is not)."""
        if req.system != self.system:
            err = rejections.invalid(f"prepare for system {req.system} sent to system "
                                     f"{self.system}")
            rejections.rejected("PlanRequest", err, log, key=self.key)
            return common_convert.error_msg(self.stamper, err.code, str(err))
        try:
            self.prepare(req.mission_id, req.spec, req.config)
        except ValueError as err:
            rejections.rejected("PlanRequest", err, log, key=self.key)
            return common_convert.error_msg(self.stamper, common_pb2.ERROR_CODE_INVALID, str(err))
        prepared = plan_pb2.Plan(step=0, system=self.system, status=plan_pb2.PLAN_STATUS_OK,
                                 message="prepared", request_seq=req.seq)
        self.stamper.stamp(prepared.header)
        return prepared


def run(ctx: bus.Context, system: int, make: PlannerMaker) -> None:
    """The body of a planner service: queryables ``<ns>/plan/system<k>`` (any replica) and
    ``<ns>/plan/system<k>/<zid>`` (this replica: the supervisor's) until stopped."""
    assert ctx.session is not None
    warm_up((system,))  # before the token: alive means ready to answer in time (once a process)
    session: zenoh.Session = ctx.session
    uav = ctx.settings.uav_id
    live = bus.Liveliness(session, uav)  # whose forecasts count: the EWS token holder's
    service = PlannerService(system, make, uav,
                             forecasts=ZenohForecasts(session, uav, ctx.stop, live))
    queries = bus.Inbox(keys.plan(uav, system))
    operator = bus.Inbox()
    zid = str(session.info.zid())
    queryables = [session.declare_queryable(key, queries.on_query) for key in (
        keys.plan(uav, system), keys.plan_replica(uav, system, zid))]
    sub = session.declare_subscriber(keys.waypoints(uav), operator.on_sample)
    ctx.announce()
    while not ctx.stop.is_set():
        item = queries.get(timeout=0.2)
        while (wp := operator.get(timeout=0)) is not None:
            try:
                msg = wire.parse(wp.payload, vehicle_pb2.OperatorWaypoints, wp.encoding)
                service.set_operator_waypoints(vehicle_convert.waypoints_from_msg(msg))
                log.info("operator waypoints", extra=fields(
                    mission=msg.mission_id, revision=msg.revision, n=len(msg.waypoints)))
            except rejections.CodecError as err:
                rejections.rejected("OperatorWaypoints", err, log, key=keys.waypoints(uav))
        if item is None or item.query is None:
            continue
        out = service.handle(item.payload, item.encoding)
        if isinstance(out, common_pb2.Error):
            bus.reply_error(item.query, out)
        else:
            bus.reply(item.query, out)
    for queryable in queryables:
        queryable.undeclare()
    sub.undeclare()
    live.sub.undeclare()

