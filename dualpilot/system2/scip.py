"""Problem (P2) as an MIQP in native SCIP (PySCIPOpt), seeded with an incumbent.

The same problem as :class:`dualpilot.system2.exact.ExactSystem2` — Eq. (S2) with
Eq. (P2_1)-(P2_6) and big-M avoidance over every face of every hull — with
three differences that help the branch and bound, none of which changes the
optimum:

* the true hull faces are used (no slots, so no conservative simplification);
* each big-M is the tightest valid one, M_{i,l} = β_{i,l} + ε − min_{p∈area} α_{i,l}·p,
  and (τ, i) pairs that no p_τ can reach are dropped (per-axis reach at the
  speed and force limits);
* a verified plan (the fast method's) is added as the starting incumbent, so
  every node worse than it is pruned from the start.

The quadratic objective is moved into one convex constraint J(X, U) ≤ t.
SCIP's dual bound gives a certified lower bound on the optimum even when the
time limit stops it.

In 3-D (``dynamics.dim == 3``) the hulls are prisms (every face: a cuboid's six), the
altitude band bounds every planned z and is part of the box the tightest M is taken over,
as in :class:`dualpilot.system2.exact.ExactSystem2` (docs/three_d.md, 6).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualpilot.arrays import AnyArray
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import (
    DynamicsParams,
    reach_boxes,
    rollout,
    speed_polygon,
    transition_matrices,
)
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.problem import Obstacle, System2Params, p2_cost, verify_p2_plan


@dataclass(frozen=True)
class ScipResult:
    """Best controls found (None if none), status, objective, dual bound and time (s)."""

    controls: AnyArray | None
    status: str
    objective: float
    dual_bound: float
    optimal: bool
    time_s: float
    n_binaries: int


def solve_seeded(x0: AnyArray, hulls: Sequence[Obstacle], goal: AnyArray,
                 kappa: tuple[float, float], u_prev: AnyArray, params: System2Params,
                 dyn: DynamicsParams, incumbent: AnyArray | None, time_limit_s: float,
                 epsilon_m: float, area_size_m: float | None,
                 band: AltitudeBand | None = None) -> ScipResult:
    """Solve (P2) with SCIP from the incumbent controls (T, dim); see the module docstring.

    ``epsilon_m`` is ε of Eq. (P2_3); ``area_size_m`` None plans without the area bounds;
    ``band`` bounds z in 3-D (default: the default band).
    """
    from pyscipopt import Model

    t0 = time.perf_counter()
    T = params.horizon
    eps = epsilon_m
    m = Model("P2")
    m.hideOutput()
    m.setParam("limits/time", max(0.1, float(time_limit_s)))
    if dyn.dim == 3 and dyn.speed_limit == "norm":
        raise ValueError("the seeded exact method plans in 3-D under speed_limit = 'axis' only")
    band = AltitudeBand() if band is None else band
    u, x = _add_dynamics(m, x0, T, dyn, area_size_m, band)
    if dyn.speed_limit == "norm":
        _add_speed_polygon(m, x, params.speed_polygon_sides, dyn)
    binaries = _add_avoidance(m, x, x0, hulls, T, dyn, eps, area_size_m, band)
    t = _add_objective(m, x, u, goal, kappa, u_prev)
    if incumbent is not None:
        _add_incumbent(m, incumbent, x0, hulls, goal, kappa, u_prev, eps, dyn, u, x, binaries,
                       t)
    m.optimize()
    status = str(m.getStatus())
    controls, obj, dual = _read_solution(m, u)
    return ScipResult(controls, status, obj, dual, status == "optimal",
                      time.perf_counter() - t0, len(binaries))


def _add_dynamics(m: Any, x0: AnyArray, T: int, dyn: DynamicsParams, area: float | None,
                  band: AltitudeBand) -> tuple[list[list[Any]], list[list[Any]]]:
    """Controls u (T, dim) in ±u_max (N), states x (T, 2·dim) and Eq. (P2_1)-(P2_2),
    x_{k+1} = Φx_k + Γu.

    Positions x, y lie in [0, ``area``] m (unbounded for None), z (3-D) in ``band``,
    velocities in ±v_max (m/s).
    """
    from pyscipopt import quicksum

    n = dyn.dim
    phi, gamma = transition_matrices(dyn)
    inf = m.infinity()
    u = [[m.addVar(lb=-dyn.u_max_n, ub=dyn.u_max_n, name=f"u{k}_{a}") for a in range(n)]
         for k in range(T)]
    pos_lb, pos_ub = (0.0, area) if area is not None else (-inf, inf)
    lb = [pos_lb, pos_lb] + [band.floor_m] * (n - 2) + [-dyn.v_max_mps] * n
    ub = [pos_ub, pos_ub] + [band.ceiling_m] * (n - 2) + [dyn.v_max_mps] * n
    x = [[m.addVar(lb=lb[a], ub=ub[a], name=f"x{k}_{a}") for a in range(2 * n)]
         for k in range(T)]
    for k in range(T):
        prev = [float(v) for v in x0] if k == 0 else x[k - 1]
        for r in range(2 * n):
            m.addCons(x[k][r] == quicksum(phi[r, c] * prev[c] for c in range(2 * n) if phi[r, c])
                      + quicksum(gamma[r, c] * u[k][c] for c in range(n) if gamma[r, c]))
    return u, x


def _add_speed_polygon(m: Any, x: list[list[Any]], sides: int, dyn: DynamicsParams) -> None:
    """X under "norm": n_j·v_τ ≤ v_max cos(π/K) for the K = ``sides`` normals, inside the disc."""
    normals, cos_k = speed_polygon(sides)
    for xk in x:
        for nx, ny in normals.tolist():
            m.addCons(nx * xk[2] + ny * xk[3] <= dyn.v_max_mps * cos_k)


def _add_avoidance(m: Any, x: list[list[Any]], x0: AnyArray, hulls: Sequence[Obstacle],
                   T: int, dyn: DynamicsParams, eps: float, area: float | None,
                   band: AltitudeBand) -> list[tuple[int, int, int, Any]]:
    """Eq. (P2_3)-(P2_4), big-M per face with the tightest M over p_τ's reach box (in 3-D
    cut to the band).

    Returns the binaries b as (k, hull, face, variable); (τ, i) pairs whose box
    keeps some face clear by ε (m) everywhere get none.
    """
    from pyscipopt import quicksum

    n = dyn.dim
    lo, hi = reach_boxes(x0, T, dyn)
    if area is not None:
        lo[:, :2], hi[:, :2] = np.maximum(lo[:, :2], 0.0), np.minimum(hi[:, :2], area)
    if n == 3:
        lo[:, 2] = np.maximum(lo[:, 2], band.floor_m)
        hi[:, 2] = np.minimum(hi[:, 2], band.ceiling_m)
    binaries: list[tuple[int, int, int, Any]] = []
    for i, h in enumerate(hulls):
        for k in range(T):
            # the least α·p over the reach box of p_{k+1}: the tightest valid big-M
            mins = np.minimum(h.A * lo[k], h.A * hi[k]).sum(axis=1)
            need = h.b + eps - mins  # > 0 where face l can be violated inside the box
            if np.any(need <= 0):
                continue  # some face holds everywhere in the box: the pair is always safe
            bs = []
            for l_ in range(h.n_faces):
                b = m.addVar(vtype="B", name=f"b{k}_{i}_{l_}")
                lhs = (h.A[l_, 0] * x[k][0] + h.A[l_, 1] * x[k][1] if n == 2 else
                       quicksum(float(h.A[l_, a]) * x[k][a] for a in range(n)))
                m.addCons(lhs >= h.b[l_] + eps - need[l_] * b)
                bs.append(b)
                binaries.append((k, i, l_, b))
            m.addCons(quicksum(bs) <= h.n_faces - 1)
    return binaries


def _add_objective(m: Any, x: list[list[Any]], u: list[list[Any]], goal: AnyArray,
                   kappa: tuple[float, float], u_prev: AnyArray) -> Any:
    """Eq. (S2) as the convex constraint J(X, U) ≤ t; minimises t and returns it."""
    from pyscipopt import quicksum

    T, n = len(x), len(u[0])
    t = m.addVar(lb=0.0, ub=m.infinity(), name="J")
    k1, k2 = kappa
    if n == 2:
        expr = quicksum(k1 * ((x[k][0] - goal[0]) ** 2 + (x[k][1] - goal[1]) ** 2)
                        for k in range(T))
    else:
        expr = quicksum(k1 * quicksum((x[k][a] - goal[a]) ** 2 for a in range(n))
                        for k in range(T))
    expr += quicksum(k2 * ((u[0][a] - float(u_prev[a])) ** 2) for a in range(n))
    expr += quicksum(k2 * ((u[k][a] - u[k - 1][a]) ** 2) for k in range(1, T) for a in range(n))
    m.addCons(expr <= t)
    m.setObjective(t, "minimize")
    return t


def _read_solution(m: Any, u: list[list[Any]]) -> tuple[AnyArray | None, float, float]:
    """The best controls (T, dim) (None if none), their objective and SCIP's dual bound."""
    controls: AnyArray | None = None
    obj = math.inf
    if m.getNSols() > 0:
        sol = m.getBestSol()
        controls = np.array([[m.getSolVal(sol, uk[a]) for a in range(len(uk))] for uk in u])
        obj = float(m.getSolObjVal(sol))
    try:
        dual = float(m.getDualbound())
    except Exception:  # noqa: BLE001 - no bound when nothing was solved
        dual = -math.inf
    return controls, obj, dual


