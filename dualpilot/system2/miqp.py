"""Problem (P2) as a mixed-integer QP compiled once in cvxpy, and one solve of it.

Eq. (S2) objective, Eq. (P2_1)-(P2_6) constraints; avoidance, Eq. (P2_3)-(P2_4), is
big-M over the faces of each H-polytope (unit outward normals α, margin ε in m) in
fixed slots (``max_hulls`` × ``max_faces``, :mod:`dualpilot.system2.slots`); in 3-D each
slot also holds a prism's top and bottom, the band bounds z (docs/three_d.md, 6). The problem
is built once with DPP parameters and re-solved each tick by updating ``.value``;
:meth:`P2Miqp.solve` runs SCIP (or Gurobi) on it and reads the native statistics.
"""

from __future__ import annotations

import contextlib
import math
import time
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import cvxpy as cp
import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import DynamicsParams, speed_polygon, transition_matrices
from dualpilot.system2.problem import Obstacle, System2Params

DEFAULT_SCIP_OPTIONS: dict[str, Any] = {
    "separating/maxroundsroot": 15,
    "separating/maxrounds": 2,
}
"""Fewer cut rounds: SCIP's root cut loop on the outer approximation of the
quadratic objective otherwise ate the whole budget (T = 80: 1 hull 23 s -> ~13 s,
3 hulls 45 s limit with 3 % gap -> optimal in 7-15 s). User options override."""


def slot_faces(params: System2Params, dim: int) -> int:
    """Faces a hull's slot holds: ``max_faces`` in 2-D, a prism's base's ``max_faces`` and
    its top and bottom in 3-D."""
    return params.max_faces + (2 if dim == 3 else 0)


def gurobi_available() -> bool:
    """True if gurobipy imports and cvxpy lists Gurobi (the licence is tried on first solve)."""
    try:
        import gurobipy  # noqa: F401
    except ImportError:
        return False
    return "GUROBI" in cp.installed_solvers()


