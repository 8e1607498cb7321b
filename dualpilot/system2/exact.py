"""System 2, the exact reference: Problem (P2) as a mixed-integer QP, solved to optimality.

The compiled cvxpy problem (:class:`dualpilot.system2.miqp.P2Miqp`, Eq. (S2) with
Eq. (P2_1)-(P2_6)) is solved by SCIP (or Gurobi when a working licence is present),
with the request's hulls in its slots (:mod:`dualpilot.system2.slots`); more reachable
hulls than slots: INVALID_INPUT. A plan is the roll-out of Eq. (1) under the solver's
controls, verified at the spec's d_safe; ``Plan.cost`` is the Eq. (S2) value.
``isolate=True`` (the registry's "exact") runs the solver in a
:class:`dualpilot.system2.worker.Worker` with a hard deadline.

In 3-D (``spec.dim == 3``, docs/three_d.md, 6) the hulls are prisms (a cuboid by its six
faces (α_l, β_l), Σ_{l=1..6} b ≤ 5), Eq. (1) has 3×3 blocks, the band bounds every planned
altitude, and a plan is returned only if it passes :func:`verify_p2_plan` with the band
and the prisms, the check every fast 3-D plan passes.
"""

from __future__ import annotations

import dataclasses
import math
import time
import weakref
from collections.abc import Mapping, Sequence
from typing import Any

import cvxpy as cp
import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.dynamics import rollout
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.miqp import P2Miqp, gurobi_available
from dualpilot.system2.problem import (
    Obstacle,
    System2Params,
    check_request,
    p2_cost,
    verify_p2_plan,
)
from dualpilot.system2.slots import big_m_ok, select_hulls
from dualpilot.system2.worker import PlannerFactory, Worker
from dualpilot.verify import Verdict, verify_trajectory

_SOLVERS = ("auto", "SCIP", "GUROBI")

#: How far (m) a 3-D exact plan may sit inside ε of Eq. (P2_3) and still pass the check:
#: SCIP keeps a binary within 1e-6 of its integer value, which with M = 1e5 relaxes a
#: big-M row by up to 0.1 m (d_safe itself is checked exactly).
DISJUNCTION_TOL_M = 0.1


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
        Gurobi names), merged over the time limit and
        :data:`dualpilot.system2.miqp.DEFAULT_SCIP_OPTIONS`.
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
        self.dim = dynamics.dim
        self.band = spec.band
        #: G_o of Eq. (S2): the goal's centre (2-D), at G_o's altitude (3-D)
        self.goal_o = spec.goal_center
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
        self.model = P2Miqp(params, dynamics, self.epsilon_m, spec.area_size_m,
                            self.objective_scale, spec.band)
        self.problem = self.model.problem
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

    # ----------------------------------------------------------------- plan
    def plan(
        self,
        state: Array,
        hulls: Sequence[Obstacle],
        objective: Objective = Objective.MISSION_TIME,
        prev_control: Array | None = None,
    ) -> Plan:
        """Solve (P2) from ``state`` avoiding ``hulls`` (polygons in 2-D, prisms in 3-D);
        ``prev_control`` is u_{t|t} (N)."""
        t0 = time.perf_counter()
        checked = check_request(state, hulls, objective, prev_control,
                                dim=self.dim)  # type: ignore[call-overload]
        if isinstance(checked, str):
            return self._fail(t0, objective, PlanStatus.INVALID_INPUT, checked)
        x0, u_prev, hulls = checked
        unsafe_start = self._start_too_close(x0, hulls)
        if unsafe_start is not None:
            return self._fail(t0, objective, PlanStatus.INVALID_INPUT, unsafe_start)

        selected, simplified = select_hulls(x0, hulls, self.params, self.dynamics,
                                            self.epsilon_m)
        info: dict[str, object] = {
            "n_hulls": len(selected), "n_hulls_input": len(hulls),
            "simplified_hulls": simplified,
        }
        polys, unfit = self._fit_hulls(x0, selected)
        if unfit is not None:
            return self._fail(t0, objective, PlanStatus.INVALID_INPUT, unfit, info)
        fixed = first_step_failure(x0, hulls, self.spec, self.params.keep_in_area)
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
        plan = Plan.failed(self.system, status, time.perf_counter() - t0, msg, dim=self.dim)
        return dataclasses.replace(plan, objective=objective, info=dict(info or {}))

    def _start_too_close(self, x0: Array, hulls: Sequence[Obstacle]) -> str | None:
        """Why no plan can start at ``x0`` (within d_safe of a hull: it is given, not planned)."""
        p0 = x0[:self.dim]
        for i, hull in enumerate(hulls):
            dist = hull.distance(p0)
            if dist < self.clearance_m:
                return (f"start {p0} is {dist:.2f} m from hull {i} "
                        f"(< d_safe {self.clearance_m} m): no safe plan can start here")
        return None

    def _fit_hulls(self, x0: Array, selected: Sequence[tuple[int, Obstacle]]
                   ) -> tuple[list[Obstacle], str | None]:
        """The selected polygons, and why they do not fit the compiled problem (slots, M)."""
        if len(selected) > self.params.max_hulls:
            return [], (f"{len(selected)} hulls are reachable within the horizon but the "
                        f"compiled problem has max_hulls={self.params.max_hulls}; construct "
                        "ExactSystem2 with a larger System2Params.max_hulls")
        polys = [poly for _, poly in selected]
        if not big_m_ok(x0, polys, self.params, self.dynamics, self.epsilon_m,
                        self.area_size_m, self.band):
            return polys, f"big_m={self.params.big_m} is too small for this geometry"
        return polys, None

    def _set_values(self, x0: Array, u_prev: Array, objective: Objective,
                    polys: Sequence[Obstacle]) -> tuple[float, float]:
        """Set the DPP parameters of (P2) for this tick; returns κ = (κ1, κ2) of Eq. (S2)."""
        kappa = self.params.kappa(objective)
        self.model.set_values(x0, u_prev, self.goal_o, kappa, polys)
        return kappa

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
                       kappa: tuple[float, float], hulls: Sequence[Obstacle],
                       result: Mapping[str, object], status: str,
                       info: dict[str, object]) -> Plan:
        """The plan of the solver's controls: Eq. (1) roll-out, Eq. (S2) cost, verified."""
        controls = np.clip(np.asarray(result.get("U"), dtype=float),
                           -self.dynamics.u_max_n, self.dynamics.u_max_n)
        states = rollout(x0, controls, self.dynamics)
        info["dyn_residual"] = float(np.max(np.abs(states[1:] - np.asarray(result.get("X")))))
        info["optimal"] = status == cp.OPTIMAL
        cost = p2_cost(states, controls, self.goal_o, kappa, u_prev)
        value = result.get("value")
        if isinstance(value, float) and math.isfinite(value):
            info["solver_objective"] = value * self.objective_scale
        verdict = self._verify(states, controls, hulls)
        info["clearance_m"] = verdict.clearance_m
        elapsed = time.perf_counter() - t0
        if not verdict.ok:
            return Plan(system=self.system, status=PlanStatus.UNSAFE,
                        states=np.empty((0, 2 * self.dim)), controls=np.empty((0, self.dim)),
                        compute_time_s=elapsed, objective=objective, cost=cost,
                        message=f"solver plan ({status}) failed verification: {verdict.reason}",
                        info=info)
        return Plan(system=self.system, status=PlanStatus.OK, states=states, controls=controls,
                    compute_time_s=elapsed, objective=objective, cost=cost,
                    message="" if info["optimal"] else f"time limit hit: incumbent ({status})",
                    info=info)

    def _verify(self, states: Array, controls: Array, hulls: Sequence[Obstacle]) -> Verdict:
        """The independent check: Eq. (1), U, X and d_safe (2-D); in 3-D
        :func:`verify_p2_plan` with the band and the prisms (the fast 3-D plans' check), its
        ε-disjunction to :data:`DISJUNCTION_TOL_M` (the solver's feasibility tolerance on
        big-M rows)."""
        if self.dim == 2:
            return verify_trajectory(states, controls, hulls,  # type: ignore[arg-type]
                                     self.dynamics, clearance_m=self.clearance_m)
        area = self.area_size_m if self.params.keep_in_area else None
        return verify_p2_plan(states, controls, hulls, self.dynamics, self.epsilon_m,
                              self.clearance_m, area, tol=DISJUNCTION_TOL_M, rolled_out=True,
                              band=self.band)

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
        out, why = self._worker.solve((self.model.values(), name), self.hard_timeout_s)
        if isinstance(out, dict):
            return out
        if why.startswith("killed"):
            return {"solver": name, "timeout": True,
                    "error": f"solver process killed after the hard deadline "
                             f"{self.hard_timeout_s:.1f} s"}
        return {"solver": name, "error": f"solver process: {why}"}

    def solve_values(self, values: Mapping[str, Any], name: str) -> dict[str, object]:
        """Set the parameters by name and solve in this process (the worker's handler)."""
        self.model.load(values)
        return self._solve_with(name)

    def _solve_with(self, name: str) -> dict[str, object]:
        """One in-process solve of the compiled problem with solver ``name``."""
        return self.model.solve(name, self.solver_options)


