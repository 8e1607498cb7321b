"""Seeded planning instances on the paper's fire setup (Sec. IV-A), for tests and benchmarks.

A :class:`FireField` runs for a random number of sub-steps from a seeded RNG;
to reach the instance's hull count extra fronts are spawned and propagated
with the same Gauss–Markov model (not extinguished, so their hulls
△(C^i_{1:t}) grow as the paper's do). The UAV is placed somewhere free near
the start–goal diagonal of the spec with a random velocity; the objective
and u_{t|t} are drawn too. Lengths in m.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.geometry import Polytope
from dualpilot.plan import Objective, Plan
from dualpilot.spec import MissionSpec
from dualpilot.system2.problem import verify_p2_plan
from dualpilot.verify import verify_trajectory

#: The instances' mission: the default spec (start, goal G, area, d_safe, clearance).
SPEC = MissionSpec()
START = np.array(SPEC.start)
GOAL = SPEC.goal
#: Drawn UAV positions stay this far inside the area's border (m).
_BORDER_M = 20.0


@dataclass(frozen=True)
class Instance:
    """One planning query: state, hulls, objective and u_{t|t}."""

    index: int
    seed: int
    state: Array
    hulls: tuple[Polytope, ...]
    objective: Objective
    prev_control: Array
    substeps: int

    @property
    def n_hulls(self) -> int:
        return len(self.hulls)


def make_instance(index: int, seed: int, n_hulls: int, fire: FireParams = FireParams(),
                  spec: MissionSpec = SPEC) -> Instance:
    """A seeded instance with exactly ``n_hulls`` active fronts and a free UAV state.

    The start keeps ``spec.clearance_m`` + 5 m from every hull, the UAV
    ``spec.clearance_m`` + 10 m (and its next position + 5 m).
    """
    rng = np.random.default_rng(np.random.SeedSequence([seed, index]))
    start = np.array(spec.start)
    for _attempt in range(200):
        field = FireField(fire)
        substeps = int(rng.integers(1, 60))
        for k in range(substeps):
            field.substep(rng, k)
        while len(field.fronts) > n_hulls:
            field.fronts.pop(int(rng.integers(len(field.fronts))))
        # top up: spawned fronts propagate for a random number of sub-steps
        while len(field.fronts) < n_hulls:
            front = field.spawn(rng, substeps)
            field.fronts.pop()
            for _ in range(int(rng.integers(0, 60))):
                front = front.advance(rng, fire)
            field.fronts.append(front)
        hulls = field.snapshot().hulls
        if any(h.contains(start, margin=spec.clearance_m + 5.0) for h in hulls):
            continue
        state = _free_state(rng, hulls, spec)
        if state is None:
            continue
        objective = Objective.MISSION_TIME if rng.random() < 0.5 else Objective.ENERGY
        prev_control = rng.uniform(-3.0, 3.0, size=2)
        return Instance(index, seed, state, hulls, objective, prev_control, substeps)
    raise RuntimeError(f"could not draw instance {index} with {n_hulls} hulls")


def make_physics_instance(index: int, seed: int, scenario: str,
                          spec: MissionSpec = SPEC) -> Instance:
    """A seeded instance on a fire-behaviour scenario (dualpilot/model/scenarios.py).

    The scenario's fire runs from one birth for 20–160 sub-steps of T_f (its own births
    go on at p_b); the hulls are its snapshot's, the UAV as in :func:`make_instance`.
    """
    rng = np.random.default_rng(np.random.SeedSequence([seed, index, 2]))
    start = np.array(spec.start)
    for _attempt in range(200):
        field = FireField(FireParams(scenario=scenario))
        field.spawn(rng, 0)
        substeps = int(rng.integers(20, 161))
        for k in range(substeps):
            field.substep(rng, k)
        hulls = field.snapshot().hulls
        if not hulls or any(h.contains(start, margin=spec.clearance_m + 5.0) for h in hulls):
            continue
        state = _free_state(rng, hulls, spec)
        if state is None:
            continue
        objective = Objective.MISSION_TIME if rng.random() < 0.5 else Objective.ENERGY
        return Instance(index, seed, state, hulls, objective, rng.uniform(-3.0, 3.0, size=2),
                        substeps)
    raise RuntimeError(f"could not draw physics instance {index} on {scenario}")


def small_instance(seed: int, spec: MissionSpec = SPEC) -> tuple[Instance, int]:
    """A small (P2) instance for checks against a proven optimum, and its horizon T (3–8).

    One or two rectangles (30–120 m a side) near the straight line the UAV would fly in
    T steps, a random velocity, objective and u_{t|t}; redrawn until the start is free.
    """
    rng = np.random.default_rng(np.random.SeedSequence([seed, 17]))
    horizon = int(rng.integers(3, 9))
    for _attempt in range(1000):
        pos = rng.uniform(150.0, spec.area_size_m - 150.0, size=2)
        vel = rng.uniform(-12.0, 12.0, size=2)
        heading = spec.goal.center - pos
        heading /= max(float(np.linalg.norm(heading)), 1e-9)
        hulls = []
        for _ in range(int(rng.integers(1, 3))):
            centre = pos + rng.uniform(0.2, 1.0) * 15.0 * horizon * heading \
                + rng.normal(0.0, 25.0, size=2)
            half = rng.uniform(15.0, 60.0, size=2)
            hulls.append(Polytope.from_vertices(np.array([
                centre - half, centre + [half[0], -half[1]], centre + half,
                centre + [-half[0], half[1]]])))
        p1 = pos + spec.dynamics.dt_s * vel
        if any(h.distance(pos) < spec.d_safe_m + 1.0
               or float(np.max(h.A @ p1 - h.b)) < spec.clearance_m + 1.0 for h in hulls):
            continue
        if any(h.segment_distance(pos, p1) < spec.d_safe_m + 1.0 for h in hulls):
            continue
        objective = Objective.MISSION_TIME if rng.random() < 0.5 else Objective.ENERGY
        inst = Instance(seed, seed, np.concatenate([pos, vel]), tuple(hulls), objective,
                        rng.uniform(-3.0, 3.0, size=2), 0)
        return inst, horizon
    raise RuntimeError(f"could not draw small instance {seed}")


def _free_state(rng: np.random.Generator, hulls: Sequence[Polytope],
                spec: MissionSpec) -> Array | None:
    start = np.array(spec.start)
    clearance = spec.clearance_m
    for _ in range(200):
        s = rng.uniform(0.0, 0.85)
        pos = start + s * (spec.goal.center - start) + rng.normal(0.0, 120.0, size=2)
        if np.any(pos < _BORDER_M) or np.any(pos > spec.area_size_m - _BORDER_M):
            continue
        vel = rng.uniform(-10.0, 10.0, size=2)
        p1 = pos + vel
        if any(h.distance(pos) < clearance + 10.0 or float(np.max(h.A @ p1 - h.b))
               < clearance + 5.0 for h in hulls):
            continue
        return np.concatenate([pos, vel])
    return None


def check_plan(plan: Plan, inst: Instance, spec: MissionSpec = SPEC,
               p2: bool = True) -> tuple[bool, str]:
    """Independent check of a plan: Eq. (1), bounds, d_safe and, with ``p2``, P2's ε-disjunction."""
    if not plan.ok:
        return False, f"status {plan.status.value}"
    if p2:
        verdict = verify_p2_plan(plan.states, plan.controls, inst.hulls, spec.dynamics,
                                 spec.clearance_m, spec.d_safe_m, spec.area_size_m, tol=1e-3)
    else:
        verdict = verify_trajectory(plan.states, plan.controls, inst.hulls, spec.dynamics,
                                    spec.d_safe_m)
    return verdict.ok, verdict.reason
