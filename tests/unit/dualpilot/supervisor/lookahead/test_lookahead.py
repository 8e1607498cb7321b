"""The lookahead supervisor: what it calls sound on the known future, and the guard at work on
fires written out by hand (their forecast exact), against the concurrent supervisor."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalPlanners, LocalVehicle
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.dynamics import hover_state, rollout
from dualpilot.model.geometry import Rect
from dualpilot.plan import Plan, PlanStatus
from dualpilot.planners import build_planners
from dualpilot.spacetime.plan import FutureBoxes
from dualpilot.supervisor.lookahead.planning import SPACE_TIME, LookaheadSupervisor
from tests.support.scripted_fires import ScriptedFire, ScriptedFront, moving_box

START, GOAL = (50.0, 500.0), Rect(900.0, 500.0, 100.0, 100.0)


def config(name: str) -> MissionConfig:
    return MissionConfig.named(name, start=START, goal=GOAL)


def planning() -> LookaheadSupervisor:
    from dualpilot.supervisor.registry import build_supervisor

    cfg = config("lookahead")
    got = build_supervisor(cfg, cfg.spec())
    assert isinstance(got, LookaheadSupervisor)
    return got


def coasting(x: float, y: float, vx: float, vy: float, steps: int) -> Plan:
    """A plan that keeps its velocity for ``steps`` steps with no force... and brakes none."""
    spec = config("lookahead").spec()
    controls = np.tile(np.array([vx, vy]) * spec.dynamics.zeta * spec.dynamics.mass_kg /
                       spec.dynamics.dt_s, (steps, 1))
    return Plan(1, PlanStatus.OK, rollout(np.array([x, y, vx, vy]), controls, spec.dynamics),
                controls, 0.0)


def test_what_the_guard_calls_sound() -> None:
    """Clear boxes and no stall: sound. A box met within the next 10 flights: not. A plan
    that hovers 100 m from G (within 200 m of its centre) without ever landing in it:
    stalled, not sound. One that lands in G within 25 flights is checked until it does."""
    sup = planning()
    d = 20.5
    empty = FutureBoxes.of([np.empty((0, 4))] * 200)
    far = coasting(100.0, 500.0, 10.0, 0.0, 30)
    assert sup.sound(far, far.states[0], empty, d)
    wall = FutureBoxes.of([np.empty((0, 4))] * 5 + [np.array([[200.0, 0.0, 210.0, 1000.0]])]
                          * 195)
    assert not sup.sound(far, far.states[0], wall, d)  # flight 4 ends at 150 m, 5 at 160 m…
    hover = coasting(750.0, 500.0, 0.0, 0.0, 30)
    assert not sup.sound(hover, hover.states[0], empty, d)
    lands = coasting(700.0, 500.0, 15.0, 0.0, 40)  # in G (x ≥ 850) after 10 flights
    late = FutureBoxes.of([np.empty((0, 4))] * 12 + [np.array([[0.0, 0.0, 1.0, 1.0]])] * 188)
    assert sup.sound(lands, lands.states[0], late, d)


def two_gaps(closes: int) -> ScriptedFire:
    """A wall x ∈ [400, 600] across the area with gaps y ∈ [440, 560] (on the straight line,
    filled from sub-step ``closes``) and y ∈ [740, 860] (open)."""
    return ScriptedFire([
        ScriptedFront(0, moving_box(400.0, -100.0, 600.0, 440.0)),
        ScriptedFront(1, moving_box(400.0, 560.0, 600.0, 740.0)),
        ScriptedFront(2, moving_box(400.0, 860.0, 600.0, 1100.0)),
        ScriptedFront(3, moving_box(400.0, 440.0, 600.0, 560.0), born=closes),
    ])


def fly(name: str, fire: ScriptedFire) -> tuple[bool, str, list[str]]:
    cfg = config(name)
    spec = cfg.spec()
    state = hover_state(np.array(spec.start), spec.dynamics)
    planners = build_planners(spec, cfg.methods(), risk=cfg.risk)
    ports = MissionPorts(fire.port(), LocalPlanners(planners), LocalVehicle(state,
                                                                            spec.dynamics))
    result = Mission(cfg, spec, ports, state).run()
    return result.success, result.failure_cause, [r.plan_status for r in result.records]


@pytest.mark.parametrize("closes", [30])
def test_the_guard_sees_a_gap_close_that_the_planners_cannot(closes: int) -> None:
    """The gap on the straight line closes at sub-step 30, before any UAV can be through it
    (x ≥ 620 takes 40 steps from rest): the planners see only the wall of now and take it;
    the concurrent supervisor is caught in the gap. The lookahead supervisor's forecast (the
    fires' own, exact here) shows the gap closing: its space-time plan goes through the
    other gap and lands in G."""
    ok, cause, _ = fly("concurrent", two_gaps(closes))
    assert not ok and cause in ("fire_contact", "fire_while_planning", "step_limit")
    ok, cause, statuses = fly("lookahead", two_gaps(closes))
    assert ok, cause
    assert any(SPACE_TIME in s for s in statuses)
