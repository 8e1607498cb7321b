"""The run-time monitor (dualpilot/mission/monitor.py): each check against a hand-made plan."""

from __future__ import annotations

import re

import numpy as np
import pytest

from dualpilot.mission import monitor
from dualpilot.mission.local import LocalPlanners, local_mission
from dualpilot.mission.params import Controller, Timing
from dualpilot.model.dynamics import DynamicsParams, hover_state, rollout
from dualpilot.model.geometry import Rect
from dualpilot.plan import Plan, PlanStatus
from dualpilot.spec import MissionSpec
from tests.support.missions import config_for

SPEC = MissionSpec()
DYN = DynamicsParams()


def straight(x0: np.ndarray, u: tuple[float, float] = (2.0, 2.0), T: int = 5) -> tuple[
        np.ndarray, np.ndarray]:
    controls = np.tile(np.array(u, dtype=float), (T, 1))
    return rollout(x0, controls, DYN), controls


X0 = hover_state(np.array([100.0, 100.0]), DYN)


def test_an_honest_straight_plan_passes() -> None:
    states, controls = straight(X0)
    v = monitor.check_plan(states, controls, X0, (), SPEC)
    assert v.ok, v.reason


@pytest.mark.parametrize(("mutate", "match"), [
    (lambda s, c: (s + np.array([0.5, 0, 0, 0]), c), "starts"),
    (lambda s, c: (s, c * 1.0 + np.array([[0.0, 0.1]] * len(c))), "Eq. \\(1\\)"),
    (lambda s, c: (rollout(X0, c * 0 + 9999.0, DYN), c * 0 + 9999.0), "exceeds 7.5 N"),
    (lambda s, c: (s[:, :3], c), "bad shapes"),
    (lambda s, c: (s * np.nan, c), "non-finite"),
])
def test_each_violation_is_rejected_with_its_reason(mutate, match) -> None:  # type: ignore[no-untyped-def]
    states, controls = straight(X0)
    s, c = mutate(states, controls)
    v = monitor.check_plan(s, c, X0, (), SPEC)
    assert not v.ok
    assert re.search(match, v.reason), v.reason


def test_velocity_limit_and_area() -> None:
    fast = X0.copy()
    fast[2:] = [14.9, 0.0]
    states, controls = straight(fast, (7.5, 0.0), T=10)
    v = monitor.check_plan(states, controls, fast, (), SPEC)
    assert not v.ok and "|v|" in v.reason
    edge = hover_state(np.array([999.0, 500.0]), DYN)
    states, controls = straight(edge, (5.0, 0.0), T=3)
    v = monitor.check_plan(states, controls, edge, (), SPEC)
    assert not v.ok and "area" in v.reason


def test_clearance_from_the_obstacles_the_step_sent() -> None:
    states, controls = straight(X0, (2.0, 2.0), T=6)
    end = states[-1, :2]
    # a fire region 10 m beyond the end of the planned polyline: closer than d_safe = 20 m
    region = Rect(float(end[0]) + 15.0, float(end[1]), 10.0, 10.0).polytope()
    v = monitor.check_plan(states, controls, X0, (region,), SPEC)
    assert not v.ok and "d_safe" in v.reason and v.clearance_m == pytest.approx(10.0, abs=1e-6)
    far = Rect(float(end[0]) + 45.0, float(end[1]), 10.0, 10.0).polytope()
    assert monitor.check_plan(states, controls, X0, (far,), SPEC).ok


class Byzantine:
    """A planner whose OK plans head for the centre of a region 1000 m away (not from x_t)."""

    system, method = 2, "byzantine"

    def plan(self, state, hulls, objective=None, prev_control=None):  # type: ignore[no-untyped-def]
        states, controls = straight(hover_state(np.array([500.0, 500.0]), DYN))
        return Plan(system=2, status=PlanStatus.OK, states=states, controls=controls,
                    compute_time_s=0.0)


def test_the_step_never_flies_a_rejected_plan_and_records_why() -> None:
    from dualpilot.planners import build_planners

    spec = MissionSpec(seed=3)
    honest = build_planners(spec)
    mission = local_mission(config_for(spec, Controller.S2, timing=Timing.PAPER),
                            planners={1: honest[1], 2: Byzantine()})
    assert isinstance(mission.planners, LocalPlanners)
    for _ in range(3):
        rec = mission.step()
        assert rec is not None
        assert rec.system == 0 and "s2:unsafe[monitor: starts" in rec.plan_status
        assert np.all(np.abs(rec.control) <= DYN.u_max_n)
