"""The planner port over the planner pool: prepare, ask (or launch and collect), waypoints."""

from __future__ import annotations

import logging
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import Array
from dualpilot.plan import Plan, PlanStatus
from dualpilot.spec import MissionSpec
from services.common import keys
from services.common.convert import plan as plan_convert
from services.common.convert import vehicle as vehicle_convert
from services.common.log import fields, vehicle_thread
from services.msgs import plan_pb2

from ..pool import PlannerPool
from .params import AirLinkParams
from .stackbus import Aborted, StackBus

log = logging.getLogger("services.supervisor.ports")


def across_link(plan: Plan, wall_s: float, link: AirLinkParams) -> Plan:
    """A plan of a system behind the air–ground link took its request's whole wall time
    (``wall_s``: the link's round trip, the planner's compute): that is its planning time, as
    in flight (``--timing measured``), the planner's own kept in ``info``. Any other plan as
    it is."""
    if (f"system{plan.system}" not in link.services or plan.status is not PlanStatus.OK
            or wall_s <= plan.compute_time_s):
        return plan
    plan.info["planner_compute_s"] = round(plan.compute_time_s, 6)
    return replace(plan, compute_time_s=wall_s)


class StackPlanners:
    """The planner port over the planner pool (services/supervisor/pool.py).

    A planner is asked only while its liveliness token is up and the pool has
    not demoted it. Each request goes to the mission's replica and comes back
    checked (the pool's rules). A planner that was not prepared for this mission
    (it was restarted) is prepared again and asked once more. Operator waypoints
    travel on their own key, with a revision the requests name. A risk-aware request
    of a system in ``forecast_by_reference`` names its forecast (the planner takes it from
    the EWS beside it); when the planner cannot have it, the request is sent again with
    the forecast whole (``forecast_resends``).
    """

    def __init__(self, b: StackBus, spec: MissionSpec, config: MissionConfig, pool: PlannerPool):
        self.b = b
        self.spec = spec
        self.config = config
        self.pool = pool
        self.waypoints = vehicle_convert.Waypoints(b.mission_id, 0, None)
        self.last_info: dict[int, dict[str, object]] = {}
        self.compute = 0.0  # this step's planners' compute time (s)
        self._background: ThreadPoolExecutor | None = None  # launch/collect
        #: requests sent again with their forecast whole (the planner could not have it)
        self.forecast_resends = 0

    def begin_step(self) -> None:
        self.compute = 0.0
        self.last_info = {}
        self.pool.begin_step()

    def available(self, system: int) -> bool:
        return self.b.alive(f"system{system}") and self.pool.available(system)

    def uses_forecast(self, system: int) -> bool:
        """Under ``risk`` both systems' planners are risk-aware (dualpilot.planners)."""
        return self.config.risk

    # -- messages ---------------------------------------------------------------------------------
    def _query_msg(self, request: PlanRequest, by_reference: bool) -> plan_pb2.PlanRequest:
        query = plan_convert.PlanQuery(request, self.b.mission_id, 0,
                                       self.b.deadline_s(request.system),
                                       self.waypoints.revision)
        return plan_convert.plan_query_msg(query, self.b.stamper, self.b.clock.now_s,
                                           by_reference)

    def prepare(self, systems: list[int]) -> None:
        """Warm-up: every replica of each planner builds this mission's planner from the spec
        and the configuration. Raises Aborted when no replica of a system could."""
        for system in systems:
            prep = plan_convert.Prepare(self.b.mission_id, system, self.spec, self.config,
                                        deadline_s=self.b.deadline_s(system))
            msg = plan_convert.prepare_msg(prep, self.b.stamper, self.b.clock.now_s)
            try:
                self.pool.prepare(system, msg)
            except RuntimeError as err:
                raise Aborted(str(err)) from err

    def set_waypoints(self, points: Array | None, publish: bool) -> None:
        """A new revision of the operator waypoints, published on their key."""
        self.waypoints = vehicle_convert.Waypoints(self.b.mission_id,
                                                   self.waypoints.revision + 1, points)
        if publish:
            self.publish_waypoints()

    def publish_waypoints(self) -> None:
        self.b.transport.put(keys.waypoints(self.b.uav),
                             vehicle_convert.waypoints_msg(self.waypoints, self.b.stamper))

    # -- the port ---------------------------------------------------------------------------------
    def launch(self, request: PlanRequest) -> object:
        """Ask in the background (the concurrent supervisor's System 2): the query leaves now,
        on a thread of its own; :meth:`collect` takes its checked reply."""
        if self._background is None:
            self._background = ThreadPoolExecutor(max_workers=1, thread_name_prefix="deliberate",
                                                  initializer=vehicle_thread(lambda: None))
        return self._background.submit(self._ask, request, False)

    def collect(self, ticket: object) -> Plan:
        """The launched request's plan (a failed plan when it was late or not this step's)."""
        assert isinstance(ticket, Future)
        plan: Plan = ticket.result()
        self.pool.count_background(plan)
        return plan

    def close(self) -> None:
        if self._background is not None:
            self._background.shutdown(wait=False, cancel_futures=True)

    def plan(self, request: PlanRequest) -> Plan:
        plan = self._ask(request)
        if plan.info.get("unprepared"):
            try:  # a restarted service: prepare it (and re-send the waypoints), ask once more
                self.prepare([request.system])
                if self.waypoints.revision:
                    self.publish_waypoints()
            except Aborted as err:
                log.warning("planner could not be prepared again", extra=fields(error=str(err)))
            else:
                plan = self._ask(request)
        self.pool.count(request.system, plan)
        self.compute += plan.compute_time_s
        if request.system == 1:
            self.last_info[1] = dict(plan.info)
        return plan

    def _ask(self, request: PlanRequest, account: bool = True) -> Plan:
        t0 = self.b.wall.now()
        plan = self._ask_once(request, account)
        if self.b.stop.is_set():
            raise Aborted("stopped")
        return across_link(plan, self.b.wall.now() - t0, self.b.stack.link)

    def _ask_once(self, request: PlanRequest, account: bool) -> Plan:
        by_ref = (request.forecast is not None
                  and request.system in self.b.stack.forecast_by_reference)
        plan = self.pool.ask(request.system, request.t, self._query_msg(request, by_ref),
                             account)
        if by_ref and plan.info.get("forecast_unavailable") and not self.b.stop.is_set():
            self.forecast_resends += 1
            log.warning("planner could not take the forecast by reference: sent whole",
                        extra=fields(system=request.system, step=request.t,
                                     reason=plan.message))
            plan = self.pool.ask(request.system, request.t, self._query_msg(request, False),
                                 account)
        return plan
