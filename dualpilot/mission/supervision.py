"""The supervisor's part of the mission step: decide, ask the planners, pick the plan to fly.

Each supervisor (built by name, :mod:`dualpilot.mission.supervisors`) implements
:class:`SupervisorPlanning`: the step calls :meth:`~SupervisorPlanning.plan` once
per step t with d_t of Eq. (KSI) and the fire snapshot, flies what it returns (or
brakes), and reports the flight back with :meth:`~SupervisorPlanning.after_flight`.
The supervisor reads the step through :class:`StepView`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

from dualpilot.mission.answers import Answer
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.ports import FirePort, PlannerPort, StepObserver
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.risk import ForecastView
from dualpilot.plan import Plan
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.decision import Decision, Supervisor


@dataclass
class Planned:
    """A step's planning: the decision recorded, the plan to fly (None: brake), each system's
    answers in order (dualpilot/mission/answers.py), the planning interval T_s the fires
    advance through (s), a note for the record ("" when there is none) and the forecast the
    plan was made on (None: none)."""

    decision: Decision
    plan: Plan | None
    answers: list[Answer] = field(default_factory=list)
    planning_s: float = 0.0
    note: str = ""
    forecast: ForecastView | None = None


class StepView(Protocol):
    """The mission step as a supervisor sees it (:class:`dualpilot.mission.step.Mission`)."""

    controller: Controller
    spec: MissionSpec
    timing: Timing
    params: MissionParams
    fires: FirePort
    planners: PlannerPort
    observer: StepObserver | None
    #: the paper's supervisor: the attention stream (Eqs. KSI, dir, categorical) and Ψ
    supervisor: Supervisor
    state: Array
    prev_control: Array
    sim_time_s: float
    #: the systems whose planners take the fire forecast
    forecast_systems: frozenset[int]

    def record_time(self, system: int, seconds: float) -> None:
        """Record one answer's compute time (s) of ``system``'s planner."""
        ...

    def forecast_view(self, system: int) -> ForecastView | None:
        """The fire forecast for a plan of ``system`` (None when it is not used)."""
        ...


class SupervisorPlanning(Protocol):
    """One supervisor's planning phase over a mission."""

    def plan(self, step: StepView, t: int, d_t: float, snapshot: FireSnapshot) -> Planned:
        """Step t's decision and plan (``d_t``: m, Eq. KSI; ``snapshot``: the fires now)."""
        ...

    def after_flight(self, system: int, p0: Array, p1: Array, du2: float) -> None:
        """One step flown by ``system`` (0: braking) from p0 to p1, ‖u_t − u_{t−1}‖² = du2."""
        ...
