"""A supervisor of one distance: System 2 near a fire, System 1 elsewhere ("proximity").

Each step t the paper's decision dynamics go on as under every built-in supervisor (the
attention stream of Eqs. KSI, dir, categorical, Ψ of Eq. Psi, and System 2's objective),
so the records and the attention stream stay comparable; but the system in control is
chosen by one rule:

    S_t = 2 if d_t < near_m else 1

with d_t the distance of Eq. (KSI) from the UAV to the nearest fire (m, the reading's
``d_t_reading``). Far from the fires the fast System 1 flies (by default this package's
straight line, :mod:`dualpilot_example.straight`); near them the deliberate System 2
plans around their hulls. The UAV waits for the chosen system's plan, as under the paper's
supervisor, and, when that plan is not OK or the run-time monitor refuses it, for the
other system's; the step's planning interval is the sum of the answers' T_s (the paper's
155 ms / 5 s under paper timing). It runs the cognitive controller.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from dualpilot.mission import monitor
from dualpilot.mission.answers import Answer, SystemStatus
from dualpilot.mission.params import Controller
from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.stale_fire import grown_snapshot
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.interface import (
    Planned,
    StepView,
    Supervisor,
    SupervisorEntry,
    SupervisorSettings,
)
from dualpilot.supervisor.paper.planning import planning_time


@dataclass(frozen=True)
class ProximityParams:
    """The rule's one distance (m)."""

    #: System 2 is in control while a fire is nearer than this
    near_m: float = 150.0

    def __post_init__(self) -> None:
        if not self.near_m >= 0:
            raise ValueError(f"near_m must be >= 0, got {self.near_m}")


class ProximitySupervisor:
    """System 2 near a fire, System 1 elsewhere; the UAV waits for the plan (module docstring)."""

    def __init__(self, params: ProximityParams = ProximityParams()):
        self.params = params

    def plan(self, step: StepView, t: int, d_t: float, snapshot: FireSnapshot) -> Planned:
        """Step t: the system the rule picks plans first, the other if its plan fails."""
        paper = step.decision_dynamics.decide(t, d_t)  # the attention stream goes on
        chosen = 2 if d_t < self.params.near_m else 1
        decision = replace(paper, system=chosen)
        if step.observer is not None:
            step.observer.decided(t, decision, chosen)
        seen = grown_snapshot(snapshot, step.fires.margin_m())  # stale fire data: grown
        obstacles = seen.obstacles_for(step.state[:2], step.spec.clearance_m)
        got = Planned(decision, None)
        for system in (chosen, 3 - chosen):
            if not step.planners.available(system):
                got.answers.append(Answer(system, SystemStatus.UNAVAILABLE))
                continue
            request = PlanRequest(t=t, system=system, state=step.state.copy(),
                                  prev_control=step.prev_control, obstacles=obstacles,
                                  objective=decision.objective,
                                  forecast=step.forecast_view(system))
            candidate = step.planners.plan(request)
            step.record_time(system, candidate.compute_time_s)
            got.planning_s += planning_time(candidate, step.timing, step.params)
            if not candidate.ok:
                got.answers.append(Answer(system, SystemStatus.of(candidate.status)))
                continue
            verdict = monitor.check(candidate, step.state, obstacles, step.spec)
            if verdict.ok:
                verdict = monitor.check_risk(candidate, request.forecast, step.spec)
            if not verdict.ok:  # never flown: the monitor's refusal is the answer
                got.answers.append(monitor.refusal(system, verdict))
                continue
            got.answers.append(Answer(system, SystemStatus.OK))
            got.plan, got.forecast = candidate, request.forecast
            return got
        return got  # no plan: the UAV brakes

    def after_flight(self, system: int, p0: Array, p1: Array, du2: float) -> None:
        """Nothing: the rule keeps no state across flights."""


def _build(config: SupervisorSettings, spec: MissionSpec) -> Supervisor:
    return ProximitySupervisor()


#: The entry point ``proximity`` of group ``dualpilot.supervisors``: the cognitive
#: controller, System 1 by this package's straight line unless the configuration names one.
PROXIMITY = SupervisorEntry(_build, frozenset({Controller.CC}), "straight",
                            "System 2 within 150 m of a fire, System 1 elsewhere")
