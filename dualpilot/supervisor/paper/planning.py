"""The paper's supervisor in the mission step (Sec. III-C, IV): wait for the chosen plan.

Each step the supervisor draws A_t, updates Ψ_t (Eq. Psi) and picks S_t (Eq. maxPsi);
``s1`` / ``s2`` run the same supervisor but force the system, so all three controllers
see the same attention stream. The chosen system plans from the current state while
the UAV hovers (``cc`` with ``fallback``: the other one if the plan is not OK); the
step's planning interval is the sum of the answers' T_s. Every plan is checked by the
run-time monitor before it can be flown. The rule is the decision dynamics of
:mod:`dualpilot.supervisor.paper.decision`; :class:`PaperSupervisor` is the registry's
"paper" supervisor (:data:`ENTRY`), the default.
"""

from __future__ import annotations

from dualpilot.mission import monitor
from dualpilot.mission.answers import Answer, SystemStatus
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.stale_fire import grown_snapshot
from dualpilot.plan import Plan
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.interface import (
    Planned,
    StepView,
    Supervisor,
    SupervisorEntry,
    SupervisorSettings,
)


def planning_time(plan: Plan, timing: Timing, params: MissionParams) -> float:
    """T_s of a plan (s): measured, or the paper's 155 ms / 5 s for System 1 / 2."""
    if timing is Timing.PAPER:
        return params.paper_planning_time_s[plan.system - 1]
    return plan.compute_time_s


def planning_order(controller: Controller, chosen: int, params: MissionParams) -> list[int]:
    """Systems to ask this step: the one in control, then (CC with fallback) the other."""
    wanted = {Controller.CC: chosen, Controller.S1: 1, Controller.S2: 2}[controller]
    fallback = params.fallback and controller is Controller.CC
    return [wanted, 3 - wanted] if fallback else [wanted]


class PaperSupervisor:
    """The paper's supervisor: the system in control plans, the UAV waits for it."""

    def plan(self, step: StepView, t: int, d_t: float, snapshot: FireSnapshot) -> Planned:
        """Decide S_t, then ask the systems in :func:`planning_order` for the first OK,
        verified plan."""
        decision = step.decision_dynamics.decide(t, d_t)
        order = planning_order(step.controller, decision.system, step.params)
        if step.observer is not None:
            step.observer.decided(t, decision, order[0])
        seen = grown_snapshot(snapshot, step.fires.margin_m())  # stale data: grown
        obstacles = seen.obstacles(step.state[: step.spec.dim], step.spec.clearance_m)
        got = Planned(decision, None)
        for system in order:
            if not step.planners.available(system):
                got.answers.append(Answer(system, SystemStatus.UNAVAILABLE))
                continue
            request = PlanRequest(
                t=t, system=system, state=step.state.copy(), prev_control=step.prev_control,
                obstacles=obstacles, objective=decision.objective,
                forecast=step.forecast_view(system))
            candidate = step.planners.plan(request)
            step.record_time(system, candidate.compute_time_s)
            got.planning_s += planning_time(candidate, step.timing, step.params)
            verdict = monitor.check(candidate, step.state, obstacles, step.spec) if (
                candidate.ok) else None
            if verdict is not None and verdict.ok:  # and the forecast's zones it says it met
                verdict = monitor.check_risk(candidate, request.forecast, step.spec)
            if verdict is not None and not verdict.ok:  # never flown: a failed plan
                got.answers.append(monitor.refusal(system, verdict))
                continue
            got.answers.append(Answer(system, SystemStatus.of(candidate.status)))
            if candidate.ok:
                got.plan, got.forecast = candidate, request.forecast
                return got
        return got

    def after_flight(self, system: int, p0: Array, p1: Array, du2: float) -> None:
        """Nothing: the paper's supervisor keeps no state across flights but Ψ."""


def _build(config: SupervisorSettings, spec: MissionSpec) -> Supervisor:
    return PaperSupervisor()


#: The registry's "paper" supervisor: every controller, System 1 by Alg. 1 ("rrt"), in 2-D
#: and 3-D (its rule takes d_t as a number; its obstacles are the snapshot's of the
#: dimension, and the monitor checks the plans of either).
ENTRY = SupervisorEntry(_build, frozenset(Controller), "rrt",
                        "Sec. III-C: the system in control plans, the UAV waits for it",
                        dims=frozenset({2, 3}))
