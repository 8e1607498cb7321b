"""A planner service plans the risk-aware methods on the forecast a plan request carries, and
refuses a forecast that does not fit the prepared mission with a counted INVALID."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import hover_state
from dualpilot.model.forecast import LEVELS, OccupancyForecast
from dualpilot.model.geometry import Rect
from dualpilot.model.risk import ForecastView
from dualpilot.plan import Objective
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from services.common import rejections, wire
from services.common.convert import plan as plan_convert
from services.common.planning import PlannerService
from services.msgs import common_pb2, plan_pb2

pytestmark = pytest.mark.timeout(120)

#: start west, goal east: the straight line y = 500 crosses the box of certain fire
SPEC = MissionSpec(start=(100.0, 500.0), goal=Rect(900.0, 500.0, 100.0, 100.0), seed=3)
BOX = (400.0, 430.0, 600.0, 570.0)
STAMP = wire.Stamper("supervisor", "u")


def service(system: int) -> PlannerService:
    return PlannerService(system, lambda spec, c: build_planner(
        system, spec, c.methods()[system], risk=c.risk), "u")


def box_forecast(issued: int = 0, substep_s: float = 0.5) -> OccupancyForecast:
    """Certain fire on the cells of BOX at every horizon 0..80, nothing elsewhere (10 m)."""
    c = (np.arange(100) + 0.5) * 10.0
    x0, y0, x1, y1 = BOX
    cells = (c[:, None] >= y0) & (c[:, None] <= y1) & (c[None, :] >= x0) & (c[None, :] <= x1)
    levels = np.repeat((cells * LEVELS).astype(np.uint8)[None], 41, axis=0)
    return OccupancyForecast(resolution_m=10.0, substep_s=substep_s,
                             horizons=tuple(range(0, 81, 2)), levels=levels,
                             issued_substep=issued)


def query(system: int, t: int = 1, forecast: ForecastView | None = None) -> bytes:
    """A plan request for mission m1 at step t, through the real codec."""
    state = hover_state(np.array(SPEC.start), SPEC.dynamics)
    req = PlanRequest(t=t, system=system, state=state, prev_control=np.zeros(2),
                      obstacles=(), objective=Objective.MISSION_TIME, forecast=forecast)
    msg = plan_convert.plan_query_msg(plan_convert.PlanQuery(req, "m1", t, 30.0), STAMP, 0.0)
    return msg.SerializeToString()


def handle(s: PlannerService, payload: bytes) -> plan_pb2.Plan | common_pb2.Error:
    return s.handle(payload, wire.encoding_name(plan_pb2.PlanRequest))


def rejected(system: int) -> dict[str, int]:
    return rejections.REJECTED.snapshot().get(f"dualpilot/u/plan/system{system}", {})


@pytest.mark.parametrize(("system", "controller", "method"), [
    (1, "cc", "rrt"), (1, "concurrent", "rrt+du"), (2, "s2", "fast"),
    (1, "cc+risk", "rrt+risk"), (1, "concurrent+risk", "rrt+du+risk"),
    (2, "s2+risk", "fast+risk")])
def test_every_controllers_method_is_prepared(system: int, controller: str,
                                              method: str) -> None:
    config = MissionConfig.named(controller, seed=3)
    held = service(system).prepare("m1", MissionSpec(seed=3), config)
    assert held.config == config and held.planner.method == method


@pytest.mark.parametrize(("system", "controller"), [(1, "s1+risk"), (2, "s2+risk")])
def test_a_risk_aware_plan_is_made_on_the_forecast_the_request_carries(
        system: int, controller: str) -> None:
    """The straight line crosses the box: the plan that meets the zones goes round it."""
    s = service(system)
    s.prepare("m1", SPEC, MissionConfig.named(controller, seed=3))
    reply = handle(s, query(system, forecast=ForecastView(box_forecast(), 1)))
    assert isinstance(reply, plan_pb2.Plan) and reply.status == plan_pb2.PLAN_STATUS_OK
    plan = plan_convert.plan_from_msg(reply, system)
    assert plan.info["risk"] == "met"
    box = Rect(500.0, 500.0, 200.0, 140.0).polytope()
    assert min(box.distance(p) for p in plan.states[2:40, :2]) > 0.0


@pytest.mark.parametrize(("controller", "forecast", "reason", "match"), [
    ("s2", ForecastView(box_forecast(), 1), "invalid", "takes no forecast"),
    ("s2+risk", ForecastView(box_forecast(substep_s=1.0), 1), "out_of_range", "T_f 1 s"),
])
def test_a_forecast_that_does_not_fit_is_refused_and_counted(
        controller: str, forecast: ForecastView, reason: str, match: str) -> None:
    s = service(2)
    s.prepare("m1", SPEC, MissionConfig.named(controller, seed=3))
    before = rejected(2).get(reason, 0)
    reply = handle(s, query(2, forecast=forecast))
    assert isinstance(reply, common_pb2.Error), reply
    assert reply.code == common_pb2.ERROR_CODE_INVALID and match in reply.message
    assert rejected(2)[reason] == before + 1


def test_a_forecast_older_than_one_planned_on_is_stale() -> None:
    s = service(2)
    s.prepare("m1", SPEC, MissionConfig.named("s2+risk", seed=3))
    assert isinstance(handle(s, query(2, t=2, forecast=ForecastView(box_forecast(20), 1))),
                      plan_pb2.Plan)
    before = rejected(2).get("stale", 0)
    reply = handle(s, query(2, t=3, forecast=ForecastView(box_forecast(10), 1)))
    assert isinstance(reply, common_pb2.Error) and "older than 20" in reply.message
    assert rejected(2)["stale"] == before + 1
    # the same revision again (a retry of the step) is planned
    assert isinstance(handle(s, query(2, t=3, forecast=ForecastView(box_forecast(20), 1))),
                      plan_pb2.Plan)


def test_a_mission_prepared_again_flies_afresh() -> None:
    """A second flight of the same mission id and configuration (a prepare begins a flight):
    the forecast's revisions start again from 0, and the planner is a new one."""
    s = service(2)
    config = MissionConfig.named("s2+risk", seed=3)
    first = s.prepare("m1", SPEC, config).planner
    assert isinstance(handle(s, query(2, t=30, forecast=ForecastView(box_forecast(300), 1))),
                      plan_pb2.Plan)
    assert s.prepare("m1", SPEC, config).planner is not first
    reply = handle(s, query(2, t=0, forecast=ForecastView(box_forecast(0), 1)))
    assert isinstance(reply, plan_pb2.Plan) and reply.status == plan_pb2.PLAN_STATUS_OK


def test_a_risk_aware_method_without_a_forecast_plans_as_its_paper_method() -> None:
    a, b = service(2), service(2)
    a.prepare("m1", SPEC, MissionConfig.named("s2", seed=3))
    b.prepare("m1", SPEC, MissionConfig.named("s2+risk", seed=3))
    pa = plan_convert.plan_from_msg(handle(a, query(2)), 2)  # type: ignore[arg-type]
    pb = plan_convert.plan_from_msg(handle(b, query(2)), 2)  # type: ignore[arg-type]
    assert np.array_equal(pa.states, pb.states)