class P2Miqp:
    """(P2) over ``params``' horizon and slots, compiled once (DPP), in 2-D or 3-D.

    In 3-D (``dynamics.dim == 3``) positions are [x, y, z], Eq. (1) has 3×3 blocks, each
    slot holds ``max_faces`` faces of a prism's base and its top and bottom (a cuboid: the
    six faces of Sec. II-B, Σ_{l=1..6} b ≤ 5 once the padded slots' binaries are forced to
    1), and the altitude band [floor, ceiling] bounds every planned z.

    Parameters
    ----------
    params : System2Params
        Horizon T, M, the slots, the time limit (s) and whether to keep the area.
    dynamics : DynamicsParams
        Eq. (1) and the bounds U, X (2-D or 3-D; 3-D under ``speed_limit = "axis"`` only).
    epsilon_m, area_size_m : float
        ε of Eq. (P2_3) and the area's side (m).
    objective_scale : float
        The solver minimises J / objective_scale (numerics only).
    band : AltitudeBand, optional
        The altitudes every planned position keeps (3-D; default: the spec's default band).
    """

    def __init__(self, params: System2Params, dynamics: DynamicsParams, epsilon_m: float,
                 area_size_m: float, objective_scale: float,
                 band: AltitudeBand | None = None) -> None:
        if dynamics.dim == 3 and dynamics.speed_limit == "norm":
            raise ValueError("the exact method plans in 3-D under speed_limit = 'axis' only: "
                             "the polyhedron inscribed in the speed ball is not written")
        self.params, self.dynamics = params, dynamics
        self.epsilon_m, self.area_size_m = epsilon_m, area_size_m
        self.objective_scale = objective_scale
        self.band = AltitudeBand() if band is None else band
        self.dim = n = dynamics.dim
        #: faces a slot holds: the base's ``max_faces`` (and in 3-D the top and the bottom)
        self.slot_faces = slot_faces(params, n)
        T, H, F = params.horizon, params.max_hulls, self.slot_faces

        self._x0 = cp.Parameter(2 * n, name="x0")
        # sqrt-weights keep the objective DPP: ‖w1 p − w1 G_o‖² = κ1/s ‖p − G_o‖²
        self._w1 = cp.Parameter(nonneg=True, name="w1")
        self._w1_goal = cp.Parameter(n, name="w1_goal")
        self._w2 = cp.Parameter(nonneg=True, name="w2")
        self._w2_uprev = cp.Parameter(n, name="w2_uprev")
        self._alpha = cp.Parameter((H * F, n), name="alpha")
        self._beta = cp.Parameter((H * F, 1), name="beta")

        lo, hi = self._state_bounds()
        self.X = cp.Variable((T, 2 * n), name="X", bounds=[lo, hi])  # x_{t+1|t}..x_{t+T|t}
        self.U = cp.Variable((T, n), name="U", bounds=[-dynamics.u_max_n, dynamics.u_max_n])
        self.B = cp.Variable((H * F, T), boolean=True, name="b")
        cons = self._constraints()
        pos = self.X[:, :n]
        dist = self._w1 * pos - np.ones((T, 1)) @ cp.reshape(self._w1_goal, (1, n), order="C")
        du0 = self._w2 * self.U[0] - self._w2_uprev
        du = self._w2 * (self.U[1:] - self.U[:-1])
        objective = cp.sum_squares(dist) + cp.sum_squares(du0) + cp.sum_squares(du)
        self.problem = cp.Problem(cp.Minimize(objective), cons)
        if not self.problem.is_dpp():
            raise RuntimeError("P2 is not DPP")  # pragma: no cover - construction bug
        # neutral values so the first compile succeeds
        self._alpha.value = np.zeros((H * F, n))
        self._beta.value = np.full((H * F, 1), -params.big_m)
        self._x0.value = np.zeros(2 * n)
        self._w1.value = 1.0
        self._w1_goal.value = np.zeros(n)
        self._w2.value = 1.0
        self._w2_uprev.value = np.zeros(n)

    def _state_bounds(self) -> tuple[Array, Array]:
        """The bounds of x_τ (T, 2·dim): the area (or none) in the plane, the band's
        altitudes in 3-D, X per axis (m, m/s)."""
        p, d, inf = self.params, self.dynamics, np.inf
        pos_lo, pos_hi = (0.0, self.area_size_m) if p.keep_in_area else (-inf, inf)
        lo = [pos_lo, pos_lo] + ([self.band.floor_m] if self.dim == 3 else [])
        hi = [pos_hi, pos_hi] + ([self.band.ceiling_m] if self.dim == 3 else [])
        lo += [-d.v_max_mps] * self.dim
        hi += [d.v_max_mps] * self.dim
        T = p.horizon
        return np.tile(lo, (T, 1)), np.tile(hi, (T, 1))

    def _constraints(self) -> list[cp.Constraint]:
        """Eq. (P2_1)-(P2_4) and X's speed polygon (``speed_limit = "norm"``, 2-D)."""
        p, d, n = self.params, self.dynamics, self.dim
        T, H, F = p.horizon, p.max_hulls, self.slot_faces
        phi, gamma = transition_matrices(d)
        xs, us, bs = self.X, self.U, self.B
        speed: list[cp.Constraint] = []
        if d.speed_limit == "norm":  # X: n_k·v_τ ≤ v_max cos(π/K), inside the disc
            normals, cos_k = speed_polygon(p.speed_polygon_sides)
            speed.append(xs[:, n:] @ normals.T <= d.v_max_mps * cos_k)
        return [
            xs[0] == phi @ self._x0 + gamma @ us[0],  # Eq. (P2_1)-(P2_2)
            xs[1:] == xs[:-1] @ phi.T + us[1:] @ gamma.T,
            # Eq. (P2_3): α·p_τ − β ≥ ε − M b
            self._alpha @ xs[:, :n].T - self._beta @ np.ones((1, T))
            >= self.epsilon_m - p.big_m * bs,
            # Eq. (P2_4): Σ_l b ≤ F − 1 per hull and τ
            np.kron(np.eye(H), np.ones((1, F))) @ bs <= F - 1,
            *speed,
        ]

    # -------------------------------------------------------------- values
    def set_values(self, x0: Array, u_prev: Array, goal: Array, kappa: tuple[float, float],
                   polys: Sequence[Obstacle]) -> None:
        """Set the DPP parameters of (P2) for this tick: x_t, u_{t|t}, G_o, κ and the hulls
        (polygons in 2-D, prisms in 3-D, each with at most :attr:`slot_faces` faces)."""
        k1, k2 = kappa
        s = self.objective_scale
        w1, w2 = math.sqrt(k1 / s), math.sqrt(k2 / s)
        self._x0.value = x0
        self._w1.value = w1
        self._w1_goal.value = w1 * goal
        self._w2.value = w2
        self._w2_uprev.value = w2 * u_prev
        self._set_hulls(polys)

    def _set_hulls(self, polys: Sequence[Obstacle]) -> None:
        H, F, big_m = self.params.max_hulls, self.slot_faces, self.params.big_m
        alpha = np.zeros((H * F, self.dim))
        beta = np.full((H * F, 1), -big_m)
        for k, poly in enumerate(polys):
            nf = poly.n_faces
            alpha[k * F:k * F + nf] = poly.A
            beta[k * F:k * F + nf, 0] = poly.b
            # padded face slot: 0 ≥ M/2 + ε − M b forces b = 1, so Σ_l b ≤ F − 1
            # leaves at least one real face with b = 0 (the disjunction is exact and,
            # unlike repeating a face, adds no symmetric choices for branching); a
            # cuboid's six real faces then keep the paper's Σ_{l=1..6} b ≤ 5
            beta[k * F + nf:(k + 1) * F, 0] = big_m / 2
        self._alpha.value = alpha
        self._beta.value = beta

    def values(self) -> dict[str, Any]:
        """Every parameter's value by name (what a solve in another process needs)."""
        return {prm.name(): prm.value for prm in self.problem.parameters()}

    def load(self, values: Mapping[str, Any]) -> None:
        """Set the parameters by name (the inverse of :meth:`values`)."""
        by_name = {prm.name(): prm for prm in self.problem.parameters()}
        for key, val in values.items():
            by_name[key].value = val

    # --------------------------------------------------------------- solve
    def solve(self, name: str, solver_options: Mapping[str, Any]) -> dict[str, object]:
        """One in-process solve with solver ``name`` ("SCIP" or "GUROBI") within the time limit.

        Returns the solver, its status and native status, timings, the MIP gap, whether
        the limit stopped it, and the solution (``U``, ``X``, ``value``: J / scale); an
        ``error`` instead when the solver failed.
        """
        tl = self.params.time_limit_s
        opts: dict[str, Any]
        if name == "SCIP":
            opts = {"scip_params": {**DEFAULT_SCIP_OPTIONS, "limits/time": tl,
                                    **solver_options}}
        else:
            opts = {"TimeLimit": tl, **solver_options}
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
        if self.U.value is not None and self.X.value is not None:
            out["U"] = np.array(self.U.value, dtype=float)
            out["X"] = np.array(self.X.value, dtype=float)
            val = self.problem.value
            out["value"] = float(val) if val is not None else math.nan  # type: ignore[arg-type]
        return out
