"""StepPlans (supervisor/plans, the live view's plans of a step): round trip and each rejection."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from dualpilot.mission.answers import parse_answers
from dualpilot.mission.result import StepRecord
from dualpilot.model.fire import FireSnapshot
from dualpilot.plan import Objective
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision
from services.common import rejections, wire
from services.common.convert import supervisor as supervisor_convert
from services.msgs import supervisor_pb2

PLAN = np.array([[50.0, 50.0], [65.0, 64.5], [80.0, 79.0]])


def record(plan_status: str, system: int, planned: np.ndarray = PLAN) -> StepRecord:
    d = Decision(t=7, d_t=math.inf, xi=np.ones(3), p=np.full(3, 1 / 3), attention=1,
                 psi=np.array([0.5, 0.5]), system=1, objective=Objective.MISSION_TIME)
    return StepRecord(t=7, state=np.array([50.0, 50.0, 0.0, 0.0]), control=np.zeros(2),
                      decision=d, system=system, answers=parse_answers(plan_status),
                      planned_positions=planned if system else np.empty((0, 2)),
                      planning_time_s=0.155, fire_substeps=1, d_t=math.inf, fires_active=0,
                      snapshot=FireSnapshot((), ()), time_s=42.5)


def roundtrip(rec: StepRecord) -> supervisor_convert.StepPlans:
    m = supervisor_convert.step_plans_msg(rec, "m1", MissionSpec(seed=9),
                                      wire.Stamper("supervisor", "u"), 43.0)
    return supervisor_convert.step_plans_from_msg(wire.parse(m.SerializeToString(),
                                                         supervisor_pb2.StepPlans))


def test_step_plans_round_trip() -> None:
    got = roundtrip(record("s2:timeout;s1:unsafe[monitor: clearance 3.2 m];s1:ok", 1))
    assert (got.mission_id, got.step, got.time_s, got.flown) == ("m1", 7, 42.5, 1)
    assert got.spec == MissionSpec(seed=9)
    s1, s2 = got.plans
    assert (s1.system, s1.status, s1.flown) == (1, "unsafe[monitor: clearance 3.2 m];ok", True)
    assert s1.positions.tolist() == PLAN.tolist()
    assert (s2.system, s2.status, s2.flown, s2.positions.shape) == (2, "timeout", False, (0, 2))


def test_a_braking_step_and_a_system_not_asked() -> None:
    s1, s2 = roundtrip(record("s1:no_path", 0)).plans
    assert (s1.status, s1.flown, len(s1.positions)) == ("no_path", False, 0)
    assert (s2.status, s2.flown) == ("", False)


def test_a_kept_plan_flown_without_a_status() -> None:
    """The concurrent supervisor flies a kept plan: no status for it at this step."""
    got = roundtrip(record("s1:ok", 2))
    assert (got.plans[1].status, got.plans[1].flown) == ("", True)
    assert got.plans[1].positions.tolist() == PLAN.tolist()


def _msg() -> supervisor_pb2.StepPlans:
    return supervisor_convert.step_plans_msg(record("s2:timeout;s1:ok", 1), "m1", MissionSpec(),
                                         wire.Stamper("supervisor", "u"), 1.0)


@pytest.mark.parametrize(("edit", "match"), [
    (lambda m: m.ClearField("mission"), "without the mission spec"),
    (lambda m: setattr(m.plans[0], "system", 3), "plan of system 3"),
    (lambda m: setattr(m.plans[0], "system", 1), "plan of system 1"),  # twice
    (lambda m: setattr(m.plans[0], "status", "Timeout!"), "is not a status"),
    (lambda m: setattr(m.plans[0], "status", ""), "is not a status"),
    (lambda m: m.plans[0].positions_m.extend([1.0, 2.0]), "which was not flown"),
    (lambda m: m.plans[1].ClearField("positions_m"), "positions are missing"),
    (lambda m: m.plans[1].positions_m.append(3.0), "multiple of 2"),
    (lambda m: m.plans[1].positions_m.__setitem__(0, math.nan), "finite"),
    (lambda m: setattr(m, "flown_system", 4), "out of range"),
    (lambda m: setattr(m, "step_time_s", -1.0), "step_time_s"),
])
def test_bad_step_plans_are_rejected(edit: Callable[[supervisor_pb2.StepPlans], object],
                                     match: str) -> None:
    m = _msg()
    edit(m)
    with pytest.raises(rejections.CodecError, match=match):
        supervisor_convert.step_plans_from_msg(m)


def test_mission_events_are_checked() -> None:
    ok = supervisor_pb2.MissionEvent(kind=supervisor_pb2.MISSION_EVENT_KIND_STEP, step=3)
    assert supervisor_convert.check_mission_event(ok) is ok
    step = supervisor_pb2.MISSION_EVENT_KIND_STEP
    unknown = supervisor_pb2.MissionEvent()
    unknown.ParseFromString(b"\x10\x63")  # kind = 99: a value this build does not know
    for bad, match in ((supervisor_pb2.MissionEvent(), "unknown mission event kind"),
                       (unknown, "unknown mission event kind"),
                       (supervisor_pb2.MissionEvent(kind=step, flown_system=5), "flown_system"),
                       (supervisor_pb2.MissionEvent(kind=step, controller="x" * 17), "longer")):
        with pytest.raises(rejections.CodecError, match=match):
            supervisor_convert.check_mission_event(bad)