def _add_incumbent(m: Any, controls: AnyArray, x0: AnyArray, hulls: Sequence[Obstacle],
                   goal: AnyArray, kappa: tuple[float, float], u_prev: AnyArray, eps: float,
                   dyn: DynamicsParams,
                   u: list[list[Any]], x: list[list[Any]],
                   binaries: list[tuple[int, int, int, Any]], t: Any) -> None:
    ctrl = np.clip(np.asarray(controls, dtype=float), -dyn.u_max_n, dyn.u_max_n)
    states = rollout(x0, ctrl, dyn)
    sol = m.createSol()
    n = dyn.dim
    for k in range(len(ctrl)):
        for a in range(n):
            m.setSolVal(sol, u[k][a], float(ctrl[k, a]))
        for r in range(2 * n):
            m.setSolVal(sol, x[k][r], float(states[k + 1, r]))
    for k, i, l_, b in binaries:
        h = hulls[i]
        ok = float(h.A[l_] @ states[k + 1, :n]) >= h.b[l_] + eps - 1e-9
        m.setSolVal(sol, b, 0.0 if ok else 1.0)
    m.setSolVal(sol, t, p2_cost(states, ctrl, goal, kappa, u_prev) * (1 + 1e-9) + 1e-9)
    m.addSol(sol, free=True)


