"""The three ports the one mission step talks to: fires, planners, vehicle.

The in-process adapters are in :mod:`dualpilot.mission.local`; the stack's
(Zenoh and MAVLink) are in ``services/supervisor/ports/``. Times are
simulated seconds of the mission.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from dualpilot.mission.result import Ending, StepRecord
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot, Region
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.risk import ForecastView
from dualpilot.plan import Objective, Obstacles, Plan
from dualpilot.supervisor.paper.decision import Decision

#: Where no front may ignite during a fire sub-step: (position (m), (dim,), radius (m)).
KeepOut = tuple[Array, float]


@dataclass(frozen=True)
class PlanRequest:
    """What a planner is asked at step t: plan from ``state`` avoiding ``obstacles``."""

    t: int
    system: int
    state: Array  # x_t, (2·dim,)
    prev_control: Array  # u_{t|t}, the control applied at the previous step (N), (dim,)
    #: FireSnapshot.obstacles of the UAV's position: polygons in 2-D, prisms in 3-D
    obstacles: Obstacles
    objective: Objective
    #: the fire forecast for a risk-aware planner (None: the paper's planners, or no forecast)
    forecast: ForecastView | None = None


class FirePort(Protocol):
    def snapshot(self) -> FireSnapshot:
        """The fire state the step decides and plans on."""
        ...

    def margin_m(self) -> float:
        """How far (m) the fire data must be grown before planning (0 while it is fresh)."""
        ...

    def advance(self, t: int, n: int,
                keep_out: KeepOut | None) -> Sequence[tuple[Region, ...]]:
        """Propagate ``n`` sub-steps of T_f; the active regions after each one (rectangles;
        in 3-D cuboids, a rectangle without a top being taller than the band).

        Fewer than ``n`` entries (none) when the fire service could not run them.
        """
        ...


@runtime_checkable
class ForecastPort(Protocol):
    """The fire port's optional forecast (dualpilot/model/forecast.py), asked only by a
    mission whose planners or supervisor use it."""

    def forecast(self, substeps_per_step: int) -> OccupancyForecast | None:
        """P(inside a fire region) ahead of :meth:`FirePort.snapshot`'s state, assuming
        time-steps of ``substeps_per_step`` sub-steps; None when there is none."""
        ...


class PlannerPort(Protocol):
    def available(self, system: int) -> bool:
        """The planner can be asked (its service is alive)."""
        ...

    def plan(self, request: PlanRequest) -> Plan:
        """A plan of any status; a planner that rejects its input answers INVALID_INPUT."""
        ...

    def launch(self, request: PlanRequest) -> object:
        """Start planning in the background; a ticket for :meth:`collect`."""
        ...

    def collect(self, ticket: object) -> Plan:
        """The plan of a launched request (waits for it; TIMEOUT when it never came)."""
        ...


@runtime_checkable
class ForecastPlannerPort(Protocol):
    """The planner port's optional question: does this system's planner use a forecast?"""

    def uses_forecast(self, system: int) -> bool: ...


class VehiclePort(Protocol):
    def command(self, target: Array, control: Array, after_s: float) -> None:
        """Fly towards ``target`` (the plan's x_{t+1|t}) with ``control``, due in ``after_s``."""
        ...

    def observe(self) -> Array:
        """The state reached at the commanded time."""
        ...


class StepObserver(Protocol):
    """Called by the step as it goes; publishing and records observe, they never steer."""

    def decided(self, t: int, decision: Decision, commanded: int) -> None: ...

    def commanded(self, t: int, flown: int, info: dict[str, object]) -> None: ...

    def recorded(self, record: StepRecord, flown: bool) -> None: ...

    def ended(self, record: StepRecord, ending: Ending) -> None: ...
