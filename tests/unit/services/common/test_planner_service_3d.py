"""A planner service prepared for a 3-D mission plans 3-D requests from the wire and refuses,
counted, a malformed one or one of another dimension (services/common/planning.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import hover_state
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Prism
from dualpilot.model.zone_heights import BAND, ZoneHeights
from dualpilot.plan import Objective, Obstacles, PlanStatus
from dualpilot.planners import build_planner
from services.common import rejections, wire
from services.common.convert import plan as plan_convert
from services.common.planning import PlannerService
from services.msgs import common_pb2, plan_pb2

pytestmark = pytest.mark.timeout(120)

STAMP = wire.Stamper("supervisor", "u")
CONFIG = MissionConfig.named("s2", seed=3, settings=(("dim", 3),))
SPEC = CONFIG.spec()
#: a low front (30 m tall) on the way to the goal: the UAV at 50 m may fly over it
LOW = Prism(Rect(200.0, 200.0, 120.0, 120.0).polytope(), 0.0, 30.0)
KEY = "dualpilot/u/plan/system2"


def handle(s: PlannerService, m: plan_pb2.PlanRequest) -> plan_pb2.Plan | common_pb2.Error:
    return s.handle(m.SerializeToString(), wire.encoding_name(plan_pb2.PlanRequest))


def query(state: np.ndarray, u: np.ndarray, obstacles: Obstacles) -> plan_pb2.PlanRequest:
    req = PlanRequest(t=1, system=2, state=state, prev_control=u, obstacles=obstacles,
                      objective=Objective.MISSION_TIME)
    return plan_convert.plan_query_msg(plan_convert.PlanQuery(req, "m3", 1, 30.0), STAMP, 0.0)


def counted(reason: str) -> int:
    return rejections.REJECTED.snapshot().get(KEY, {}).get(reason, 0)


def test_a_3d_mission_is_planned_over_the_wire_and_a_bad_request_refused_counted() -> None:
    s = PlannerService(2, lambda spec, c: build_planner(2, spec, c.methods()[2]), "u")
    prep = plan_convert.prepare_msg(plan_convert.Prepare("m3", 2, SPEC, CONFIG), STAMP, 0.0)
    ready = handle(s, prep)
    assert isinstance(ready, plan_pb2.Plan) and ready.message == "prepared"
    assert s.missions["m3"].spec == SPEC  # the band and goal reading of the configuration
    x0 = hover_state(SPEC.start_position, SPEC.dynamics)
    reply = handle(s, query(x0, np.zeros(3), (LOW,)))
    assert isinstance(reply, plan_pb2.Plan), reply
    plan = plan_convert.plan_from_msg(reply, 2, dim=3)
    assert plan.status is PlanStatus.OK, plan.message
    assert plan.states.shape[1] == 6 and plan.controls.shape[1] == 3
    assert np.array_equal(plan.states[0], x0)
    # a front upside down (bottom above top): refused, counted under the plan key
    bad = query(x0, np.zeros(3), (LOW,))
    bad.obstacle_altitudes_m[:] = [40.0, 30.0]
    before = counted("out_of_range")
    err = handle(s, bad)
    assert isinstance(err, common_pb2.Error) and err.code == common_pb2.ERROR_CODE_INVALID
    assert "not below its top" in err.message and counted("out_of_range") == before + 1
    # a planar request for the 3-D mission: refused, counted
    planar = query(hover_state(np.array(SPEC.start), SPEC.dynamics.__class__()), np.zeros(2),
                   (LOW.base,))
    err = handle(s, planar)
    assert isinstance(err, common_pb2.Error)
    assert "dim 2 for a mission of dim 3" in err.message
    assert counted("out_of_range") == before + 2


def test_the_prepared_spec_carries_the_risk_zones_heights_of_its_configuration() -> None:
    """``risk_zone_height=fire`` reaches a planner service by the configuration: its spec's
    zone heights are the configuration's (fronts U[10, 40] m: the uniform law), and "band"
    (the default) leaves them as tall as every altitude."""
    s = PlannerService(2, lambda spec, c: build_planner(2, spec, c.methods()[2], risk=True),
                       "u")
    for reading, want in (("fire", ZoneHeights(uniform=(10.0, 40.0))), ("band", BAND)):
        config = MissionConfig.named("s2+risk", seed=3, settings=(
            ("dim", 3), ("fire_height", "uniform"), ("fire_height_min_m", 10.0),
            ("fire_height_max_m", 40.0), ("risk_zone_height", reading)))
        spec = config.spec()
        assert spec.zone_heights == want
        on_wire = dataclasses.replace(spec, zone_heights=BAND)  # the spec message has none
        prep = plan_convert.prepare_msg(plan_convert.Prepare(f"z-{reading}", 2, on_wire, config),
                                        STAMP, 0.0)
        ready = handle(s, prep)
        assert isinstance(ready, plan_pb2.Plan) and ready.message == "prepared"
        assert s.missions[f"z-{reading}"].spec == spec
