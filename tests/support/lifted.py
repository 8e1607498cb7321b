"""A 2-D planner flying a 3-D mission at one altitude: the reduction of docs/three_d.md.

With every obstacle a prism that spans the band, the UAV at G_o's altitude and not
climbing, a 3-D planning problem is the 2-D one plus an altitude that stays put; a 3-D
planner tests for this and runs its 2-D code on the footprints. :class:`LiftedPlanner` is
that reduction around a real 2-D planner, for the step-level consistency test: it
refuses any other input, and its answer is the 2-D planner's plan, lifted.
:data:`LIFTED_RRT` is System 1's "rrt" so reduced, as a planning method that says it plans
in 2-D and 3-D (where a 3-D planner plugs in), and :func:`assert_same_mission` says a 3-D
mission is a 2-D one at one altitude, row for row. :func:`flown_pair` flies a 2-D mission and
its 3-D mission (fires above the ceiling) by the same 2-D planners so reduced
(:func:`lifted_planners`), for the consistency tests and their sweep
(benchmarks/consistency3d.py).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from dualpilot.arrays import Array
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.result import MissionResult
from dualpilot.model.altitude import lift_controls, lift_state, planar_state
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan, Planner
from dualpilot.planners import PlannerMethod, build_planner
from dualpilot.spec import MissionSpec

#: the paper's fire process and two scenarios, the consistency tests' missions
SCENARIOS = ("paper", "grass-5", "shrub")
#: the 3-D mission of a 2-D one under the reduction: every cuboid taller than the ceiling
THREE_D = {"dim": 3, "fire_height": "above-ceiling"}
#: the controllers whose 2-D planners fly under the reduction
LIFTED = ("cc", "s1", "s2", "cc+risk")


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


def lifted_planners(config: MissionConfig, flat: MissionConfig) -> dict[int, Planner]:
    """The 2-D planners of ``flat``'s mission, as planners of ``config``'s 3-D mission."""
    spec2, spec3 = flat.spec(), config.spec()
    methods = flat.methods()
    return {s: LiftedPlanner(build_planner(s, spec2, methods[s], flat.system2_params() if s == 2
                                           else None, flat.risk), spec3)  # type: ignore
            for s in flat.systems()}


def config_pair(name: str, seed: int, scenario: str, max_steps: int = 150) -> tuple[
        MissionConfig, MissionConfig]:
    """Seed ``seed``'s configuration of ``name`` on ``scenario`` in 2-D, and its 3-D one
    (:data:`THREE_D`)."""
    flat = MissionConfig.named(name, seed=seed, settings=(("scenario", scenario),
                                                          ("max_steps", max_steps)))
    return flat, flat.with_settings(THREE_D)


def flown_pair(name: str, seed: int, scenario: str) -> tuple[MissionResult, MissionResult]:
    """Seed ``seed``'s 2-D mission of ``name`` on ``scenario``, and its 3-D mission (fires
    above the ceiling) flown by the same 2-D planners under the reduction."""
    flat, tall = config_pair(name, seed, scenario)
    a = local_mission(flat).run()
    b = local_mission(tall, planners=lifted_planners(tall, flat)).run()
    return a, b


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
