"""A 2-D planner flying a 3-D mission at one altitude: the reduction of docs/three_d.md.

With every obstacle a prism that spans the band, the UAV at G_o's altitude and not
climbing, a 3-D planning problem is the 2-D one plus an altitude that stays put; a 3-D
planner tests for this and runs its 2-D code on the footprints. :class:`LiftedPlanner` is
that reduction around a real 2-D planner, for the step-level consistency test: it
refuses any other input, and its answer is the 2-D planner's plan, lifted.
:data:`LIFTED_RRT` is System 1's "rrt" so reduced, as a planning method that says it plans
in 2-D and 3-D (where a 3-D planner plugs in), and :func:`assert_same_mission` says a 3-D
mission is a 2-D one at one altitude, row for row.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from dualpilot.arrays import Array
from dualpilot.mission.result import MissionResult
from dualpilot.model.altitude import lift_controls, lift_state, planar_state
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan, Planner
from dualpilot.planners import PlannerMethod, build_planner
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


def planar_spec(spec: MissionSpec) -> MissionSpec:
    """``spec`` of a 3-D mission as the 2-D mission's (the same geometry and seed)."""
    return replace(spec, dynamics=replace(spec.dynamics, dim=2))


def _lifted_rrt(spec: MissionSpec, params: Any, risk: bool = False) -> Planner:
    planar = build_planner(1, planar_spec(spec) if spec.dim == 3 else spec, "rrt", params, risk)
    return LiftedPlanner(planar, spec) if spec.dim == 3 else planar


#: System 1's "rrt" under the reduction, a method of both dimensions (a real registry's
#: entry point "tests.support.lifted:LIFTED_RRT" in the tests that use it)
LIFTED_RRT = PlannerMethod(1, _lifted_rrt, lambda spec, params: _lifted_rrt(spec, params, True),
                           "System 1's rrt, flown at one altitude in 3-D",
                           dims=frozenset({2, 3}))


def assert_same_mission(flat: MissionResult, tall: MissionResult) -> None:
    """The 3-D mission ``tall`` is the 2-D mission ``flat`` at 50 m, row for row."""
    assert tall.spec.dim == 3 and flat.spec.dim == 2
    assert (flat.ending, flat.steps, flat.energy, flat.mission_time_s, flat.switches,
            flat.sim_time_s) == (tall.ending, tall.steps, tall.energy, tall.mission_time_s,
                                 tall.switches, tall.sim_time_s)
    assert len(flat.records) == len(tall.records)
    for a, b in zip(flat.records, tall.records, strict=True):
        assert (a.t, a.system, a.plan_status, a.d_t, a.fire_substeps, a.planning_time_s,
                a.fires_active, a.time_s) == (b.t, b.system, b.plan_status, b.d_t,
                                              b.fire_substeps, b.planning_time_s,
                                              b.fires_active, b.time_s)
        assert np.array_equal(a.state, planar_state(b.state))
        assert b.state[2] == 50.0 and b.state[5] == 0.0
        assert np.array_equal(a.control, b.control[:2]) and b.control[2] == 0.0
        assert np.array_equal(a.planned_positions, b.planned_positions[:, :2])
        assert np.all(b.planned_positions[:, 2] == 50.0)
        da, db = a.decision, b.decision
        assert (da.attention, da.system, da.objective, da.d_t) == (db.attention, db.system,
                                                                   db.objective, db.d_t)
        assert all(np.array_equal(u, v) for u, v in ((da.xi, db.xi), (da.p, db.p),
                                                     (da.psi, db.psi)))
        assert a.snapshot.regions == b.snapshot.regions
        assert all(np.array_equal(h.vertices, g.vertices)
                   for h, g in zip(a.snapshot.hulls, b.snapshot.hulls, strict=True))
        assert set(b.snapshot.tops_m) <= {145.0} and set(b.snapshot.hull_tops_m) <= {145.0}
    assert flat.final_state is not None and tall.final_state is not None
    assert np.array_equal(flat.final_state, planar_state(tall.final_state))
