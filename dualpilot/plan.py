"""What a planner returns: a predicted trajectory over the horizon and its status."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.geometry import Polytope

if TYPE_CHECKING:
    from dualpilot.model.risk import ForecastView


class PlanStatus(enum.Enum):
    OK = "ok"
    INFEASIBLE = "infeasible"  # the solver proved no safe plan exists
    TIMEOUT = "timeout"  # no verified plan within the time limit
    NO_PATH = "no_path"  # RRT found no path within its iteration cap
    UNSAFE = "unsafe"  # a candidate failed verification against the hulls
    INVALID_INPUT = "invalid_input"
    ERROR = "error"  # the solver crashed or returned garbage


class Objective(enum.Enum):
    """System 2's objective, chosen by the attention (attribute 2 or 3)."""

    MISSION_TIME = "mission_time"  # (κ1, κ2) = (1, 0.001)
    ENERGY = "energy"  # (κ1, κ2) = (0.001, 1)


@dataclass(frozen=True)
class Plan:
    """A plan x_{t|t..t+T|t}, u_{t+1|t..t+T|t} from one system.

    ``states`` has shape (T+1, 2·dim) starting at the current state; ``controls``
    has shape (T, dim) where controls[k] drives states[k] to states[k+1].
    A plan whose status is not OK carries empty arrays and must not be flown.
    """

    system: int
    status: PlanStatus
    states: Array
    controls: Array
    compute_time_s: float
    objective: Objective | None = None
    cost: float | None = None
    path: Array | None = None  # System 1's reference path (k, 2)
    message: str = ""
    info: dict[str, object] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status is PlanStatus.OK

    @staticmethod
    def failed(
        system: int, status: PlanStatus, compute_time_s: float, message: str, dim: int = 2
    ) -> Plan:
        return Plan(
            system=system,
            status=status,
            states=np.empty((0, 2 * dim)),
            controls=np.empty((0, dim)),
            compute_time_s=compute_time_s,
            message=message,
        )


class Planner(Protocol):
    """One step method, called by the mission loop and by the planner services.

    ``system`` is 1 or 2; ``method`` the name :mod:`dualpilot.planners` builds it by.
    """

    system: int
    method: str

    def plan(
        self,
        state: Array,
        hulls: tuple[Polytope, ...],
        objective: Objective = Objective.MISSION_TIME,
        prev_control: Array | None = None,
    ) -> Plan:
        """Plan from ``state`` avoiding ``hulls``; ``prev_control`` is u_{t|t} (N)."""
        ...


class ForecastPlanner(Planner, Protocol):
    """A risk-aware planner (``uses_forecast`` True, e.g. "rrt+risk", "fast+risk"): ``plan``
    also takes the fire forecast; without one it plans as its paper method."""

    uses_forecast: bool

    def plan(
        self,
        state: Array,
        hulls: tuple[Polytope, ...],
        objective: Objective = Objective.MISSION_TIME,
        prev_control: Array | None = None,
        forecast: ForecastView | None = None,
    ) -> Plan: ...
