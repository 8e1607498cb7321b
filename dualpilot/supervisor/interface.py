"""What a supervisor is to the mission step: decide, ask the planners, pick the plan to fly.

Every supervisor (built by name, :mod:`dualpilot.supervisor.registry`) implements
:class:`Supervisor`: the step calls :meth:`~Supervisor.plan` once per step t with d_t of
Eq. (KSI) and the fire snapshot, flies what it returns (or brakes), and reports the
flight back with :meth:`~Supervisor.after_flight`. The supervisor reads the step through
:class:`StepView`. A :class:`SupervisorEntry` is one supervisor of the registry: how it is
built from the mission's configuration (:class:`SupervisorSettings`) and its spec.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from dualpilot.mission.answers import Answer
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.ports import FirePort, PlannerPort, StepObserver
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.risk import ForecastView
from dualpilot.plan import Plan
from dualpilot.readings import Profile
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.rule import ConcurrentParams
from dualpilot.supervisor.paper.decision import Decision, DecisionDynamics

__all__ = ["Planned", "StepView", "Supervisor", "SupervisorEntry", "SupervisorSettings"]


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
    #: the paper's decision dynamics: the attention stream (Eqs. KSI, dir, categorical) and Ψ
    decision_dynamics: DecisionDynamics
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


class Supervisor(Protocol):
    """A supervisor over one mission: each step it decides and picks the plan to fly."""

    def plan(self, step: StepView, t: int, d_t: float, snapshot: FireSnapshot) -> Planned:
        """Step t's decision and plan (``d_t``: m, Eq. KSI; ``snapshot``: the fires now)."""
        ...

    def after_flight(self, system: int, p0: Array, p1: Array, du2: float) -> None:
        """One step flown by ``system`` (0: braking) from p0 to p1, ‖u_t − u_{t−1}‖² = du2."""
        ...


class SupervisorSettings(Protocol):
    """The mission's configuration as a supervisor is built from it
    (:class:`dualpilot.mission.config.MissionConfig` is one)."""

    @property
    def controller(self) -> Controller: ...

    @property
    def supervisor(self) -> str: ...

    @property
    def risk(self) -> bool: ...

    @property
    def timing(self) -> Timing: ...

    @property
    def concurrent(self) -> ConcurrentParams: ...

    def reading(self) -> Profile:
        """The reading of the paper: the profile with the settings applied."""
        ...


@dataclass(frozen=True)
class SupervisorEntry:
    """One supervisor of the registry: how it is built for a mission, the controllers it
    runs and the System 1 method (dualpilot/planners.py) it flies unless the configuration
    names one.

    The paper's supervisor runs cc, s1 and s2 (the controller names of those three); any
    other runs the cognitive controller only, named by the supervisor's name.
    """

    build: Callable[[SupervisorSettings, MissionSpec], Supervisor]
    controllers: frozenset[Controller] = frozenset({Controller.CC})
    system1_method: str = "rrt"
    #: one line for listings
    summary: str = ""
    #: the dimensions (``DynamicsParams.dim``) it supervises missions in: 2 (the top-down
    #: evaluation) unless it says 3 too (docs/three_d.md)
    dims: frozenset[int] = frozenset({2})
