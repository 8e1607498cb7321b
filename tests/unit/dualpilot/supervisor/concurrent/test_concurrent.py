"""The concurrent supervisor on hand-built scenarios (no random fires: p_b = 0, fronts placed).

Paper timing: System 1 answers in 155 ms (one fire sub-step, a step of 1.5 s of
simulated time), System 2 in 5 s, so a System 2 plan launched at step t is due
at step t + ⌈5 / 1.5⌉ = t + 4: launched at 0 from System 1's predicted state,
adopted at 4, the next launched at 4 and due at 8.
"""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.mission.local import LocalFires, LocalPlanners, LocalVehicle
from dualpilot.mission.params import Controller
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.dynamics import hover_state
from dualpilot.model.fire import FireParams
from dualpilot.plan import Plan, PlanStatus
from dualpilot.planners import Planner, build_planner, build_planners
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.planning import ConcurrentSupervisor
from dualpilot.supervisor.concurrent.rule import ConcurrentParams, steps_until, wait_hazard
from tests.support.missions import config_for

#: no random births, nothing dies out, placed fronts 60 m square
QUIET = FireParams(p_birth=0.0, p_survive=1.0, side_min_m=60.0, side_max_m=60.0)


class NudgedVehicle(LocalVehicle):
    """Eq. (1), but pushed by ``offset`` (m, east) after the flight of step ``at``."""

    def __init__(self, state: np.ndarray, spec: MissionSpec, at: int, offset: float):
        super().__init__(state, spec.dynamics)
        self.at, self.offset, self.steps = at, offset, 0

    def observe(self) -> np.ndarray:
        x = super().observe()
        if self.steps == self.at:
            self.state[0] += self.offset
            x = self.state.copy()
        self.steps += 1
        return x


class CutPlanners(LocalPlanners):
    """The planners in this process, System 2 cut off while ``cut`` (as behind a dead link:
    unavailable, and what it was asked before never answers, a TIMEOUT)."""

    def __init__(self, planners: dict[int, Planner]):
        super().__init__(planners)
        self.cut = False

    def available(self, system: int) -> bool:
        return not (system == 2 and self.cut) and super().available(system)

    def collect(self, ticket: object) -> Plan:
        if self.cut:
            return Plan.failed(2, PlanStatus.TIMEOUT, 0.0, "no answer: cut off")
        return super().collect(ticket)


def mission(seed: int = 3, vehicle: LocalVehicle | None = None,
            params: ConcurrentParams | None = None, name: str = "concurrent",
            spec: MissionSpec | None = None) -> Mission:
    spec = spec or MissionSpec(seed=seed)
    x0 = hover_state(np.array(spec.start), spec.dynamics)
    planners = build_planners(spec, {1: "rrt+du", 2: "fast"})
    config = config_for(spec, name, fire=QUIET, concurrent=params or ConcurrentParams())
    ports = MissionPorts(LocalFires(spec, QUIET), CutPlanners(planners),
                         vehicle or LocalVehicle(x0, spec.dynamics))
    return Mission(config, spec, ports, x0)


def cut(m: Mission, on: bool) -> None:
    assert isinstance(m.planners, CutPlanners)
    m.planners.cut = on


def fly(m: Mission, steps: int) -> list:
    return [m.step() for _ in range(steps)]


def front_ahead(m: Mission, steps_ahead: int) -> None:
    """A front centred on the flown plan's position ``steps_ahead`` steps from now."""
    assert isinstance(m.supervisor, ConcurrentSupervisor) and m.supervisor.flown is not None
    plan = m.supervisor.flown.plan
    centre = plan.states[m.supervisor.flown.offset + steps_ahead, :2]
    fires = m.fires
    assert isinstance(fires, LocalFires)
    fires.field.spawn(fires.rng, m.result.steps, center=(float(centre[0]), float(centre[1])))


