"""The planner services over Zenoh: plans for valid requests, error replies for bad ones."""

from __future__ import annotations

import queue
from typing import Any

import numpy as np
import pytest
import zenoh

from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.plan import Objective, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.verify import verify_trajectory
from services.common import bus, keys, wire
from services.common.convert import plan as plan_convert
from services.common.convert import vehicle as vehicle_convert
from services.msgs import common_pb2, plan_pb2
from tests.support.missions import config_for

pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope="module")
def planners(services: Any, liveliness: bus.Liveliness) -> Any:
    services.start("system1")
    services.start("system2")
    assert liveliness.wait_for(["system1", "system2"], 90), (
        services.log("system1")[-2000:] + services.log("system2")[-2000:])
    return services


def raw_query(session: Any, key: str, payload: bytes, timeout_s: float = 30.0) -> Any:
    """Send raw bytes as a query; return the first Reply."""
    replies: queue.Queue[Any] = queue.Queue()
    session.get(key, zenoh.handlers.Callback(replies.put, lambda: replies.put(None)),
                payload=payload, timeout=timeout_s)
    reply = replies.get(timeout=timeout_s + 5)
    assert reply is not None, f"no reply on {key}"
    return reply


def request(system: int, mission_id: str = "itest-mission", prepare: bool = False,
            revision: int = 0, **state: float) -> bytes:
    """A plan request from (50, 50) around one fire at (500, 500); the spec if ``prepare``."""
    stamper = wire.Stamper("test", "itest")
    if prepare:
        spec = MissionSpec(seed=7)
        prep = plan_convert.Prepare(mission_id, system, spec, config_for(spec), deadline_s=60.0)
        return plan_convert.prepare_msg(prep, stamper, 0.0).SerializeToString()
    x = np.array([state.get("east", 50.0), state.get("north", 50.0), 0.0, 0.0])
    req = PlanRequest(t=0, system=system, state=x, prev_control=np.zeros(2),
                      obstacles=tuple(f.hull for f in _one_fire()),
                      objective=Objective.MISSION_TIME)
    query = plan_convert.PlanQuery(req, mission_id, 0, 60.0, revision)
    return plan_convert.plan_query_msg(query, stamper, 0.0).SerializeToString()


def prepare(session: Any, uav: str, system: int, mission_id: str = "itest-mission") -> None:
    reply = raw_query(session, keys.plan(uav, system), request(system, mission_id, prepare=True))
    assert reply.ok is not None, common_pb2.Error.FromString(reply.err.payload.to_bytes())
    assert plan_pb2.Plan.FromString(reply.ok.payload.to_bytes()).message == "prepared"


def error_of(reply: Any) -> common_pb2.Error:
    assert reply.err is not None, "expected an error reply"
    return common_pb2.Error.FromString(reply.err.payload.to_bytes())


@pytest.mark.parametrize("system", [1, 2])
def test_malformed_payload_gets_an_error_reply(planners: Any, session: Any,
                                               liveliness: bus.Liveliness, system: int) -> None:
    key = keys.plan(planners.uav, system)
    reply = raw_query(session, key, b"\x0a\xff\xff\xff not a protobuf")
    assert reply.ok is None, "a malformed request must not get a plan"
    err = common_pb2.Error.FromString(reply.err.payload.to_bytes())
    assert err.code == common_pb2.ERROR_CODE_MALFORMED
    assert "does not parse" in err.message
    assert str(reply.err.encoding) == "application/protobuf;dualpilot.v1.Error"
    # still alive and answering
    assert f"system{system}" in liveliness.alive
    prepare(session, planners.uav, system)
    reply = raw_query(session, key, request(system))
    assert reply.ok is not None


def test_invalid_values_get_an_error_reply(planners: Any, session: Any) -> None:
    msg = plan_pb2.PlanRequest.FromString(request(1))
    msg.state.east_m = float("nan")
    reply = raw_query(session, keys.plan(planners.uav, 1), msg.SerializeToString())
    err = common_pb2.Error.FromString(reply.err.payload.to_bytes())
    assert err.code == common_pb2.ERROR_CODE_INVALID and "finite" in err.message
    msg = plan_pb2.PlanRequest.FromString(request(2))  # a System 2 request sent to System 1
    reply = raw_query(session, keys.plan(planners.uav, 1), msg.SerializeToString())
    assert "sent to system 1" in common_pb2.Error.FromString(reply.err.payload.to_bytes()).message
    assert "rejected PlanRequest" in planners.log("system1")