class SeededExactSystem2:
    """(P2) solved by SCIP from an incumbent plan; ``plan`` takes the incumbent's controls.

    Run in a :class:`dualpilot.system2.worker.Worker`:
    ``plan(state, hulls, objective, prev_control, incumbent)``. The returned
    plan is checked with :func:`dualpilot.system2.problem.verify_p2_plan`;
    ``info`` carries SCIP's status, dual bound and whether it proved optimality.
    """

    system = 2
    method = "exact-seeded"

    def __init__(self, spec: MissionSpec, params: System2Params = System2Params()) -> None:
        self.spec, self.params = spec, params
        self.goal, self.dynamics = spec.goal, spec.dynamics
        self.goal_o = spec.goal_center  # G_o of Eq. (S2), at its altitude in 3-D
        self.area = spec.area_size_m if params.keep_in_area else None

    def plan(self, state: AnyArray, hulls: Sequence[Obstacle],
             objective: Objective = Objective.MISSION_TIME,
             prev_control: AnyArray | None = None, incumbent: AnyArray | None = None) -> Plan:
        t0 = time.perf_counter()
        x0 = np.asarray(state, dtype=float)
        n = self.dynamics.dim
        u_prev = np.zeros(n) if prev_control is None else np.asarray(prev_control, dtype=float)
        kappa = self.params.kappa(objective)
        eps = self.spec.clearance_m
        res = solve_seeded(x0, tuple(hulls), self.goal_o, kappa, u_prev, self.params,
                           self.dynamics, incumbent, self.params.time_limit_s, eps, self.area,
                           self.spec.band)
        info: dict[str, object] = {"solver_status": res.status, "optimal": res.optimal,
                                   "dual_bound": res.dual_bound, "n_binaries": res.n_binaries,
                                   "solver_objective": res.objective}
        if res.controls is None:
            status = PlanStatus.INFEASIBLE if res.status == "infeasible" else PlanStatus.TIMEOUT
            plan = Plan.failed(2, status, time.perf_counter() - t0, f"SCIP: {res.status}",
                               dim=n)
            return dataclasses.replace(plan, objective=objective, info=info)
        controls = np.clip(res.controls, -self.dynamics.u_max_n, self.dynamics.u_max_n)
        states = rollout(x0, controls, self.dynamics)
        verdict = verify_p2_plan(states, controls, tuple(hulls), self.dynamics, eps,
                                 self.spec.d_safe_m, self.area, tol=1e-3,
                                 band=self.spec.band if n == 3 else None)
        cost = p2_cost(states, controls, self.goal_o, kappa, u_prev)
        if not verdict.ok:
            plan = Plan.failed(2, PlanStatus.UNSAFE, time.perf_counter() - t0,
                               f"SCIP plan failed verification: {verdict.reason}", dim=n)
            return dataclasses.replace(plan, objective=objective, info=info)
        return Plan(system=2, status=PlanStatus.OK, states=states, controls=controls,
                    compute_time_s=time.perf_counter() - t0, objective=objective, cost=cost,
                    info=info)