def test_system2_is_never_waited_for_and_its_plans_are_adopted_when_due() -> None:
    assert steps_until(5.0, 1.5) == 4
    recs = fly(mission(), 9)
    assert [r.system for r in recs] == [1, 1, 1, 1, 2, 2, 2, 2, 2]
    assert {r.fire_substeps for r in recs} == {1}  # the UAV waits for nothing slower than S1
    assert "s2:launched" in recs[0].plan_status and "s2:adopted" in recs[4].plan_status
    assert "s2:adopted" in recs[8].plan_status
    # no planner asked while a plan is kept: no wait at all, still one sub-step (fair timing)
    assert recs[5].plan_status == "" and recs[5].planning_time_s == 0.0


def test_a_front_near_the_uav_makes_system1_fly_from_that_step() -> None:
    m = mission()
    fly(m, 8)
    assert isinstance(m.supervisor, ConcurrentSupervisor) and m.supervisor.flown is not None
    assert m.supervisor.flown.plan.system == 2
    front_ahead(m, 6)  # ≈ 90 m ahead on the System 2 plan, unknown to it
    rec = m.step()
    assert rec is not None
    assert rec.system == 1 and "s1:ok" in rec.plan_status, rec.plan_status
    # System 2, restarted with the front, offers its plan when due; it flies again once the
    # front no longer holds the attention on response time (Σ p̄ Q favours System 2)
    later = fly(m, 30)
    assert "s2:restarted" in rec.plan_status or any(
        r is not None and "s2:launched" in r.plan_status for r in later)
    assert any(r is not None and r.system == 2 for r in later), later


def test_a_plan_that_became_unsafe_while_deliberated_is_refused_at_adoption() -> None:
    m = mission()
    fly(m, 8)  # at step 8 the plan launched at step 4 is due
    assert isinstance(m.supervisor, ConcurrentSupervisor) and m.supervisor.pending is not None
    assert m.supervisor.pending.due_t == 8
    front_ahead(m, 5)  # ignites on its path while it was being computed
    rec = m.step()
    assert rec is not None
    assert "s2:unsafe_at_adoption" in rec.plan_status, rec.plan_status
    assert rec.system == 1


@pytest.mark.parametrize(("offset", "expected"), [(0.5, "s2:adopted"), (8.0, "s2:stale_start")])
def test_a_plan_for_a_state_the_uav_did_not_reach_is_reanchored_or_refused(
        offset: float, expected: str) -> None:
    spec = MissionSpec(seed=3)
    x0 = hover_state(np.array(spec.start), spec.dynamics)
    m = mission(vehicle=NudgedVehicle(x0, spec, at=6, offset=offset))
    recs = fly(m, 9)
    assert expected in recs[8].plan_status, recs[8].plan_status
    if expected == "s2:adopted":  # re-anchored: it starts where the UAV is
        assert isinstance(m.supervisor, ConcurrentSupervisor) and m.supervisor.flown is not None
        assert np.allclose(recs[8].state[:2], recs[8].planned_positions[0])
        assert recs[8].system == 2
    else:
        assert ConcurrentParams().reanchor_tol_m < offset


def test_the_handover_to_system1_is_smooth() -> None:
    """At the S2 → S1 handover the Δu tracker jumps less than half the paper's tracker from
    the same state and u_{t−1} (dualpilot/system1/lqr.py states the bound
    ‖u_0 − u_{t−1}‖ ≤ k_v‖e_v,0‖ + k_u‖u_{t−1} − u_ff,0‖, k_v = 0.29, k_u = 0.59)."""
    m = mission()
    recs = fly(m, 8)
    front_ahead(m, 6)
    state, prev = m.state.copy(), m.prev_control.copy()
    obstacles = m.fires.snapshot().obstacles_for(state[:2], m.spec.clearance_m)
    rec = m.step()
    assert rec is not None and rec.system == 1 and recs[-1].system == 2
    jump = float(np.linalg.norm(rec.control - prev))
    plain = build_planner(1, m.spec, "rrt").plan(state, obstacles, prev_control=prev)
    assert plain.ok
    assert jump < 0.5 * float(np.linalg.norm(plain.controls[0] - prev)), (jump, plain.controls[0])


