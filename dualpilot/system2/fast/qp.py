"""Problem (P2) with one fixed half-plane per (τ, hull): a convex QP in native Clarabel form.

Fixing, for every planned position p_τ and hull i, one half-plane
n·p_τ ≥ c that lies outside the ε-inflated hull turns the MIQP (P2) into a
convex QP whose every solution is feasible for (P2). This module builds that
QP once per horizon and dynamics with numpy/scipy.sparse and, per solve, only
stacks the half-plane rows and updates vectors.

Variables are the positions p_{t+2|t} … p_{t+T+1|t} (scaled by ``scale``):
p_{t+1|t} = p_t + ΔT v_t is fixed by the current state and p_{t+T+1|t} is
virtual (it defines v_{t+T|t}). Eq. (1) then gives, exactly and linearly,

* v_τ = (p_{τ+1} − p_τ) / ΔT,
* u_τ = m / ΔT · (v_τ − (1 − ζ) v_{τ−1}),

so the dynamics need no equality constraints and every constraint row
(U, X, area, half-planes) touches at most three consecutive positions. Under
``DynamicsParams.speed_limit = "norm"`` X is the regular K-gon inside the disc,
n_k·v_τ ≤ v_max·cos(π/K) (:func:`dualpilot.model.dynamics.speed_polygon`), rows
that touch the four coordinates of p_τ and p_{τ+1}.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from dualpilot.arrays import AnyArray
from dualpilot.model.dynamics import DynamicsParams, reach_boxes
from dualpilot.system2.fast.ipm import BandedQp, Rows
from dualpilot.system2.fast.mehrotra import csr_matvec
from dualpilot.system2.fast.qp_clarabel import ClarabelQp
from dualpilot.system2.fast.qp_shape import qp_shape


@dataclass(frozen=True)
class QpResult:
    """One QP solve: positions p_{t+1|t}..p_{t+T+1|t} (m), the controls, status and cost."""

    ok: bool
    status: str
    positions: AnyArray  # (T+1, 2): p_1 .. p_{T+1}
    controls: AnyArray  # (T, 2): u_1 .. u_T (N), unclipped
    objective: float  # the QP's Eq. (S2) value (true units)
    iterations: int
    solve_time_s: float


#: interior-point structures (one per κ and pattern of reachable area sides) kept per shape;
#: about 0.25 MB each (0.5 MB with a speed polygon)
STRUCTURES_KEPT = 128

@dataclass(frozen=True)
class QpParams:
    """Numerics of the QP and its solver.

    ``v_margin``, ``u_margin``, ``area_margin`` (m/s, N, m): the QP uses the
    bounds tightened by these, so that the solver's tolerance never shows as a
    violation of the true bounds. Positions are solved in units of ``scale``
    metres (numerics only). ``tol``: Clarabel's gap and feasibility tolerances.
    ``backend``: "ipm" (the banded interior point of
    :mod:`dualpilot.system2.fast.ipm`, Clarabel to decide when it fails) or
    "clarabel" (every QP).
    """

    v_margin: float = 1e-4
    u_margin: float = 1e-5
    area_margin: float = 1e-3
    scale: float = 100.0
    tol: float = 1e-8
    backend: str = "ipm"

    def __post_init__(self) -> None:
        if self.backend not in ("ipm", "clarabel"):
            raise ValueError(f"backend must be 'ipm' or 'clarabel', got {self.backend!r}")


def _control_steps(u_prev: AnyArray, controls: AnyArray) -> AnyArray:
    """Δu_τ = u_τ − u_{τ−1}, τ = 1..T, with u_0 = ``u_prev`` (N), shape of ``controls``."""
    du = np.empty(controls.shape)
    du[0] = controls[0] - u_prev
    du[1:] = controls[1:] - controls[:-1]
    return du


def _reach(x0: AnyArray, T: int, dyn: DynamicsParams, axes: int
           ) -> tuple[AnyArray, AnyArray]:
    """:func:`reach_boxes` of a plane's state (``axes`` 2) or of one axis's [p, v] (``axes``
    1: that axis, as each axis of a planar state; the axes are independent)."""
    if axes == 2:
        return reach_boxes(x0, T, dyn)
    lo, hi = reach_boxes(np.array([x0[0], x0[0], x0[1], x0[1]]), T, dyn)
    return lo[:, :1], hi[:, :1]


def _mv(mat: sp.csr_matrix, x: AnyArray) -> AnyArray:
    """``mat @ x`` for a CSR matrix, compiled (the sums of scipy's, term for term)."""
    return csr_matvec(mat.indptr, mat.indices, mat.data, np.ascontiguousarray(x, dtype=float))


class P2Qp:
    """The convex restriction of (P2) for a fixed set of half-planes.

    Parameters
    ----------
    horizon : int
        T of Eq. (P2).
    dynamics : DynamicsParams
        Eq. (1) and the bounds U, X (2-D).
    area_size_m : float or None
        Keep p_{t+τ|t} in [0, area]² (τ = 1..T); None for no area constraint.
    params : QpParams
        The margins, the scale and the solver.
    speed_sides : int
        K of the speed polygon under ``speed_limit = "norm"`` (unused per axis).
    axes : int
        2: the plane's QP (positions (x, y), the area [0, area]²); 1: the altitude's QP of a
        3-D plan (:mod:`dualpilot.system2.fast.split`), positions z in
        [``floor_m``, ``area_size_m``] (the band), whose "half-planes" are z_τ ≥ rhs
        (normals (m, 1) of ones); ``dynamics`` then gives ΔT, ζ, m and the per-axis limits.
    floor_m : float
        The lower bound of every coordinate (m; 0: the area's side).
    """

    def __init__(self, horizon: int, dynamics: DynamicsParams, area_size_m: float | None,
                 params: QpParams = QpParams(), *, speed_sides: int = 16, axes: int = 2,
                 floor_m: float = 0.0) -> None:
        if dynamics.dim != 2:
            raise ValueError(f"the P2 QP is planar, got dim={dynamics.dim}")
        if horizon < 2:
            raise ValueError(f"horizon must be >= 2, got {horizon}")
        self.params = params
        self.axes = int(axes)
        # the matrices and the memo tables of this shape, built once a process
        self.shape = qp_shape(int(horizon), dynamics, area_size_m, float(params.v_margin),
                              float(params.u_margin), float(params.area_margin),
                              float(params.scale), int(speed_sides), self.axes,
                              float(floor_m))
        self.clarabel = ClarabelQp(self.shape, params.tol)
        self.backend = params.backend
        # the last plan's offsets and interior-point context (every QP of one plan shares them)
        self._ctx: BandedQp | None = None
        self._ctx_key: tuple[bytes, bytes, float, float] | None = None
        self._off: tuple[AnyArray, AnyArray, AnyArray, AnyArray] | None = None
        self._off_key: tuple[bytes, bytes] | None = None
        self._q: AnyArray | None = None
        self._q_key: tuple[object, ...] | None = None

    # ----------------------------------------------------------------- maps
    def offsets(self, x0: AnyArray, u_prev: AnyArray
                ) -> tuple[AnyArray, AnyArray, AnyArray, AnyArray]:
        """Constant parts (from the state and u_{t|t}) of v, u and Δu, and p_{t+1|t}.

        The last result is cached (every QP of one plan shares x_t and u_{t|t});
        the arrays are read-only.
        """
        sh = self.shape
        x0 = np.asarray(x0, dtype=float)
        u_prev = np.asarray(u_prev, dtype=float)
        key = (x0.tobytes(), u_prev.tobytes())
        if self._off_key == key and self._off is not None:
            return self._off
        T, k = sh.T, sh.axes
        dt, a, mass = sh.dyn.dt_s, 1.0 - sh.dyn.zeta, sh.dyn.mass_kg
        p1 = x0[:k] + dt * x0[k:]
        e = np.zeros(k * (T + 1))
        e[:k] = p1
        vc = _mv(sh.dv, e)
        vprev = _mv(sh.shift, vc)
        vprev[:k] += x0[k:]
        uc = (mass / dt) * (vc - a * vprev)
        duc = _mv(sh.diff, uc)
        duc[:k] -= u_prev
        out = (vc, uc, duc, p1)
        for arr in out:
            arr.setflags(write=False)
        self._off, self._off_key = out, key
        return out

    def _context(self, x0: AnyArray, u_prev: AnyArray, q: AnyArray,
                 kappa: tuple[float, float]) -> BandedQp:
        """The fixed part of the interior-point QP for one (state, u_{t|t}, κ), cached."""
        sh = self.shape
        key = (x0.tobytes(), u_prev.tobytes(), float(kappa[0]), float(kappa[1]))
        if self._ctx_key == key and self._ctx is not None:
            return self._ctx
        T = sh.T
        vc, uc, _, _ = self.offsets(x0, u_prev)
        nu, nv = sh.fixed_norm[0], sh.fixed_norm[1]
        if sh.norm:  # one-sided: n_k·v_τ ≤ v_max cos(π/K)
            lo = [(-sh.umax - uc) / nu, np.full(len(nv), -np.inf)]
            hi = [(sh.umax - uc) / nu, (sh.vpoly - _mv(sh.N, vc)) / nv]
        else:
            lo = [(-sh.umax - uc) / nu, (-sh.vmax - vc) / nv]
            hi = [(sh.umax - uc) / nu, (sh.vmax - vc) / nv]
        if sh.area is not None:
            # a side of the area that p_τ cannot reach (per-axis reach at the limits) is
            # left out: its bound is infinite, so it adds no inequality
            r_lo, r_hi = _reach(x0, T, sh.dyn, sh.axes)
            na = sh.fixed_norm[2]
            floor = sh.floor + sh.area_margin  # the area's: 0 + margin, the margin exactly
            a_lo = np.where(r_lo[1:].ravel() < floor + 1.0, floor, -np.inf)
            a_hi = np.where(r_hi[1:].ravel() > sh.area - sh.area_margin - 1.0,
                            sh.area - sh.area_margin, np.inf)
            lo.append(a_lo / na)
            hi.append(a_hi / na)
        lo_a, hi_a = np.concatenate(lo), np.concatenate(hi)
        # the factor-independent structure depends only on κ and which bounds are finite
        skey = (float(kappa[0]), float(kappa[1]), np.isfinite(lo_a).tobytes(),
                np.isfinite(hi_a).tobytes())
        cache = sh.struct_cache
        with sh.struct_lock:  # planners of a fleet share it from their own threads
            base = cache.get(skey)
            if base is not None:
                cache.move_to_end(skey)
        if base is None:
            fixed = Rows(sh.fixed.cols, sh.fixed.vals, lo_a, hi_a)
            base = BandedQp(sh.hessian_band(kappa), q, fixed, sh.fixed_pairs)
            with sh.struct_lock:
                if len(cache) >= STRUCTURES_KEPT:
                    cache.popitem(last=False)  # the least recently used
                cache[skey] = base
            self._ctx = base
        else:
            self._ctx = base.rebound_unchecked(q, lo_a, hi_a)  # skey holds the pattern
        self._ctx_key = key
        return self._ctx

    def _solve_ipm(self, x0: AnyArray, u_prev: AnyArray, q: AnyArray, kappa: tuple[float, float],
                   tau: AnyArray, normals: AnyArray, rhs: AnyArray, z0: AnyArray | None = None,
                   detect_infeasible: bool = True) -> tuple[bool, str, AnyArray, int]:
        ctx = self._context(x0, u_prev, q, kappa)
        m = len(tau)
        extra = None
        if m:
            k = self.axes
            j = k * (np.asarray(tau, dtype=np.int64) - 2)
            nrm = np.asarray(normals, dtype=float).reshape(m, k)
            scale_n = np.linalg.norm(nrm, axis=1)
            cols = np.column_stack([j, j + k - 1, j])
            vals = np.column_stack([nrm[:, 0], nrm[:, k - 1] if k == 2 else np.zeros(m),
                                    np.zeros(m)]) / scale_n[:, None]
            rhs_n = np.asarray(rhs, dtype=float) / (self.shape.scale * scale_n)
            extra = Rows(cols, vals, rhs_n, np.full(m, np.inf))
        res = ctx.solve(extra, z0=z0, detect_infeasible=detect_infeasible)
        return res.ok, f"ipm {res.status}", res.z, res.iterations

    def positions(self, z: AnyArray, x0: AnyArray) -> AnyArray:
        """p_1..p_{T+1} (m) from the scaled variables."""
        k = self.axes
        p1 = x0[:k] + self.shape.dyn.dt_s * x0[k:]
        return np.vstack([p1, self.shape.scale * z.reshape(-1, k)])

    def controls(self, z: AnyArray, x0: AnyArray, u_prev: AnyArray) -> AnyArray:
        _, uc, _, _ = self.offsets(x0, u_prev)
        return np.asarray(_mv(self.shape.U, z) + uc).reshape(-1, self.axes)

    def cost(self, positions: AnyArray, controls: AnyArray, goal: AnyArray,
             kappa: tuple[float, float], u_prev: AnyArray) -> float:
        """Eq. (S2) for p_1..p_T (rows 0..T-1 of ``positions``) and u_1..u_T."""
        pos = positions[: self.shape.T]
        du = _control_steps(u_prev, controls)
        return float(kappa[0] * np.sum((pos - goal) ** 2) + kappa[1] * np.sum(du**2))

    def _linear_term(self, x0: AnyArray, u_prev: AnyArray, goal: AnyArray,
                     kappa: tuple[float, float]) -> AnyArray:
        """q of the QP (the cost's linear term); every QP of one plan shares it, so the
        last one is kept, like :meth:`offsets`."""
        sh = self.shape
        _, _, duc, _ = self.offsets(x0, u_prev)
        key = (self._off_key, np.asarray(goal, dtype=float).tobytes(), float(kappa[0]),
               float(kappa[1]))
        if self._q_key == key and self._q is not None:
            return self._q
        goal_vec = np.tile(goal, sh.T - 1)
        q = -2.0 * kappa[0] * _mv(sh.selT, goal_vec) + 2.0 * kappa[1] * _mv(sh.dUT, duc)
        q.setflags(write=False)
        self._q, self._q_key = q, key
        return q

    # ---------------------------------------------------------------- solve
    def solve(self, x0: AnyArray, u_prev: AnyArray, goal: AnyArray, kappa: tuple[float, float],
              tau: AnyArray, normals: AnyArray, rhs: AnyArray, area_rows: AnyArray | None = None,
              elastic: float | None = None, *, z0: AnyArray | None = None,
              confirm: bool = False) -> QpResult:
        """Solve the QP with half-planes normals[k]·p_{tau[k]} ≥ rhs[k] (τ in 2..T).

        ``area_rows`` is an (r, 3) int array of (τ, axis, side) with side 0 for
        p ≥ 0 and 1 for p ≤ area; None adds every area row. With ``elastic``
        the half-planes are soft: a violation of σ m costs ``elastic``·σ.
        ``z0`` (positions p_2..p_{T+1}, m) starts the interior-point solver; if it
        fails, Clarabel decides only when ``confirm`` (else the result is not ok);
        ``confirm`` is for QPs known to be feasible (no early infeasibility guess).
        """
        sh = self.shape
        if len(tau) and (int(np.min(tau)) < 2 or int(np.max(tau)) > sh.T):
            raise ValueError(f"half-planes apply to p_2..p_{sh.T}, got τ in "
                             f"{int(np.min(tau))}..{int(np.max(tau))}")
        n_sl = len(tau) if elastic is not None else 0
        vc, uc, _, _ = self.offsets(x0, u_prev)
        q = self._linear_term(x0, u_prev, goal, kappa)
        if self.backend == "ipm" and not n_sl:
            banded = self._solve_banded(x0, u_prev, goal, kappa, q, uc, tau, normals, rhs, z0,
                                        confirm)
            if banded is not None:
                return banded
            area_rows = None  # Clarabel decides, with every area row
        sol = self.clarabel.solve(kappa, q, vc, uc, (tau, normals, rhs), area_rows, elastic)
        status = str(sol.status)
        ok = status in ("Solved", "AlmostSolved")
        z = np.asarray(sol.x, dtype=float)[: sh.n]
        if not ok or not np.all(np.isfinite(z)):
            empty = np.empty((0, self.axes))
            return QpResult(False, status, empty, empty, float("inf"), int(sol.iterations),
                            float(sol.solve_time))
        pos, ctrl, cost = self._outputs(z, x0, u_prev, uc, goal, kappa)
        if n_sl:
            slack = float(np.max(np.asarray(sol.x)[sh.n:], initial=0.0))
            status += f" (elastic, slack {slack:.3g} m)"
        return QpResult(True, status, pos, ctrl, cost, int(sol.iterations), float(sol.solve_time))

    def _solve_banded(self, x0: AnyArray, u_prev: AnyArray, goal: AnyArray,
                      kappa: tuple[float, float], q: AnyArray, uc: AnyArray, tau: AnyArray,
                      normals: AnyArray, rhs: AnyArray, z0: AnyArray | None,
                      confirm: bool) -> QpResult | None:
        """:meth:`solve` by the banded interior-point solver (hard half-planes); None
        when it failed under ``confirm`` (then Clarabel decides)."""
        t_start = time.perf_counter()
        zs = None if z0 is None else np.asarray(z0, dtype=float).ravel() / self.shape.scale
        ok, status, z, iters = self._solve_ipm(x0, u_prev, q, kappa, tau, normals, rhs, zs,
                                               detect_infeasible=not confirm)
        if not ok and not confirm:
            empty = np.empty((0, self.axes))
            return QpResult(False, status, empty, empty, float("inf"), iters,
                            time.perf_counter() - t_start)
        if ok:
            pos, ctrl, cost = self._outputs(z, x0, u_prev, uc, goal, kappa)
            return QpResult(True, status, pos, ctrl, cost, iters, time.perf_counter() - t_start)
        return None

    def _outputs(self, z: AnyArray, x0: AnyArray, u_prev: AnyArray, uc: AnyArray,
                 goal: AnyArray, kappa: tuple[float, float]) -> tuple[AnyArray, AnyArray, float]:
        """Positions p_1..p_{T+1} (m), controls u_1..u_T (N) and Eq. (S2) of a solution z."""
        pos = self.positions(z, x0)
        ctrl = np.asarray(_mv(self.shape.U, z) + uc).reshape(-1, self.axes)
        return pos, ctrl, self.cost(pos, ctrl, goal, kappa, u_prev)
