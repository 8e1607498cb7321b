"""Flying the oracle's witness through the one mission step, with every failure rule.

The witness is handed to :class:`~dualpilot.mission.step.Mission` as a supervisor's
plan, step by step (:class:`WitnessReplay`): each step's plan is the rest of the
witness rolled out from the vehicle's state, checked by the run-time monitor for
Eq. (1), the force and speed limits and the area (the fires are the failure rules'
job: the plan knows the future, the step's obstacles are the present), and flown
with a planning interval of zero, so the fires advance the one sub-step every step
takes. The mission's own fire port, with its ignition keep-out, and its own failure
rules then say whether the witness reaches G: nothing of the search is trusted.
"""

from __future__ import annotations

from dualpilot.mission import monitor
from dualpilot.mission.answers import Answer, SystemStatus
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalPlanners, LocalVehicle, local_mission
from dualpilot.mission.ports import FirePort
from dualpilot.mission.result import MissionResult
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.dynamics import Array, hover_state, rollout
from dualpilot.model.fire import FireSnapshot
from dualpilot.oracle.search import Witness
from dualpilot.plan import Plan, PlanStatus
from dualpilot.supervisor.interface import Planned, StepView

#: the records' name of the oracle's plans (Plan.info["oracle"])
ORACLE_INFO = "witness"


class WitnessReplay:
    """A supervisor that flies a fixed witness (dualpilot.supervisor.interface.Supervisor)."""

    def __init__(self, witness: Witness):
        self.witness = witness
        #: the monitor's refusals (step, reason): none for a sound witness
        self.refusals: list[tuple[int, str]] = []

    def plan(self, step: StepView, t: int, d_t: float, snapshot: FireSnapshot) -> Planned:
        """Step t's plan: the witness from step t, rolled out from the vehicle's state."""
        decision = step.decision_dynamics.decide(t, d_t)  # the attention stream goes on as for all
        controls = self.witness.controls[t:]
        if len(controls) == 0:
            return Planned(decision, None, note="witness ended")
        states = rollout(step.state, controls, step.spec.dynamics)
        verdict = monitor.check_plan(states, controls, step.state, (), step.spec)
        if not verdict.ok:
            self.refusals.append((t, verdict.reason))
            return Planned(decision, None, [monitor.refusal(1, verdict)])
        plan = Plan(1, PlanStatus.OK, states, controls, 0.0, info={"oracle": ORACLE_INFO})
        return Planned(decision, plan, [Answer(1, SystemStatus.OK)], planning_s=0.0)

    def after_flight(self, system: int, p0: Array, p1: Array, du2: float) -> None:
        """Nothing: the witness is fixed."""


def fly_witness(config: MissionConfig, witness: Witness,
                fires: FirePort | None = None) -> tuple[MissionResult, WitnessReplay]:
    """The mission of ``config`` flown along ``witness`` by the in-process mission step (on
    ``fires``, the mission's own fire process when None)."""
    if fires is None:
        mission = local_mission(config, planners={})
    else:
        spec = config.spec()
        state = hover_state(spec.start_position, spec.dynamics)
        ports = MissionPorts(fires, LocalPlanners({}), LocalVehicle(state, spec.dynamics))
        mission = Mission(config, spec, ports, state)
    replay = WitnessReplay(witness)
    mission.supervisor = replay
    return mission.run(), replay