def test_the_hazard_of_waiting() -> None:
    """P(a front within reach during n sub-steps): (2·(125 + 20) m)² = 84,100 m² of 1 km²,
    times p_b = 0.1, is 0.841 % a sub-step; ten sub-steps (System 2's 5 s): 1 − 0.99159^10."""
    f = FireParams()
    assert wait_hazard(1, f, 1000.0, 20.0) == pytest.approx(0.00841)
    assert wait_hazard(10, f, 1000.0, 20.0) == pytest.approx(1 - (1 - 0.00841) ** 10)
    assert wait_hazard(0, f, 1000.0, 20.0) == 0.0
    with pytest.raises(ValueError, match="n_substeps"):
        wait_hazard(-1, f, 1000.0, 20.0)


def test_only_the_cognitive_controller_takes_the_concurrent_supervisor() -> None:
    spec = MissionSpec()
    with pytest.raises(ValueError, match="concurrent supervisor does not run s1"):
        config_for(spec, Controller.S1, supervisor="concurrent")
    with pytest.raises(ValueError,
                       match="unknown supervisor 'ours'; installed: paper, concurrent, lookahead"):
        config_for(spec, Controller.CC, supervisor="ours")


def test_without_system2_system1_plans_every_step_and_system2_flies_again_once_back() -> None:
    """``s2_unavailable = "system1"``: System 2 flies from step 4 (the first test); cut off
    after step 8 (its plan launched at 8 is due at 12), every step plans with System 1 and
    flies it, System 2 is not asked, the plan due at 12 is a TIMEOUT; back at step 15, it is
    launched at once and adopted when due, 4 steps later (19)."""
    m = mission(params=ConcurrentParams(s2_unavailable="system1"))
    before = fly(m, 9)
    assert before[8].system == 2 and "s2:adopted" in before[8].plan_status
    cut(m, True)
    during = fly(m, 6)  # steps 9..14
    assert [r.system for r in during] == [1] * 6
    assert all("s1:ok" in r.plan_status and "s2:launched" not in r.plan_status
               for r in during), [r.plan_status for r in during]
    assert all(r.planning_time_s > 0 for r in during)  # a fresh plan each step: S1's 155 ms
    assert "s2:timeout" in during[12 - 9].plan_status, during[3].plan_status
    cut(m, False)
    after = fly(m, 5)  # steps 15..19
    assert "s2:launched" in after[0].plan_status, after[0].plan_status
    assert "s2:adopted" in after[4].plan_status and after[4].system == 2, after[4].plan_status


def test_the_lookahead_supervisor_flies_system1_without_system2_too() -> None:
    """It chooses through the concurrent supervisor's rule: cut off after step 8, System 1
    plans every step (or the guard's own plan flies, answered as System 1's)."""
    m = mission(params=ConcurrentParams(s2_unavailable="system1"), name="lookahead")
    assert fly(m, 9)[8].system == 2
    cut(m, True)
    during = fly(m, 6)
    assert [r.system for r in during] == [1] * 6
    assert all("s1:ok" in r.plan_status and "s2:launched" not in r.plan_status
               for r in during), [r.plan_status for r in during]


def test_by_default_the_rest_of_the_system2_plan_flies_while_system2_is_unavailable() -> None:
    """``s2_unavailable = "keep"`` (the default, unchanged): cut off after step 8, the kept
    System 2 plan flies on, no planner is asked (it is safe: no front), System 2 not launched."""
    assert ConcurrentParams().s2_unavailable == "keep"
    m = mission()
    fly(m, 9)
    cut(m, True)
    during = fly(m, 6)
    assert [r.system for r in during] == [2] * 6
    assert [r.plan_status for r in during] == ["", "", "", "s2:timeout", "", ""]
    with pytest.raises(ValueError, match="s2_unavailable must be 'keep' or 'system1'"):
        ConcurrentParams(s2_unavailable="ground")  # type: ignore[arg-type]
