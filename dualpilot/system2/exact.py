"""System 2, the exact reference: Problem (P2) as a mixed-integer QP in cvxpy.

Eq. (S2) objective, Eq. (P2_1)-(P2_6) constraints, solved to optimality by
SCIP (or Gurobi when a working licence is present). The problem is built once
with DPP parameters and re-solved each tick by updating ``.value``.

Avoidance, Eq. (P2_3)-(P2_4), is big-M over the faces of each H-polytope (unit
outward normals α, margin ε in m) in fixed slots (``max_hulls`` ×
``max_faces``); more reachable hulls than slots: INVALID_INPUT. A plan is the
roll-out of Eq. (1) under the solver's controls, verified at the spec's d_safe;
``Plan.cost`` is the Eq. (S2) value. ``isolate=True`` (the registry's "exact")
runs the solver in a :class:`dualpilot.system2.worker.Worker` with a hard
deadline.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
import warnings
import weakref
from collections.abc import Mapping, Sequence
from typing import Any

import cvxpy as cp
import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.dynamics import reach_radius, rollout, speed_polygon, transition_matrices
from dualpilot.model.geometry import Polytope
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.geometry import Inflated
from dualpilot.system2.problem import System2Params, check_request, p2_cost
from dualpilot.system2.worker import PlannerFactory, Worker
from dualpilot.verify import verify_trajectory

_SOLVERS = ("auto", "SCIP", "GUROBI")

DEFAULT_SCIP_OPTIONS: dict[str, Any] = {
    "separating/maxroundsroot": 15,
    "separating/maxrounds": 2,
}
"""Fewer cut rounds: SCIP's root cut loop on the outer approximation of the
quadratic objective otherwise ate the whole budget (T = 80: 1 hull 23 s -> ~13 s,
3 hulls 45 s limit with 3 % gap -> optimal in 7-15 s). User options override."""


def gurobi_available() -> bool:
    """True if gurobipy imports and cvxpy lists Gurobi (the licence is tried on first solve)."""
    try:
        import gurobipy  # noqa: F401
    except ImportError:
        return False
    return "GUROBI" in cp.installed_solvers()


def face_inflated(poly: Polytope, eps: float) -> Polytope:
    """{p : α_l·p ≤ β_l + ε ∀l}: the region Eq. (P2_3)-(P2_4) forbid, faces pushed out by ε (m).

    It extends beyond the ε-distance offset at sharp vertices; the vertices
    are those of :class:`dualpilot.system2.fast.geometry.Inflated`.
    """
    return poly if eps <= 0 else Polytope.from_vertices(Inflated.make(poly, eps).W)


def outer_simplify(poly: Polytope, max_faces: int) -> Polytope:
    """A polygon with at most ``max_faces`` faces that contains ``poly``.

    Greedily removes the edge whose removal (extending its two neighbours to
    their intersection) adds the least area; only edges whose neighbours
    meet on the outside (turn < π) are removable, so the result stays bounded.
    """
    if max_faces < 4:
        raise ValueError(f"max_faces must be >= 4, got {max_faces}")
    verts = [np.asarray(p, dtype=float) for p in poly.vertices]
    while len(verts) > max_faces:
        k = len(verts)
        best: tuple[float, int, Array] | None = None
        for i in range(k):
            # edge i runs verts[i] -> verts[i+1]; its neighbours are a0->a1 and b0->b1
            a0, a1 = verts[i - 1], verts[i]
            b0, b1 = verts[(i + 1) % k], verts[(i + 2) % k]
            da, db = a1 - a0, b1 - b0
            den = da[0] * db[1] - da[1] * db[0]
            if den <= 1e-12 * np.linalg.norm(da) * np.linalg.norm(db):
                continue  # neighbours parallel or diverging: removal would be unbounded
            s = ((b0 - a0)[0] * db[1] - (b0 - a0)[1] * db[0]) / den
            r = ((b0 - a0)[0] * da[1] - (b0 - a0)[1] * da[0]) / den
            if s < 1.0 - 1e-12 or r > 1e-12:
                continue  # the extended neighbours would not meet outside edge i
            apex = a0 + s * da
            area = 0.5 * abs((b0 - a1)[0] * (apex - a1)[1] - (b0 - a1)[1] * (apex - a1)[0])
            if best is None or area < best[0]:
                best = (area, i, apex)
        if best is None:  # cannot happen for a convex polygon with > 4 edges
            raise ValueError("cannot simplify polygon conservatively")
        _, i, apex = best
        j = (i + 1) % k
        # replace verts[i] and verts[j] by the apex
        verts = [apex] + verts[1:i] if j == 0 else verts[:i] + [apex] + verts[j + 1 :]
    return Polytope.from_vertices(np.array(verts))


class ExactSystem2:
    """Problem (P2) solved exactly (MIQP, big-M avoidance) with SCIP or Gurobi.

    Parameters
    ----------
    spec : MissionSpec
        Goal G (its centre is G_o of Eq. (S2)), area, ε (``clearance_m``),
        the d_safe every returned plan is verified against, and Eq. (1).
    params : System2Params
        Horizon T, M, κ, slots, time limit (s).
    solver : {"auto", "SCIP", "GUROBI"}
        "auto" tries Gurobi when available and falls back to SCIP for good
        if Gurobi fails (e.g. a size-limited licence).
    objective_scale : float
        The solver minimises J / objective_scale (numerics only: with SCIP's
        outer approximation of the quadratic objective, 10 solved the T = 80
        instances we tried 1.5-2x faster than 1 or 1e3).
    solver_options : mapping, optional
        Extra native parameters (SCIP names such as ``"limits/gap"``, or
        Gurobi names), merged over the time limit and ``DEFAULT_SCIP_OPTIONS``.
    isolate : bool
        Solve in a persistent worker process with a hard deadline (see the
        module notes). The worker is spawned on the first plan (~2 s; a
        script using it needs the usual ``if __name__ == "__main__":`` guard)
        and stopped by :meth:`close` or when the planner is garbage-collected.
    hard_timeout_s : float, optional
        With ``isolate``, the worker is killed after this long per solve
        (default 1.5 × time_limit_s + 10 s, which covers the first compile).
    """

    system = 2
    method = "exact"

    def __init__(
        self,
        spec: MissionSpec,
        params: System2Params = System2Params(),
        solver: str = "auto",
        *,
        objective_scale: float = 10.0,
        solver_options: Mapping[str, Any] | None = None,
        isolate: bool = False,
        hard_timeout_s: float | None = None,
    ) -> None:
        dynamics = spec.dynamics
        if dynamics.dim != 2:
            raise ValueError(f"ExactSystem2 plans in 2-D (Sec. IV); got dim={dynamics.dim}")
        if params.max_hulls < 1 or params.max_faces < 4:
            raise ValueError("need max_hulls >= 1 and max_faces >= 4")
        if solver.upper() not in ("AUTO", "SCIP", "GUROBI"):
            raise ValueError(f"solver must be one of {_SOLVERS}, got {solver!r}")
        if not objective_scale > 0:
            raise ValueError("objective_scale > 0 is required")
        if hard_timeout_s is not None and not hard_timeout_s > 0:
            raise ValueError(f"hard_timeout_s must be positive, got {hard_timeout_s}")
        solver = solver.upper()
        if solver == "GUROBI" and not gurobi_available():
            raise ValueError("solver='GUROBI' but gurobipy is not installed")
        if solver == "SCIP" and "SCIP" not in cp.installed_solvers():
            raise ValueError("solver='SCIP' but pyscipopt is not installed")
        self.spec = spec
        self.goal = spec.goal
        self.params = params
        self.dynamics = dynamics
        self.clearance_m = spec.d_safe_m  # every returned plan keeps d_safe
        self.epsilon_m = spec.clearance_m  # ε of Eq. (P2_3)
        self.area_size_m = spec.area_size_m
        self.objective_scale = float(objective_scale)
        self.solver_options = dict(solver_options or {})
        self.fallback_reason = ""
        if solver == "AUTO":
            self._solvers = ["GUROBI", "SCIP"] if gurobi_available() else ["SCIP"]
        else:
            self._solvers = [solver]
        self.hard_timeout_s = (
            1.5 * params.time_limit_s + 10.0 if hard_timeout_s is None else float(hard_timeout_s)
        )
        self._build()
        self._worker: Worker | None = None
        if isolate:
            options = {"objective_scale": self.objective_scale,
                       "solver_options": self.solver_options}
            self._worker = Worker(PlannerFactory(ExactSystem2, spec, params, options,
                                                 answer="solve_values"))
            self._finalizer = weakref.finalize(self, self._worker.stop)

    def close(self) -> None:
        """Stop the worker process, if any (the planner stays usable; it restarts)."""
        if self._worker is not None:
            self._worker.stop()

    def __enter__(self) -> ExactSystem2:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ build
    def _build(self) -> None:
        """Compile (P2) once; every tick only sets parameter values."""
        p, d = self.params, self.dynamics
        T, H, F = p.horizon, p.max_hulls, p.max_faces
        phi, gamma = transition_matrices(d)
        big_m, eps = p.big_m, self.epsilon_m

        self._x0 = cp.Parameter(4, name="x0")
        # sqrt-weights keep the objective DPP: ‖w1 p − w1 G_o‖² = κ1/s ‖p − G_o‖²
        self._w1 = cp.Parameter(nonneg=True, name="w1")
        self._w1_goal = cp.Parameter(2, name="w1_goal")
        self._w2 = cp.Parameter(nonneg=True, name="w2")
        self._w2_uprev = cp.Parameter(2, name="w2_uprev")
        self._alpha = cp.Parameter((H * F, 2), name="alpha")
        self._beta = cp.Parameter((H * F, 1), name="beta")

        inf = np.inf
        pos_lo, pos_hi = (0.0, self.area_size_m) if p.keep_in_area else (-inf, inf)
        lo = np.tile([pos_lo, pos_lo, -d.v_max_mps, -d.v_max_mps], (T, 1))
        hi = np.tile([pos_hi, pos_hi, d.v_max_mps, d.v_max_mps], (T, 1))
        self._X = cp.Variable((T, 4), name="X", bounds=[lo, hi])  # x_{t+1|t}..x_{t+T|t}
        self._U = cp.Variable((T, 2), name="U", bounds=[-d.u_max_n, d.u_max_n])
        self._B = cp.Variable((H * F, T), boolean=True, name="b")
        xs, us, bs = self._X, self._U, self._B
        pos = xs[:, :2]
        speed: list[cp.Constraint] = []
        if d.speed_limit == "norm":  # X: n_k·v_τ ≤ v_max cos(π/K), inside the disc
            normals, cos_k = speed_polygon(p.speed_polygon_sides)
            speed.append(xs[:, 2:] @ normals.T <= d.v_max_mps * cos_k)

        cons = [
            xs[0] == phi @ self._x0 + gamma @ us[0],  # Eq. (P2_1)-(P2_2)
            xs[1:] == xs[:-1] @ phi.T + us[1:] @ gamma.T,
            # Eq. (P2_3): α·p_τ − β ≥ ε − M b
            self._alpha @ pos.T - self._beta @ np.ones((1, T)) >= eps - big_m * bs,
            # Eq. (P2_4): Σ_l b ≤ F − 1 per hull and τ
            np.kron(np.eye(H), np.ones((1, F))) @ bs <= F - 1,
            *speed,
        ]
        dist = self._w1 * pos - np.ones((T, 1)) @ cp.reshape(self._w1_goal, (1, 2), order="C")
        du0 = self._w2 * us[0] - self._w2_uprev
        du = self._w2 * (us[1:] - us[:-1])
        objective = cp.sum_squares(dist) + cp.sum_squares(du0) + cp.sum_squares(du)
        self.problem = cp.Problem(cp.Minimize(objective), cons)
        if not self.problem.is_dpp():
            raise RuntimeError("P2 is not DPP")  # pragma: no cover - construction bug
        # neutral values so the first compile succeeds
        self._alpha.value = np.zeros((H * F, 2))
        self._beta.value = np.full((H * F, 1), -big_m)
        self._x0.value = np.zeros(4)
        self._w1.value = 1.0
        self._w1_goal.value = np.zeros(2)
        self._w2.value = 1.0
        self._w2_uprev.value = np.zeros(2)

    # -------------------------------------------------------------- helpers
    def _select_hulls(
        self, state: Array, hulls: Sequence[Polytope]
    ) -> tuple[list[tuple[int, Polytope]], list[int]]:
        """Reachable hulls (index, polygon ≤ max_faces) sorted by distance; simplified indices."""
        eps = self.epsilon_m
        reach = reach_radius(state[2:], self.params.horizon, self.dynamics)
        kept: list[tuple[float, int, Polytope]] = []
        simplified: list[int] = []
        for i, hull in enumerate(hulls):
            poly = hull
            if poly.n_faces > self.params.max_faces:
                poly = outer_simplify(poly, self.params.max_faces)
                simplified.append(i)
            dist = face_inflated(poly, eps).distance(state[:2])
            if dist <= reach + 1e-6:
                kept.append((dist, i, poly))
        kept.sort(key=lambda item: item[0])
        return [(i, poly) for _, i, poly in kept], simplified

    def _set_hull_params(self, polys: Sequence[Polytope]) -> None:
        H, F, big_m = self.params.max_hulls, self.params.max_faces, self.params.big_m
        alpha = np.zeros((H * F, 2))
        beta = np.full((H * F, 1), -big_m)
        for k, poly in enumerate(polys):
            nf = poly.n_faces
            alpha[k * F:k * F + nf] = poly.A
            beta[k * F:k * F + nf, 0] = poly.b
            # padded face slot: 0 ≥ M/2 + ε − M b forces b = 1, so Σ_l b ≤ F − 1
            # leaves at least one real face with b = 0 (the disjunction is exact and,
            # unlike repeating a face, adds no symmetric choices for branching)
            beta[k * F + nf:(k + 1) * F, 0] = big_m / 2
        self._alpha.value = alpha
        self._beta.value = beta

    def _big_m_ok(self, state: Array, polys: Sequence[Polytope]) -> bool:
        """M must relax Eq. (P2_3) everywhere a planned position can be."""
        p = self.params
        if p.keep_in_area:
            lo, hi = np.zeros(2), np.full(2, self.area_size_m)
        else:
            r = reach_radius(state[2:], self.params.horizon, self.dynamics)
            lo, hi = state[:2] - r, state[:2] + r
        corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        for poly in polys:
            need = np.max(poly.b[:, None] + self.epsilon_m - poly.A @ corners.T)
            if need > p.big_m:
                return False
        return True

    # ----------------------------------------------------------------- plan
    def plan(
        self,
        state: Array,
        hulls: Sequence[Polytope],
        objective: Objective = Objective.MISSION_TIME,
        prev_control: Array | None = None,
    ) -> Plan:
        """Solve (P2) from ``state`` avoiding ``hulls``; ``prev_control`` is u_{t|t} (N)."""
        t0 = time.perf_counter()
        checked = check_request(state, hulls, objective, prev_control)
        if isinstance(checked, str):
            return self._fail(t0, objective, PlanStatus.INVALID_INPUT, checked)
        x0, u_prev, hulls = checked
        unsafe_start = self._start_too_close(x0, hulls)
        if unsafe_start is not None:
            return self._fail(t0, objective, PlanStatus.INVALID_INPUT, unsafe_start)

        selected, simplified = self._select_hulls(x0, hulls)
        info: dict[str, object] = {
            "n_hulls": len(selected), "n_hulls_input": len(hulls),
            "simplified_hulls": simplified,
        }
        polys, unfit = self._fit_hulls(x0, selected)
        if unfit is not None:
            return self._fail(t0, objective, PlanStatus.INVALID_INPUT, unfit, info)
        fixed = self._first_step_failure(x0, hulls)
        if fixed is not None:
            return self._fail(t0, objective, *fixed, info)

        kappa = self._set_values(x0, u_prev, objective, polys)
        result = self._solve()
        info.update({k: v for k, v in result.items() if k not in ("U", "X", "value")})
        status = str(result.get("solver_status"))
        failure = self._solver_failure(result, status, simplified)
        if failure is not None:
            return self._fail(t0, objective, *failure, info)
        return self._solution_plan(t0, objective, x0, u_prev, kappa, hulls, result, status, info)

    def _fail(self, t0: float, objective: Objective, status: PlanStatus, msg: str,
              info: Mapping[str, object] | None = None) -> Plan:
        """A failed plan with ``status``, a copy of ``info`` and the time since ``t0``."""
        plan = Plan.failed(self.system, status, time.perf_counter() - t0, msg)
        return dataclasses.replace(plan, objective=objective, info=dict(info or {}))

    def _start_too_close(self, x0: Array, hulls: Sequence[Polytope]) -> str | None:
        """Why no plan can start at ``x0`` (within d_safe of a hull: it is given, not planned)."""
        for i, hull in enumerate(hulls):
            dist = hull.distance(x0[:2])
            if dist < self.clearance_m:
                return (f"start {x0[:2]} is {dist:.2f} m from hull {i} "
                        f"(< d_safe {self.clearance_m} m): no safe plan can start here")
        return None

    def _fit_hulls(self, x0: Array, selected: Sequence[tuple[int, Polytope]]
                   ) -> tuple[list[Polytope], str | None]:
        """The selected polygons, and why they do not fit the compiled problem (slots, M)."""
        if len(selected) > self.params.max_hulls:
            return [], (f"{len(selected)} hulls are reachable within the horizon but the "
                        f"compiled problem has max_hulls={self.params.max_hulls}; construct "
                        "ExactSystem2 with a larger System2Params.max_hulls")
        polys = [poly for _, poly in selected]
        if not self._big_m_ok(x0, polys):
            return polys, f"big_m={self.params.big_m} is too small for this geometry"
        return polys, None

    def _first_step_failure(self, x0: Array, hulls: Sequence[Polytope]
                            ) -> tuple[PlanStatus, str] | None:
        """x_{t+1|t}'s position is p_t + ΔT v_t whatever the control: check it before solving.

        Within ε of a hull (Eq. (P2_3)) or outside the area: INFEASIBLE; the
        segment to it within d_safe of a hull: UNSAFE.
        """
        p1 = x0[:2] + self.dynamics.dt_s * x0[2:]
        eps = self.epsilon_m
        for i, hull in enumerate(hulls):
            margin = float(np.max(hull.A @ p1 - hull.b))
            if margin < eps:
                return (PlanStatus.INFEASIBLE,
                        f"x_(t+1|t) position {p1} is fixed by the current velocity and "
                        f"lies within ε={eps} m of hull {i} (max_l α·p−β = {margin:.2f}): "
                        "(P2) is infeasible")
        if self.params.keep_in_area and not (
            np.all(p1 >= 0.0) and np.all(p1 <= self.area_size_m)
        ):
            return (PlanStatus.INFEASIBLE,
                    f"x_(t+1|t) position {p1} is fixed by the current velocity and "
                    "lies outside the area: (P2) is infeasible")
        first_gap = min((h.segment_distance(x0[:2], p1) for h in hulls), default=math.inf)
        if first_gap < self.clearance_m:
            return (PlanStatus.UNSAFE,
                    f"the first segment, fixed by the current velocity, passes "
                    f"{first_gap:.2f} m from a hull (< {self.clearance_m} m)")
        return None

    def _set_values(self, x0: Array, u_prev: Array, objective: Objective,
                    polys: Sequence[Polytope]) -> tuple[float, float]:
        """Set the DPP parameters of (P2) for this tick; returns κ = (κ1, κ2) of Eq. (S2)."""
        k1, k2 = self.params.kappa(objective)
        s = self.objective_scale
        w1, w2 = math.sqrt(k1 / s), math.sqrt(k2 / s)
        self._x0.value = x0
        self._w1.value = w1
        self._w1_goal.value = w1 * self.goal.center
        self._w2.value = w2
        self._w2_uprev.value = w2 * u_prev
        self._set_hull_params(polys)
        return k1, k2

    def _solver_failure(self, result: Mapping[str, object], status: str,
                        simplified: Sequence[int]) -> tuple[PlanStatus, str] | None:
        """The failed status and message of a solve that gave no usable solution, else None."""
        if "error" in result:
            if result.get("timeout"):
                return (PlanStatus.TIMEOUT,
                        f"no incumbent within the time limit: {result['error']}")
            return PlanStatus.ERROR, f"solver failed: {result['error']}"
        if status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
            if result.get("timeout"):
                return PlanStatus.TIMEOUT, f"no incumbent within {self.params.time_limit_s} s"
            msg = "(P2) is infeasible: no safe trajectory over the horizon"
            if simplified:
                msg += f" (hulls {simplified} were enlarged to {self.params.max_faces} faces)"
            return PlanStatus.INFEASIBLE, msg
        u_sol, x_sol = result.get("U"), result.get("X")
        has_solution = status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE, cp.USER_LIMIT)
        if not has_solution or u_sol is None or x_sol is None:
            return PlanStatus.ERROR, f"solver returned status {status}"
        return None

    def _solution_plan(self, t0: float, objective: Objective, x0: Array, u_prev: Array,
                       kappa: tuple[float, float], hulls: Sequence[Polytope],
                       result: Mapping[str, object], status: str,
                       info: dict[str, object]) -> Plan:
        """The plan of the solver's controls: Eq. (1) roll-out, Eq. (S2) cost, verified."""
        controls = np.clip(np.asarray(result.get("U"), dtype=float),
                           -self.dynamics.u_max_n, self.dynamics.u_max_n)
        states = rollout(x0, controls, self.dynamics)
        info["dyn_residual"] = float(np.max(np.abs(states[1:] - np.asarray(result.get("X")))))
        info["optimal"] = status == cp.OPTIMAL
        cost = p2_cost(states, controls, self.goal.center, kappa, u_prev)
        value = result.get("value")
        if isinstance(value, float) and math.isfinite(value):
            info["solver_objective"] = value * self.objective_scale
        verdict = verify_trajectory(states, controls, hulls, self.dynamics,
                                    clearance_m=self.clearance_m)
        info["clearance_m"] = verdict.clearance_m
        elapsed = time.perf_counter() - t0
        if not verdict.ok:
            return Plan(system=self.system, status=PlanStatus.UNSAFE,
                        states=np.empty((0, 4)), controls=np.empty((0, 2)),
                        compute_time_s=elapsed, objective=objective, cost=cost,
                        message=f"solver plan ({status}) failed verification: {verdict.reason}",
                        info=info)
        return Plan(system=self.system, status=PlanStatus.OK, states=states, controls=controls,
                    compute_time_s=elapsed, objective=objective, cost=cost,
                    message="" if info["optimal"] else f"time limit hit: incumbent ({status})",
                    info=info)

    def _solve(self) -> dict[str, object]:
        """Solve with the first solver that works; returns status, solution and statistics."""
        while True:
            name = self._solvers[0]
            isolated = self._worker is not None
            out = self._solve_isolated(name) if isolated else self._solve_with(name)
            if "error" in out and len(self._solvers) > 1 and not out.get("timeout"):
                # e.g. a size-limited Gurobi licence: fall back for good
                self._solvers.pop(0)
                self.fallback_reason = f"{name}: {out['error']}"
                continue
            if self.fallback_reason:
                out["fallback"] = self.fallback_reason
            return out

    def _solve_isolated(self, name: str) -> dict[str, object]:
        """:meth:`_solve_with` in the worker, killed past ``hard_timeout_s``."""
        assert self._worker is not None
        values = {prm.name(): prm.value for prm in self.problem.parameters()}
        out, why = self._worker.solve((values, name), self.hard_timeout_s)
        if isinstance(out, dict):
            return out
        if why.startswith("killed"):
            return {"solver": name, "timeout": True,
                    "error": f"solver process killed after the hard deadline "
                             f"{self.hard_timeout_s:.1f} s"}
        return {"solver": name, "error": f"solver process: {why}"}

    def solve_values(self, values: Mapping[str, Any], name: str) -> dict[str, object]:
        """Set the parameters by name and solve in this process (the worker's handler)."""
        by_name = {prm.name(): prm for prm in self.problem.parameters()}
        for key, val in values.items():
            by_name[key].value = val
        return self._solve_with(name)

    def _solve_with(self, name: str) -> dict[str, object]:
        """One in-process solve of the compiled problem with solver ``name``."""
        tl = self.params.time_limit_s
        opts: dict[str, Any]
        if name == "SCIP":
            opts = {"scip_params": {**DEFAULT_SCIP_OPTIONS, "limits/time": tl,
                                    **self.solver_options}}
        else:
            opts = {"TimeLimit": tl, **self.solver_options}
        out: dict[str, object] = {"solver": name}
        t_solve = time.perf_counter()
        try:
            with warnings.catch_warnings():
                # cvxpy's bound inference multiplies inf by 0 on first compile
                warnings.simplefilter("ignore", RuntimeWarning)
                data, chain, inv = self.problem.get_problem_data(name, enforce_dpp=True)
            raw = chain.solve_via_data(self.problem, data, False, False, opts)
        except Exception as exc:  # noqa: BLE001 - any solver crash becomes an ERROR plan
            out["solver_time_s"] = time.perf_counter() - t_solve
            out["error"] = f"{type(exc).__name__}: {exc}"
            return out
        solver_time = time.perf_counter() - t_solve
        out["solver_time_s"] = solver_time
        native = None
        if isinstance(raw, dict):
            native = raw.get("scip_status")
            model = raw.pop("model", None)  # drop the SCIP model once read
            if model is not None:
                with contextlib.suppress(Exception):
                    gap = float(model.getGap())
                    out["mip_gap"] = gap if gap < 1e19 else math.inf  # 1e20: no incumbent
                    out["scip_time_s"] = float(model.getSolvingTime())
        out["native_status"] = native
        timed_out = native == "timelimit" or (native is None and solver_time >= 0.99 * tl)
        out["timeout"] = timed_out
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "solution may be inaccurate": we verify it
                self.problem.unpack_results(raw, chain, inv)
        except cp.error.SolverError as exc:
            out["error"] = str(exc)
            return out
        out["solver_status"] = self.problem.status
        if "mip_gap" not in out:
            with contextlib.suppress(Exception):
                gurobi_model: Any = self.problem.solver_stats.extra_stats
                out["mip_gap"] = float(gurobi_model.MIPGap)
        if self._U.value is not None and self._X.value is not None:
            out["U"] = np.array(self._U.value, dtype=float)
            out["X"] = np.array(self._X.value, dtype=float)
            val = self.problem.value
            out["value"] = float(val) if val is not None else math.nan  # type: ignore[arg-type]
        return out
