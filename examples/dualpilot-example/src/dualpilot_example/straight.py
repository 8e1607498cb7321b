"""A System 1 of straight lines: fly at G, brake before a fire (the method "straight").

Each step of the plan aims at the centre g of the goal region G. The velocity wanted is

    v* = s (g − p) / ‖g − p‖,   s = min(cruise, ‖g − p‖ / ΔT)      (m/s)

and the force is the one of Eq. (1), v_{k+1} = (1 − ζ) v_k + (ΔT/m) u_k, that reaches v*
in one ΔT, u = m (v* − (1 − ζ) v) / ΔT, scaled down as a whole into the force box
|u_i| ≤ u_max (N): the new velocity then lies on the segment from (1 − ζ) v to v*, inside
the speed limit whether it bounds each axis or the norm.

Before each step the planner asks whether the UAV could still stop after it: the path
from the next state braking to rest (v* = 0, at most ``brake_steps`` steps) must keep the
planners' clearance ε (``MissionSpec.clearance_m``) from every obstacle; if it would not,
the step brakes instead. The plan (``horizon`` steps) is then checked as every plan of the
house is (:func:`dualpilot.verify.verify_trajectory`: Eq. (1), the limits, the clearance
from the obstacles, segment by segment; and the area) and cut to its longest prefix that
passes; a plan whose first step fails is UNSAFE. No randomness: the same state and
obstacles give the same plan.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualpilot.model.dynamics import Array, DynamicsParams, rollout, step
from dualpilot.model.geometry import Polytope, path_clearance
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.planners import PlannerMethod
from dualpilot.spec import MissionSpec
from dualpilot.verify import verify_trajectory


@dataclass(frozen=True)
class StraightParams:
    """The straight line's settings (speeds m/s; None: the spec's v_max)."""

    #: steps planned
    horizon: int = 10
    #: the cruise speed (None: v_max of Eq. (1)'s speed limit)
    cruise_mps: float | None = None
    #: the most steps the braking path is followed when checking that the UAV can stop
    brake_steps: int = 10

    def __post_init__(self) -> None:
        if self.horizon < 1 or self.brake_steps < 1:
            raise ValueError("horizon and brake_steps must be >= 1")
        if self.cruise_mps is not None and not self.cruise_mps > 0:
            raise ValueError(f"cruise_mps must be > 0, got {self.cruise_mps}")


def force_towards(x: Array, v_wanted: Array, dyn: DynamicsParams) -> Array:
    """The force (N) that takes the velocity of ``x`` to ``v_wanted`` in one ΔT (Eq. 1),
    scaled as a whole into |u_i| ≤ u_max."""
    v = x[dyn.dim:]
    raw = dyn.mass_kg * (np.asarray(v_wanted, dtype=float) - (1.0 - dyn.zeta) * v) / dyn.dt_s
    peak = float(np.max(np.abs(raw)))
    return raw if peak <= dyn.u_max_n else raw * (dyn.u_max_n / peak)


def braking_path(x: Array, dyn: DynamicsParams, steps: int) -> Array:
    """The positions (k, 2) from ``x`` braking towards rest, at most ``steps`` steps (m)."""
    points = [x[: dyn.dim].copy()]
    for _ in range(steps):
        if float(np.max(np.abs(x[dyn.dim:]))) < 1e-9:
            break
        x = step(x, force_towards(x, np.zeros(dyn.dim), dyn), dyn)
        points.append(x[: dyn.dim].copy())
    return np.array(points)


class StraightSystem1:
    """System 1 "straight": straight at G's centre, braking before a fire (module docstring)."""

    system = 1
    method = "straight"

    def __init__(self, spec: MissionSpec, params: StraightParams = StraightParams()):
        self.spec = spec
        self.params = params

    def _wanted(self, x: Array) -> Array:
        """v* of the module docstring (m/s)."""
        dyn = self.spec.dynamics
        to_goal = np.asarray(self.spec.goal.center, dtype=float) - x[: dyn.dim]
        dist = float(np.linalg.norm(to_goal))
        if dist < 1e-9:
            return np.zeros(dyn.dim)
        cruise = self.params.cruise_mps or dyn.v_max_mps
        return to_goal / dist * min(cruise, dist / dyn.dt_s)

    def _stoppable(self, x: Array, nxt: Array, hulls: tuple[Polytope, ...]) -> bool:
        """Whether the step x → nxt, then braking to rest, keeps ε from every obstacle."""
        dyn = self.spec.dynamics
        path = np.vstack([x[None, : dyn.dim], braking_path(nxt, dyn, self.params.brake_steps)])
        return path_clearance(path, hulls) >= self.spec.clearance_m

    def _in_area(self, states: Array) -> bool:
        return bool(np.all((states[:, :2] >= 0.0) & (states[:, :2] <= self.spec.area_size_m)))

    def plan(self, state: Array, hulls: tuple[Polytope, ...],
             objective: Objective = Objective.MISSION_TIME,
             prev_control: Array | None = None) -> Plan:
        """A straight-line plan from ``state`` (objective and u_{t|t} are not used)."""
        t0 = time.perf_counter()
        dyn = self.spec.dynamics
        x0 = np.asarray(state, dtype=float)
        x, controls = x0, []
        for _ in range(self.params.horizon):
            u = force_towards(x, self._wanted(x), dyn)
            nxt = step(x, u, dyn)
            if not self._stoppable(x, nxt, hulls):
                u = force_towards(x, np.zeros(dyn.dim), dyn)
                nxt = step(x, u, dyn)
            controls.append(u)
            x = nxt
        us = np.array(controls)
        xs = rollout(x0, us, dyn)
        for k in range(len(us), 0, -1):  # the longest prefix that passes the checks
            verdict = verify_trajectory(xs[: k + 1], us[:k], hulls, dyn, self.spec.clearance_m,
                                        rolled_out=True)
            if verdict.ok and self._in_area(xs[: k + 1]):
                return Plan(1, PlanStatus.OK, xs[: k + 1], us[:k], time.perf_counter() - t0,
                            objective=objective, message=f"straight line, {k} steps",
                            info={"planner": "straight"})
        return Plan.failed(1, PlanStatus.UNSAFE, time.perf_counter() - t0,
                           "straight line: the first step leaves the clearance or the area")


def _build(spec: MissionSpec, params: Any) -> StraightSystem1:
    """The registry's constructor: System 1's parameters (System1Params) do not apply."""
    return StraightSystem1(spec)


#: The entry point ``straight`` of group ``dualpilot.planners``: a System 1 method with no
#: risk-aware variant.
STRAIGHT = PlannerMethod(1, _build, None, "straight at G's centre, braking before a fire")