@pytest.mark.parametrize("system", [1, 2])
def test_a_mission_is_prepared_once_then_planned(planners: Any, session: Any,
                                                 system: int) -> None:
    """Without its spec a planner cannot plan: an UNPREPARED error, so the supervisor prepares."""
    key = keys.plan(planners.uav, system)
    err = error_of(raw_query(session, key, request(system, mission_id=f"never-{system}")))
    assert err.code == common_pb2.ERROR_CODE_UNPREPARED and "not prepared" in err.message
    prepare(session, planners.uav, system, f"never-{system}")
    assert raw_query(session, key, request(system, mission_id=f"never-{system}")).ok is not None


@pytest.mark.parametrize("system", [1, 2])
def test_valid_request_gets_a_verified_plan(planners: Any, session: Any, system: int) -> None:
    prepare(session, planners.uav, system)
    reply = raw_query(session, keys.plan(planners.uav, system), request(system))
    plan = plan_convert.plan_from_msg(plan_pb2.Plan.FromString(reply.ok.payload.to_bytes()),
                                        system)
    assert plan.status is PlanStatus.OK, plan.message
    assert plan.compute_time_s > 0
    assert np.array_equal(plan.states[0], [50.0, 50.0, 0.0, 0.0])
    hulls = tuple(f.hull for f in _one_fire())
    verdict = verify_trajectory(plan.states, plan.controls, hulls, DynamicsParams(),
                                MissionSpec().d_safe_m)
    assert verdict.ok, verdict.reason


def test_a_certified_plan_carries_its_bound_over_zenoh(planners: Any, session: Any) -> None:
    """System 2 prepared with the "certified" method: the plan's bound and certified gap
    travel with it (plan.proto fields 15, 16) and pass the codec's checks."""
    mission_id = "itest-certified"
    spec = MissionSpec(seed=7)
    prep = plan_convert.Prepare(mission_id, 2, spec,
                                config_for(spec, system2_method="certified"), deadline_s=60.0)
    key = keys.plan(planners.uav, 2)
    stamper = wire.Stamper("test", "itest")
    reply = raw_query(session, key, plan_convert.prepare_msg(prep, stamper, 0.0)
                      .SerializeToString())
    assert reply.ok is not None
    msg = plan_pb2.Plan.FromString(
        raw_query(session, key, request(2, mission_id=mission_id)).ok.payload.to_bytes())
    assert msg.HasField("bound") and msg.HasField("certified_gap")
    plan = plan_convert.plan_from_msg(msg, 2)
    assert plan.status is PlanStatus.OK, plan.message
    assert plan.cost is not None and plan.bound is not None and plan.bound <= plan.cost
    assert plan.certified_gap == msg.certified_gap and msg.certified_gap <= 0.01


def test_a_planner_value_error_is_an_invalid_input_plan(planners: Any, session: Any) -> None:
    """A state inside a fire reaches System 1, which refuses it: INVALID_INPUT, not a crash."""
    prepare(session, planners.uav, 1)
    reply = raw_query(session, keys.plan(planners.uav, 1), request(1, east=500.0, north=500.0))
    plan = plan_convert.plan_from_msg(plan_pb2.Plan.FromString(reply.ok.payload.to_bytes()), 1)
    assert plan.status is PlanStatus.INVALID_INPUT
    assert not plan.ok and len(plan.states) == 0


def test_operator_waypoints_reach_system1(planners: Any, session: Any, wait_until: Any) -> None:
    """Waypoints published on operator/waypoints (revision 1) are used by the next plan that
    names that revision; until the service has it, such a plan is refused as UNPREPARED."""
    wps = np.array([[900.0, 100.0], [900.0, 900.0]])  # around the fire at (500, 500)
    key = keys.plan(planners.uav, 1)
    prepare(session, planners.uav, 1, "with-operator")
    err = error_of(raw_query(session, key, request(1, "with-operator", revision=1)))
    assert err.code == common_pb2.ERROR_CODE_UNPREPARED and "revision 1" in err.message
    msg = vehicle_convert.waypoints_msg(vehicle_convert.Waypoints("with-operator", 1, wps),
                                       wire.Stamper("operator", planners.uav))
    replies: list[Any] = []

    def published_and_used() -> bool:  # re-publish until a plan uses them (no fixed sleep)
        bus.put(session, keys.waypoints(planners.uav), msg)
        replies.append(raw_query(session, key, request(1, "with-operator", revision=1)))
        return replies[-1].ok is not None

    assert wait_until(published_and_used, 10)
    plan = plan_convert.plan_from_msg(plan_pb2.Plan.FromString(replies[-1].ok.payload.to_bytes()),
                                        1)
    assert plan.status is PlanStatus.OK and plan.info.get("source") == "operator"
    assert plan.path is not None and np.allclose(plan.path[1:], wps)


def _one_fire() -> list[Any]:
    rng = np.random.default_rng(5)
    field = FireField(params=FireParams(p_survive=1.0))
    field.spawn(rng, 0, center=(500.0, 500.0))
    return field.fronts