def first_step_failure(x0: Array, hulls: Sequence[Obstacle], spec: MissionSpec,
                       keep_in_area: bool) -> tuple[PlanStatus, str] | None:
    """x_{t+1|t}'s position is p_t + ΔT v_t whatever the control: check it before solving.

    Within ε of a hull (Eq. (P2_3)), outside the area (``keep_in_area``) or (3-D) the band:
    INFEASIBLE; the segment to it within the spec's d_safe of a hull: UNSAFE.
    """
    n, band = spec.dim, spec.band
    p0 = x0[:n]
    p1 = p0 + spec.dynamics.dt_s * x0[n:]
    eps, d_safe = spec.clearance_m, spec.d_safe_m
    for i, hull in enumerate(hulls):
        margin = float(np.max(hull.A @ p1 - hull.b))
        if margin < eps:
            return (PlanStatus.INFEASIBLE,
                    f"x_(t+1|t) position {p1} is fixed by the current velocity and "
                    f"lies within ε={eps} m of hull {i} (max_l α·p−β = {margin:.2f}): "
                    "(P2) is infeasible")
    if keep_in_area and not (np.all(p1[:2] >= 0.0) and np.all(p1[:2] <= spec.area_size_m)):
        return (PlanStatus.INFEASIBLE,
                f"x_(t+1|t) position {p1} is fixed by the current velocity and "
                "lies outside the area: (P2) is infeasible")
    if n == 3 and not band.contains(float(p1[2])):
        return (PlanStatus.INFEASIBLE,
                f"x_(t+1|t) position {p1} is fixed by the current velocity and lies "
                f"outside the band [{band.floor_m}, {band.ceiling_m}] m: "
                "(P2) is infeasible")
    first_gap = min((h.segment_distance(p0, p1) for h in hulls), default=math.inf)
    if first_gap < d_safe:
        return (PlanStatus.UNSAFE,
                f"the first segment, fixed by the current velocity, passes "
                f"{first_gap:.2f} m from a hull (< {d_safe} m)")
    return None
