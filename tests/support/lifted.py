"""A 2-D planner flying a 3-D mission at one altitude: the reduction of docs/three_d.md.

With every obstacle a prism that spans the band, the UAV at G_o's altitude and not
climbing, a 3-D planning problem is the 2-D one plus an altitude that stays put; a 3-D
planner tests for this and runs its 2-D code on the footprints. :class:`LiftedPlanner` is
that reduction around a real 2-D planner, for the step-level consistency test: it
refuses any other input, and its answer is the 2-D planner's plan, lifted.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.altitude import lift_controls, lift_state, planar_state
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan, Planner
from dualpilot.spec import MissionSpec


class LiftedPlanner:
    """``planar`` (a planner of the 2-D spec) as a planner of the 3-D ``spec`` under the
    reduction (module docstring); ValueError for an input outside it."""

    def __init__(self, planar: Planner, spec: MissionSpec):
        self.planar = planar
        self.system, self.method = planar.system, planar.method
        self.uses_forecast = bool(getattr(planar, "uses_forecast", False))
        self.spec = spec

    def _reduce(self, state: Array, hulls: tuple[Any, ...],
                prev_control: Array | None) -> tuple[Array, tuple[Any, ...], Array | None]:
        band, x = self.spec.band, np.asarray(state, dtype=float)
        if x.shape != (6,) or x[2] != band.goal_z_m or x[5] != 0.0:
            raise ValueError(f"not at G_o's altitude at rest vertically: {x}")
        if not all(isinstance(h, Prism) and h.spans(band) for h in hulls):
            raise ValueError("an obstacle lower than the band")
        u = None if prev_control is None else np.asarray(prev_control, dtype=float)
        if u is not None and u[2] != 0.0:
            raise ValueError(f"a vertical force {u}")
        return planar_state(x), tuple(h.base for h in hulls), None if u is None else u[:2]

    def plan(self, state: Array, hulls: tuple[Any, ...],
             objective: Objective = Objective.MISSION_TIME, prev_control: Array | None = None,
             forecast: Any = None) -> Plan:
        x2, bases, u2 = self._reduce(state, hulls, prev_control)
        if self.uses_forecast:
            plan = self.planar.plan(x2, bases, objective, u2, forecast=forecast)  # type: ignore
        else:
            plan = self.planar.plan(x2, bases, objective, u2)
        if not plan.ok:
            return Plan.failed(plan.system, plan.status, plan.compute_time_s, plan.message,
                               dim=3)
        z = float(state[2])
        states = np.array([lift_state(s, z) for s in plan.states])
        return Plan(plan.system, plan.status, states, lift_controls(plan.controls),
                    plan.compute_time_s, plan.objective, plan.cost, plan.path, plan.message,
                    dict(plan.info), plan.bound)
