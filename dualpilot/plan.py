"""What a planner returns: a predicted trajectory over the horizon and its status.

A plan carries its Eq. (S2) cost and, when a method proved one, a lower bound on the
optimum of the problem it solved (Problem (P2) for System 2); the certified gap
(cost − bound) / bound then says how far from optimal the plan can be at most.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism

#: What a planner avoids, one per front (:meth:`~dualpilot.model.fire.FireSnapshot.obstacles`):
#: planar polygons in 2-D, prisms (a cuboid's six faces, a swept hull's k + 2) in 3-D. A
#: planner is built for one spec's dimension (:func:`dualpilot.planners.build_planner`
#: refuses a method that does not plan in it), so it is handed obstacles of its kind only;
#: :class:`Planner` names the planar kind until a planner plans in 3-D.
Obstacles = tuple[Polytope, ...] | tuple[Prism, ...]


def planar_obstacles(obstacles: Obstacles) -> tuple[Polytope, ...]:
    """``obstacles`` as the planar kind a 2-D planner or message takes (ValueError for
    prisms: they need a planner, or a wire form, of the third dimension)."""
    if not all(isinstance(o, Polytope) for o in obstacles):
        raise ValueError("3-D obstacles (prisms) given where planar ones are taken")
    return obstacles  # type: ignore[return-value]

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


def certified_gap(cost: float | None, bound: float | None) -> float:
    """(cost − bound) / bound: the cost is at most (1 + gap) × the optimum (inf: no proof).

    0 when the bound reaches the cost; inf without a cost or a positive finite bound.
    The bench's gap to a known optimum, (cost − opt) / opt, is never larger.
    """
    if cost is None or bound is None or not (math.isfinite(cost) and math.isfinite(bound)):
        return math.inf
    if bound >= cost:
        return 0.0
    if bound <= 0.0:
        return math.inf
    return (cost - bound) / bound


@dataclass(frozen=True)
class Plan:
    """A plan x_{t|t..t+T|t}, u_{t+1|t..t+T|t} from one system.

    ``states`` has shape (T+1, 2·dim) starting at the current state; ``controls``
    has shape (T, dim) where controls[k] drives states[k] to states[k+1].
    A plan whose status is not OK carries empty arrays and must not be flown.
    ``cost`` is its Eq. (S2) value; ``bound``, when given, a proven lower bound on the
    optimum of the problem solved (never above ``cost``), and :attr:`certified_gap`
    their relative difference.
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
    bound: float | None = None  # a proven lower bound on the optimum (Eq. (S2) units)

    @property
    def ok(self) -> bool:
        return self.status is PlanStatus.OK

    @property
    def certified_gap(self) -> float | None:
        """(cost − bound) / bound (:func:`certified_gap`), None without a bound or a cost."""
        if self.bound is None or self.cost is None:
            return None
        return certified_gap(self.cost, self.bound)

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
