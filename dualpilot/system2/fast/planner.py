"""System 2 in real time: a fast, verified, near-optimal solver for Problem (P2).

Method "fast" (the service default): one half-plane outside each ε-inflated
hull per planned position makes (P2) a convex QP
(:class:`dualpilot.system2.fast.qp.P2Qp`, solved by
:mod:`dualpilot.system2.fast.ipm`), started from the relaxation, the homotopy
paths (:func:`dualpilot.system2.fast.geometry.homotopy_paths`) and the previous
plan, and improved by convex-feasible-set iteration; the cheapest candidate
that passes :func:`verify_p2_plan` is returned, else UNSAFE.

"fast+exact" (:class:`AnytimeSystem2`) then runs SCIP seeded with the fast
plan (:mod:`dualpilot.system2.scip`) in a :class:`dualpilot.system2.worker.Worker`
and returns the better verified plan; "thorough" (:class:`ThoroughSystem2`)
iterates every homotopy to convergence. ε, d_safe, G and the area come from
the :class:`dualpilot.spec.MissionSpec`; :mod:`dualpilot.planners` builds each by name.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.dynamics import DynamicsParams, reach_radius, rollout
from dualpilot.model.geometry import Polytope, SegmentChecker, hull_boxes
from dualpilot.model.risk import ForecastView, RiskMap, RiskParams
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.geometry import (
    FaceStack,
    HullStack,
    Inflated,
    homotopy_paths,
    resample,
)
from dualpilot.system2.fast.qp import P2Qp, QpResult
from dualpilot.system2.problem import (
    System2Params,
    check_request,
    disjunction_margin,
    p2_cost,
    verify_p2_plan,
)
from dualpilot.system2.scip import SeededExactSystem2
from dualpilot.system2.worker import PlannerFactory, Worker


@dataclass(frozen=True)
class FastParams:
    """Knobs of the fast method.

    ``max_homotopies`` shortest paths (one per homotopy class, within
    ``length_slack`` of the shortest, classes told apart by the rays of the
    ``max_signature_hulls`` hulls nearest the start–target line);
    ``max_iterations`` QPs per homotopy; a run stops when a QP improves the
    cost by less than ``rel_tol``; half-planes are kept for (τ, i) pairs
    within ``near_m`` m of Q_i, each ``eps_margin_m`` m beyond Q_i (the
    solver's tolerance never shows as a violation); homotopies whose cost
    exceeds the best by more than ``screen_slack`` are not iterated;
    references move at ``speed_factor`` of the speed and force limits;
    once a feasible plan exists, no improving QP is started after ``max_qp``
    QPs in all. ``time_budget_s`` (s of wall clock, off by default) adds a
    second stop; it makes a plan depend on how loaded the machine is, so a
    seed no longer reproduces a mission exactly when it is set.
    """

    max_homotopies: int = 4
    max_iterations: int = 12
    rel_tol: float = 5e-4
    near_m: float = 60.0
    eps_margin_m: float = 0.01
    length_slack: float = 1.0
    max_signature_hulls: int = 5
    use_previous: bool = True
    screen_slack: float = 0.3
    speed_factor: float = 0.85
    max_qp: int = 14
    time_budget_s: float | None = None
    max_prefeasible: int = 5
    warm_start: bool = True

    def __post_init__(self) -> None:
        if self.max_homotopies < 1 or self.max_iterations < 1:
            raise ValueError("max_homotopies and max_iterations must be >= 1")
        if not (self.near_m > 0 and self.eps_margin_m >= 0 and self.length_slack >= 0):
            raise ValueError("near_m > 0, eps_margin_m >= 0 and length_slack >= 0 required")


THOROUGH = FastParams(max_homotopies=16, max_signature_hulls=8, length_slack=1.5,
                      max_iterations=40, rel_tol=1e-9, screen_slack=100.0,
                      max_prefeasible=8, max_qp=1000)
"""FastParams of the "thorough" method: no screening, no time budget."""


@dataclass
class _Candidate:
    name: str
    positions: Array  # rows p_{t+1|t} .. p_{t+T+1|t}: p_τ is row τ − 1
    controls: Array
    cost: float
    iterations: int


class _CountedSolve:
    """``P2Qp.solve`` of one plan (state, u_{t|t}, goal, κ), counting the QPs in ``n``."""

    def __init__(self, owner: FastSystem2, x0: Array, u_prev: Array, goal: Array,
                 kappa: tuple[float, float]) -> None:
        self.owner, self.x0, self.u_prev, self.goal, self.kappa = owner, x0, u_prev, goal, kappa
        self.n = 0

    def __call__(self, tau: Array, nrm: Array, rhs: Array, z0: Array | None = None,
                 elastic: float | None = None, confirm: bool = False) -> QpResult:
        self.n += 1
        return self.owner.qp.solve(self.x0, self.u_prev, self.goal, self.kappa, tau, nrm, rhs,
                                   None, elastic, z0=z0, confirm=confirm)


class _Cfs:
    """Convex-feasible-set iterations for one homotopy, advanced one QP at a time.

    The first half-planes come from the reference ``ref`` (the homotopy). If
    that QP is infeasible (the reference's timing asks too much of Eq. (1)),
    the reference is re-timed slower (``retime``) and tried again; with
    ``max_elastic`` > 0 a last attempt is elastic (exact L1 penalty on
    half-plane violations). Once an iterate is feasible, each half-plane is
    re-chosen as a support of Q_i that contains the current point and leans
    towards the relaxation's point, so the cost never rises. The run stops
    when the cost stalls or when the supports of the active half-planes no
    longer change (the last solution then also solves the next QP).
    """

    def __init__(self, owner: FastSystem2, name: str, ref: Array, polys: list[Inflated],
                 desired: Array, solve: Callable[..., QpResult], kappa: tuple[float, float],
                 stacks: tuple[FaceStack, HullStack],
                 retime: Callable[[float], Array] | None = None, max_elastic: int = 0) -> None:
        self.o, self.name, self.ref, self.polys = owner, name, ref, polys
        self.faces, self.stack = stacks
        self.desired, self.solve, self.kappa = desired, solve, kappa
        self.retime, self.max_elastic = retime, max_elastic
        self.slowdowns = [0.6, 0.35] if retime is not None else []
        f, T = owner.fast, owner.params.horizon
        self.T = T
        self.taus = np.arange(2, T + 1)
        self.active = np.zeros((len(polys), T + 1), dtype=bool)
        self._activate(ref)
        self.cur = ref.copy()
        self.best: _Candidate | None = None
        self.last_cost = math.inf  # the latest QP's cost, feasible for (P2) or not
        self.penalty = 3e4 * kappa[0] + 3e3 * kappa[1]
        self.elastic = False
        self.n_elastic = 0
        self.feasible_seen = False
        self.done = False
        self.iterations = 0
        self.last_rows: tuple[Array, Array, Array] | None = None
        self.last_hull_ids = np.zeros(0, dtype=np.int64)
        self.escapes = 0
        self.converged = False
        self._f = f

    @property
    def cost(self) -> float:
        return self.best.cost if self.best is not None else math.inf

    def _activate(self, pos: Array) -> None:
        T = self.T
        mask = None if self.o._mask is None else self.o._mask[:, 2:T + 1]  # the risk zones' steps
        self.active[:, 2:T + 1] |= self.faces.below(pos[1:T], self.o.fast.near_m, mask)

    def _rows(self) -> tuple[Array, Array, Array]:
        """Half-planes (τ, normal, rhs) of the active (τ, i) pairs, hull-major, vectorised."""
        f, T = self.o.fast, self.T
        hid, col = np.nonzero(self.active[:, 2:T + 1])  # row-major: hull-major, τ ascending
        if not len(hid):
            self.last_hull_ids = np.zeros(0, dtype=np.int64)
            return np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros(0)
        tt = self.taus[col]
        hs = self.stack
        if self.feasible_seen:
            nrm, off, _ = hs.support_toward(hid, self.cur[tt - 1], self.desired[tt - 1],
                                            slack=f.eps_margin_m)
        elif not self.elastic and self.n_elastic == 0:
            # until an iterate is feasible the homotopy reference fixes the sides
            nrm, off, _ = hs.support(hid, self.ref[tt - 1])
        else:
            # after an elastic solve: supports at its points, the reference's inside Q
            nrm, off, outside = hs.support(hid, self.cur[tt - 1])
            use = np.logical_not(outside) & (hs.margin(hid, self.ref[tt - 1]) > 0)
            if np.any(use):
                n2, o2, _ = hs.support(hid[use], self.ref[tt[use] - 1])
                nrm[use] = n2
                off[use] = o2
        self.last_hull_ids = hid
        return np.asarray(tt, dtype=np.int64), nrm, off + f.eps_margin_m

    def _corner_escape(self, rows: tuple[Array, Array, Array]
                       ) -> tuple[Array, Array, Array] | None:
        """Swap each active vertex support for the face of Q_i the point is most outside of.

        A fixed point of the iteration where a position is held by a line through
        a vertex of Q_i is not a local optimum of (P2): the disjunction allows the
        whole half-plane of either adjacent face, which contains the position.
        Returns the new rows, or None if no active row is a vertex support.
        """
        tau, nrm, rhs = rows
        hid = self.last_hull_ids
        pts = self.cur[tau - 1]
        slack = np.einsum("ij,ij->i", nrm, pts) - rhs
        ks = np.flatnonzero(slack < 1e-3)
        if not len(ks):
            return None
        hs, eps_m = self.stack, self.o.fast.eps_margin_m
        margins = hs._face_margins(hid[ks], pts[ks])
        face = np.argmax(margins, axis=1)
        best = margins[np.arange(len(ks)), face]
        a_face = hs.A[hid[ks], face]
        swap = ~np.all(np.abs(a_face - nrm[ks]) < 1e-9, axis=1) & ~(best < 0.25 * eps_m)
        if not np.any(swap):
            return None
        nrm, rhs = nrm.copy(), rhs.copy()
        k = ks[swap]
        nrm[k] = a_face[swap]
        # keep the current position feasible (it may sit a hair inside the margin)
        rhs[k] = hs.b[hid[k], face[swap]] + np.minimum(eps_m, best[swap])
        return tau, nrm, rhs

    def _unchanged(self, rows: tuple[Array, Array, Array]) -> bool:
        """True if the active half-planes at the current solution are those it solved."""
        if self.last_rows is None or len(rows[0]) != len(self.last_rows[0]):
            return False
        tau, nrm, rhs = rows
        tau0, nrm0, rhs0 = self.last_rows
        if not np.array_equal(tau, tau0):
            return False
        slack = np.einsum("ij,ij->i", nrm0, self.cur[tau0 - 1]) - rhs0
        act = slack < 1e-3
        return bool(np.all(np.abs(nrm[act] - nrm0[act]) < 1e-7)
                    and np.all(np.abs(rhs[act] - rhs0[act]) < 1e-5))

    def step(self) -> None:
        """One QP; sets ``done`` when converged, stuck or out of iterations."""
        if self.done:
            return
        o, f = self.o, self.o.fast
        rows = self._rows()
        if self.feasible_seen and (self.converged or self._unchanged(rows)):
            # converged: one more QP only if a vertex support holds a position
            escape = self._corner_escape(rows) if self.escapes < 2 else None
            if escape is None:
                self.done = True
                return
            self.escapes += 1
            self.converged = False
            rows = escape
        self.iterations += 1
        warm = self.cur[1:] if f.warm_start else None
        # after a feasible iterate the QP is feasible by construction (its solution
        # satisfies the new half-planes): a solver failure then is numerical
        res = self.solve(*rows, warm, self.penalty if self.elastic else None,
                         self.feasible_seen)
        if self.elastic:
            self.n_elastic += 1
        if not res.ok:
            if self.feasible_seen:
                self.done = True
            elif self.slowdowns and self.retime is not None:
                self.ref = self.retime(self.slowdowns.pop(0))
                self.cur = self.ref.copy()
                self._activate(self.ref)
            elif self.n_elastic < self.max_elastic:
                self.elastic = True
            else:
                self.done = True
            return
        pos = res.positions
        self.last_cost = res.objective
        feasible = o._violations(pos, self.faces).size == 0 and o._in_area(pos)
        self.last_rows = rows
        if feasible:
            self.elastic = False
            self.feasible_seen = True
            prev = self.cost
            if res.objective < prev:
                self.best = _Candidate(self.name, pos, res.controls, res.objective,
                                       self.iterations)
            if prev - res.objective <= f.rel_tol * abs(res.objective):
                self.converged = True
        elif self.elastic and self.n_elastic >= self.max_elastic:
            self.done = True
        self._activate(pos)
        if feasible or not self.feasible_seen:
            self.cur = pos if o.area is None else np.clip(pos, 0.0, o.area)
        # else: the solution broke a (τ, i) pair that was not in the QP; keep the last
        # feasible iterate, whose supports of the newly added pairs keep the QP feasible
        if self.iterations >= f.max_iterations:
            self.done = True


class FastSystem2:
    """Problem (P2) by homotopy-seeded convex restrictions (see the module docstring).

    Parameters
    ----------
    spec : MissionSpec
        Goal G (its centre is G_o of Eq. (S2)), area, ε (``clearance_m``),
        the d_safe every returned plan is verified against, and Eq. (1).
    params : System2Params
        T, κ; ``max_hulls`` does not limit this method.
    fast : FastParams
        Method knobs.
    """

    system = 2
    method = "fast"

    def __init__(
        self,
        spec: MissionSpec,
        params: System2Params = System2Params(),
        fast: FastParams = FastParams(),
    ) -> None:
        dynamics = spec.dynamics
        if dynamics.dim != 2:
            raise ValueError(f"FastSystem2 plans in 2-D (Sec. IV); got dim={dynamics.dim}")
        if params.horizon < 2:
            raise ValueError("FastSystem2 needs a horizon of at least 2 steps")
        self.spec = spec
        self.goal = spec.goal
        self.params = params
        self.dynamics = dynamics
        self.fast = fast
        self.clearance_m = spec.d_safe_m  # every returned plan keeps d_safe
        self.epsilon_m = spec.clearance_m  # ε of Eq. (P2_3)
        self.area = spec.area_size_m if params.keep_in_area else None
        self.qp = P2Qp(params.horizon, dynamics, self.area,
                       speed_sides=params.speed_polygon_sides)
        self._last: Plan | None = None
        self.stats: dict[str, Any] = {}
        #: keep-outs of some plan steps only, (polytope, mask over τ = 0..T): the risk zones
        #: of :class:`RiskSystem2` (none for the paper's method)
        self._zones: list[tuple[Polytope, AnyArray]] = []
        self._mask: AnyArray | None = None
        self._zone_rows: list[tuple[Polytope, AnyArray]] = []

    # ---------------------------------------------------------------- public
    def reset(self) -> None:
        """Forget the previous plan (its shifted copy seeds the next call)."""
        self._last = None

    def plan(
        self,
        state: Array,
        hulls: Sequence[Polytope],
        objective: Objective = Objective.MISSION_TIME,
        prev_control: Array | None = None,
    ) -> Plan:
        """Plan from ``state`` avoiding ``hulls``; ``prev_control`` is u_{t|t} (N)."""
        t0 = time.perf_counter()
        checked = check_request(state, hulls, objective, prev_control)
        if isinstance(checked, str):
            return _failed(PlanStatus.INVALID_INPUT, checked, t0, objective)
        x0, u_prev, hull_t = checked
        early = _start_checks(x0, hull_t, self.dynamics, self.clearance_m, self.epsilon_m,
                              self.area)
        if early is not None:
            return _failed(early[0], early[1], t0, objective)
        try:
            plan = self._plan(x0, hull_t, objective, u_prev, t0)
        except Exception as exc:  # noqa: BLE001 - a crash becomes an ERROR plan, never a raise
            plan = _failed(PlanStatus.ERROR, f"{type(exc).__name__}: {exc}", t0, objective)
        self._last = plan if plan.ok else None
        return plan

    # --------------------------------------------------------------- method
    def _plan(self, x0: Array, hulls: tuple[Polytope, ...], objective: Objective,
              u_prev: Array, t0: float) -> Plan:
        kappa = self.params.kappa(objective)
        polys, stacks, static, static_stacks, info = self._plan_geometry(x0, hulls)
        solve = _CountedSolve(self, x0, u_prev, self.goal.center, kappa)
        # 1. the relaxation: no hulls
        free = solve(np.zeros(0, int), np.zeros((0, 2)), np.zeros(0), confirm=True)
        if not free.ok:
            return _failed(PlanStatus.ERROR, f"relaxed QP failed: {free.status}", t0, objective,
                           info)
        info["lower_bound"] = free.objective
        candidates: list[_Candidate] = []
        if self._violations(free.positions, stacks[0]).size == 0 and self._in_area(free.positions):
            candidates.append(_Candidate("relaxation", free.positions, free.controls,
                                         free.objective, 0))
        else:
            candidates.extend(self._homotopy_candidates(x0, free, static, static_stacks, polys,
                                                        stacks, kappa, solve, t0, info))
        info["n_qp"] = solve.n
        candidates.sort(key=lambda c: c.cost)
        reasons: list[str] = []
        for cand in candidates:
            plan = self._finish(cand, x0, hulls, objective, kappa, u_prev, t0, info, reasons)
            if plan is not None:
                return plan
        msg = "no verified candidate" + (f": {'; '.join(reasons[:3])}" if reasons else "")
        return _failed(PlanStatus.UNSAFE, msg, t0, objective, info)

    def _plan_geometry(self, x0: Array, hulls: tuple[Polytope, ...]
                       ) -> tuple[list[Inflated], tuple[FaceStack, HullStack], list[Inflated],
                                  tuple[FaceStack, HullStack], dict[str, object]]:
        """The ε-inflated hulls within reach of this plan, with the risk zones (``_mask``).

        Returns (keep-outs, their stacks, the hulls alone, their stacks, the plan's
        info): the homotopies and the target avoid the hulls alone.
        """
        reach = reach_radius(x0[2:], self.params.horizon, self.dynamics)
        polys = Inflated.make_many(hulls, self.epsilon_m)
        polys = [q for q, m in zip(polys, FaceStack.of(polys).margins(x0[:2])[0], strict=True)
                 if m <= reach]
        # per-plan geometry, shared by every homotopy run: stacked faces, padded hulls
        stacks = (FaceStack.of(polys), HullStack.of(polys))
        info: dict[str, object] = {"n_hulls": len(polys), "n_hulls_input": len(hulls)}
        static, static_stacks = polys, stacks  # what the homotopies and the target avoid
        self._mask, self._zone_rows = None, []
        if self._zones:
            polys, stacks = self._with_zones(x0, polys, reach)
            info["n_zones"] = len(self._zone_rows)
        return polys, stacks, static, static_stacks, info

    def _homotopy_candidates(self, x0: Array, free: QpResult, static: list[Inflated],
                             static_stacks: tuple[FaceStack, HullStack], polys: list[Inflated],
                             stacks: tuple[FaceStack, HullStack], kappa: tuple[float, float],
                             solve: _CountedSolve, t0: float, info: dict[str, object]
                             ) -> list[_Candidate]:
        """The best feasible iterate of each homotopy's CFS run (:meth:`_race`), or of
        braking to a hover when no run found one; ``free`` is the relaxation."""
        refs = self._references(x0, free.positions, static, kappa, static_stacks)
        info["homotopies"] = [name for name, _, _ in refs]
        runs = [_Cfs(self, name, ref, polys, free.positions, solve, kappa, stacks, retime)
                for name, ref, retime in refs]
        self._race(runs, free.objective, solve, t0, info)
        if not any(r.best is not None for r in runs):
            # fallback seed: braking to a hover is feasible whenever its path is clear
            brake = _Cfs(self, "brake", _braking(x0, self.params.horizon, self.dynamics), polys,
                         free.positions, solve, kappa, stacks, max_elastic=2)
            while not brake.done:
                brake.step()
            runs.append(brake)
        return [r.best for r in runs if r.best is not None]

    def _race(self, runs: list[_Cfs], lower_bound: float, solve: _CountedSolve, t0: float,
              info: dict[str, object]) -> None:
        """Advance the runs, one QP at a time, until none can still win.

        Screening: one QP each; then always the run with the lowest cost (its
        feasible cost, or its last QP's while it is not feasible yet) while it
        can still win, the relaxation's cost ``lower_bound`` is not reached and
        the QP and time budgets allow.
        """
        f = self.fast
        for run in runs:
            run.step()

        def key(r: _Cfs) -> float:
            return r.cost if r.best is not None else r.last_cost

        while True:
            best_cost = min(r.cost for r in runs)  # inf while nothing is feasible
            cands = [r for r in runs if not r.done and (
                r.best is not None or r.iterations < f.max_prefeasible)]
            if not cands or best_cost <= lower_bound * (1.0 + 1e-6) + 1e-9:
                break  # done, or as good as the relaxation (optimal)
            if math.isfinite(best_cost) and (solve.n >= f.max_qp or (
                    f.time_budget_s is not None and time.perf_counter() - t0 > f.time_budget_s)):
                info["budget_hit"] = True
                break  # anytime: keep the best verified plan found so far
            run = min(cands, key=key)
            if math.isfinite(best_cost) and key(run) > (1.0 + f.screen_slack) * best_cost:
                break  # no homotopy left that can still win
            run.step()

    def _finish(self, cand: _Candidate, x0: Array, hulls: tuple[Polytope, ...],
                objective: Objective, kappa: tuple[float, float], u_prev: Array, t0: float,
                info: dict[str, object], reasons: list[str]) -> Plan | None:
        """Roll out, verify and package one candidate; None (with a reason) if it fails."""
        d = self.dynamics
        controls = np.clip(cand.controls, -d.u_max_n, d.u_max_n)
        states = rollout(x0, controls, d)
        verdict = verify_p2_plan(states, controls, hulls, d, self.epsilon_m, self.clearance_m,
                                 self.area, rolled_out=True)
        if not verdict.ok:
            reasons.append(f"{cand.name}: {verdict.reason}")
            return None
        if self._zone_rows:  # each zone at its own steps, ε as for the hulls
            zones = [z for z, _ in self._zone_rows]
            faces = FaceStack.of(zones).margins(states[:, :2])  # (T+1, zones)
            steps = np.stack([m for _, m in self._zone_rows], axis=1)
            worst = float(np.min(np.where(steps, faces, np.inf))) - self.epsilon_m
            if worst < -1e-6:
                reasons.append(f"{cand.name}: {-worst:.3g} m inside a risk zone's ε")
                return None
        margin = disjunction_margin(states[1:, :2], hulls, self.epsilon_m)
        cost = p2_cost(states, controls, self.goal.center, kappa, u_prev)
        out = dict(info)
        out.update(homotopy=cand.name, cfs_iterations=cand.iterations,
                   clearance_m=verdict.clearance_m, disjunction_margin_m=margin,
                   optimal=cand.name == "relaxation")
        lb = out.get("lower_bound")
        if isinstance(lb, float) and cost > 0:
            out["bound_gap"] = max(0.0, (cost - lb) / cost)
        return Plan(system=self.system, status=PlanStatus.OK, states=states, controls=controls,
                    compute_time_s=time.perf_counter() - t0, objective=objective, cost=cost,
                    info=out)

    def _with_zones(self, x0: Array, polys: list[Inflated], reach: float
                    ) -> tuple[list[Inflated], tuple[FaceStack, HullStack]]:
        """The hulls and the zones within reach, with the steps each constrains (``_mask``)."""
        T = self.params.horizon
        inflated = Inflated.make_many([z for z, _ in self._zones], self.epsilon_m)
        margins = FaceStack.of(inflated).margins(x0[:2])[0]
        kept = [(q, z) for q, z, m in zip(inflated, self._zones, margins, strict=True)
                if m <= reach]
        self._zone_rows = [z for _, z in kept]
        if not kept:
            return polys, (FaceStack.of(polys), HullStack.of(polys))
        both = polys + [q for q, _ in kept]
        self._mask = np.vstack([np.ones((len(polys), T + 1), dtype=bool)]
                               + [z[1][None, : T + 1] for _, z in kept])
        return both, (FaceStack.of(both), HullStack.of(both))

    # ------------------------------------------------------------ homotopies
    def _references(self, x0: Array, free_pos: Array, polys: list[Inflated],
                    kappa: tuple[float, float], stacks: tuple[FaceStack, HullStack]
                    ) -> list[tuple[str, Array, Callable[[float], Array] | None]]:
        """Reference positions p_1..p_{T+1} (one per homotopy) to pick the first half-planes.

        Each comes with a function that re-times it slower by a factor (None
        for the previous plan, whose timing was feasible).
        """
        f = self.fast
        T = self.params.horizon
        p1 = free_pos[0]
        speeds = np.linalg.norm(np.diff(free_pos, axis=0), axis=1) / self.dynamics.dt_s
        faces, stack = stacks
        target = self._target(polys, faces)
        refs: list[tuple[str, Array, Callable[[float], Array] | None]] = []
        v0 = x0[2:]

        def timed(path: Array) -> tuple[Array, Callable[[float], Array]]:
            return (resample(path, self._timing(path, speeds, v0)),
                    lambda fac: resample(path, self._timing(path, speeds, v0, fac)))

        last = self._last
        if f.use_previous and last is not None and last.ok and len(last.states) == T + 1:
            prev_pos = last.states[:, :2]
            if np.linalg.norm(prev_pos[1] - x0[:2]) < 30.0:
                shifted = np.vstack([prev_pos[2:], prev_pos[-1:], prev_pos[-1:]])
                shifted[0] = p1
                refs.append(("previous", shifted, None))
        paths = homotopy_paths(p1, target, polys, area=self.area, stack=stack,
                               max_paths=f.max_homotopies,
                               max_signature_hulls=f.max_signature_hulls,
                               length_slack=f.length_slack)
        for k, path in enumerate(paths):
            refs.append((f"path{k}", *timed(path)))
        path_len = (float(np.linalg.norm(np.diff(paths[0], axis=0), axis=1).sum())
                    if paths else 0.0)
        if (paths and kappa[0] < kappa[1]
                and self._timing(paths[0], speeds, v0)[-1] < path_len - 1.0):
            # timed by a slow energy-saving relaxation (κ1 < κ2), the shortest path is not
            # finished within the horizon, which can leave the plan short of the
            # target: also try the path at the speed the limits allow
            fast_speeds = np.full_like(speeds, np.inf)
            path = paths[0]
            refs.append(("path0-brisk", resample(path, self._timing(path, fast_speeds, v0)),
                         lambda fac: resample(path, self._timing(path, fast_speeds, v0, fac))))
        # the relaxation itself: each point leaves Q through its nearest face (dead ends too)
        _, slower = timed(free_pos)
        refs.append(("projected", free_pos, slower))
        return refs

    def _timing(self, path: Array, speeds: Array, v0: Array, factor: float = 1.0) -> Array:
        """Arc lengths s(τ), τ = 1..T+1, along ``path``.

        The speed is the relaxation's, capped by a point-mass profile that
        starts from v_t's component along the path and respects Eq. (1)'s drag
        and the per-axis bounds on u and v in each segment's direction
        (times ``speed_factor``), so that the first half-planes are reachable;
        under ``speed_limit = "norm"`` the speed cap is v_max·cos(π/K), the
        inscribed radius of the QP's speed polygon.
        """
        rho = self.fast.speed_factor * factor
        dyn = self.dynamics
        d = np.diff(path, axis=0)
        seg = np.linalg.norm(d, axis=1)
        good = seg > 1e-9
        if not np.any(good):
            return np.zeros(len(speeds) + 1)
        d, seg = d[good], seg[good]
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        axis_factor = seg / np.maximum(np.max(np.abs(d), axis=1), 1e-9)  # 1..√2
        if dyn.speed_limit == "norm":
            v_cap = np.full(len(seg), rho * dyn.v_max_mps
                            * math.cos(math.pi / self.params.speed_polygon_sides))
        else:
            v_cap = rho * dyn.v_max_mps * axis_factor
        a_cap = rho * dyn.u_max_n / dyn.mass_kg * axis_factor
        keep = 1.0 - dyn.zeta
        dt = dyn.dt_s
        sigma = max(0.0, float(v0 @ d[0]) / float(seg[0]))
        # the recursion in plain floats (same IEEE arithmetic as numpy scalars, less overhead)
        cum_l, vc_l, ac_l = cum.tolist(), v_cap.tolist(), a_cap.tolist()
        end, last = cum_l[-1], len(seg) - 1
        s_k = 0.0
        out = [0.0]
        for v in speeds.tolist():
            j = min(max(bisect.bisect_right(cum_l, s_k) - 1, 0), last)
            sigma = min(vc_l[j], keep * sigma + ac_l[j] * dt, factor * max(v, 0.0))
            s_k = min(end, s_k + dt * sigma)
            out.append(s_k)
        return np.array(out)

    def _target(self, polys: list[Inflated], faces: FaceStack | None = None) -> Array:
        """G_o, or the free point nearest to it when G_o is covered by inflated hulls.

        Candidates are G_o's projections onto every edge of every Q and the
        vertices of every Q, each pushed 2 m outwards; the nearest that lies
        outside every Q (and in the area) is the target.
        """
        g = self.goal.center
        faces = FaceStack.of(polys) if faces is None else faces
        margin_g = faces.margins(g)[0]
        if np.all(margin_g > 0):
            return g
        # every hull's candidates at once, hull by hull
        all_pts, owner = self._all_candidates(polys, g)
        bounds = np.searchsorted(owner, np.arange(len(polys) + 1))
        # A candidate of Q lies 2 m outside Q, so it is at least margin_Q(G_o) − 2 m from
        # G_o: visit the hulls nearest first and stop once none can beat the best so far.
        best, best_d = g, math.inf
        for i in np.argsort(margin_g):
            if margin_g[i] - 2.0 >= best_d:
                break
            pts = all_pts[int(bounds[i]):int(bounds[i + 1])]
            free = np.all(faces.margins(pts) > 0, axis=1)
            if self.area is not None:
                free &= np.all((pts >= 0.0) & (pts <= self.area), axis=1)
            if np.any(free):
                pts = pts[free]
                d = np.linalg.norm(pts - g, axis=1)
                j = int(np.argmin(d))
                if d[j] < best_d:
                    best, best_d = pts[j], float(d[j])
        return np.asarray(best)

    @staticmethod
    def _all_candidates(polys: list[Inflated], g: Array) -> tuple[Array, Array]:
        """G_o projected onto every edge of every Q and Q's vertices, each pushed 2 m outwards.

        Returns the points hull by hull (its edge projections, then its corners)
        and each point's hull.
        """
        sizes = np.array([len(q.b) for q in polys])
        a = np.vstack([q.W for q in polys])
        nrm = np.vstack([q.A for q in polys])
        e = np.vstack([q.E for q in polys])
        len2 = np.concatenate([q.len2 for q in polys])
        t = np.clip(((g - a) * e).sum(axis=1) / len2, 0.0, 1.0)
        proj = a + t[:, None] * e
        bis = np.vstack([q.nsum for q in polys])  # α_{l−1} + α_l: the corner's bisector
        corners = a + 2.0 * bis / np.maximum(np.linalg.norm(bis, axis=1), 1e-9)[:, None]
        hull = np.repeat(np.arange(len(polys)), sizes)
        k = np.arange(len(a))
        order = np.lexsort((np.concatenate([k, k]), np.repeat([0, 1], len(k)),
                           np.concatenate([hull, hull])))
        pts = np.vstack([proj + 2.0 * nrm, corners])[order]
        return pts, np.concatenate([hull, hull])[order]

    # ------------------------------------------------------------------ CFS
    def _in_area(self, pos: Array) -> bool:
        if self.area is None:
            return True
        p = pos[1:self.params.horizon]
        return bool(np.all(p >= -1e-6) and np.all(p <= self.area + 1e-6))

    def _violations(self, pos: Array, faces: FaceStack) -> NDArray[np.int64]:
        """(τ, i) pairs (τ = 2..T) where the disjunction fails for the hulls of ``faces``."""
        T = self.params.horizon
        mask = None if self._mask is None else self._mask[:, 2:T + 1]
        hull, tt = np.nonzero(faces.below(pos[1:T], 0.0, mask))  # hull-major
        return np.column_stack([tt + 2, hull]).astype(np.int64).reshape(-1, 2)


# ------------------------------------------------------------------ helpers
def _braking(x0: Array, horizon: int, dyn: DynamicsParams) -> Array:
    """Positions p_1..p_{T+1} (m) when braking to a hover as hard as U allows."""
    keep = 1.0 - dyn.zeta
    v = x0[2:].copy()
    p = x0[:2] + dyn.dt_s * v
    out = [p.copy()]
    for _ in range(horizon):
        u = np.clip(-keep * v * dyn.mass_kg / dyn.dt_s, -dyn.u_max_n, dyn.u_max_n)
        v = keep * v + dyn.dt_s / dyn.mass_kg * u
        p = p + dyn.dt_s * v
        out.append(p.copy())
    return np.array(out)


def _start_checks(x0: Array, hulls: tuple[Polytope, ...], dyn: DynamicsParams,
                  clearance_m: float, epsilon_m: float,
                  area: float | None) -> tuple[PlanStatus, str] | None:
    """The statuses ExactSystem2 gives before solving, for the same reasons.

    ``clearance_m`` is d_safe, ``epsilon_m`` ε, ``area`` the area's side (None: no bounds).
    """
    p0 = x0[:2]
    p1 = x0[:2] + dyn.dt_s * x0[2:]
    # only hulls whose bounding box comes within clearance_m (+1 m) of the first segment's
    # box can be nearer than clearance_m to p_t or to that segment
    near = hulls
    if hulls:
        lo, hi = hull_boxes(hulls)
        gap = np.maximum(0.0, np.maximum(lo - np.maximum(p0, p1), np.minimum(p0, p1) - hi))
        close = np.hypot(gap[:, 0], gap[:, 1]) < clearance_m + 1.0
        near = tuple(h for h, c in zip(hulls, close.tolist(), strict=True) if c)
    checker = SegmentChecker(near)
    if checker.point_distance(p0) < clearance_m:  # all hulls at once; the loop names one
        for i, hull in enumerate(hulls):
            dist = hull.distance(p0)
            if dist < clearance_m:
                return (PlanStatus.INVALID_INPUT,
                        f"start {p0} is {dist:.2f} m from hull {i} (< d_safe {clearance_m} m): "
                        "no safe plan can start here")
    if hulls:
        margins = FaceStack.of(hulls).margins(p1)[0]
        bad = np.flatnonzero(margins < epsilon_m)
        if len(bad):
            return (PlanStatus.INFEASIBLE,
                    f"x_(t+1|t) position {p1} is fixed by the current velocity and lies within "
                    f"ε={epsilon_m} m of hull {int(bad[0])}: (P2) is infeasible")
    if area is not None and not (np.all(p1 >= 0.0) and np.all(p1 <= area)):
        return (PlanStatus.INFEASIBLE,
                f"x_(t+1|t) position {p1} is fixed by the current velocity and lies outside "
                "the area: (P2) is infeasible")
    first_gap = float(checker.distances(p0[None], p1[None])[0])
    if first_gap < clearance_m:
        return (PlanStatus.UNSAFE,
                f"the first segment, fixed by the current velocity, passes {first_gap:.2f} m "
                f"from a hull (< {clearance_m} m)")
    return None


def _failed(status: PlanStatus, msg: str, t0: float, objective: Objective | None,
            info: dict[str, object] | None = None) -> Plan:
    plan = Plan.failed(2, status, time.perf_counter() - t0, msg)
    return dataclasses.replace(plan, objective=objective, info=dict(info or {}))


class ThoroughSystem2(FastSystem2):
    """"thorough": the fast method with every homotopy iterated to convergence (:data:`THOROUGH`).

    Slower; one more reference in the benchmark.
    """

    method = "thorough"

    def __init__(self, spec: MissionSpec, params: System2Params = System2Params()) -> None:
        super().__init__(spec, params, THOROUGH)


class RiskSystem2(FastSystem2):
    """"fast+risk": the fast method with a chance constraint on the fire forecast.

    Each planned position p_τ (τ = 2..T) also keeps ε from the risk zones of its
    step (:mod:`dualpilot.model.risk`: the cells whose forecast occupancy exceeds
    α while the UAV is there), as keep-outs of that step only in the same
    convex restrictions; homotopies and the target still come from the hulls.
    The plan is verified against the hulls exactly as "fast" (never less), and
    against each zone at its steps. When no plan meets the chance constraint,
    the "fast" plan is returned (``info["risk"]`` says so); without a forecast
    the method is "fast".
    """

    method = "fast+risk"
    uses_forecast = True

    def __init__(self, spec: MissionSpec, params: System2Params = System2Params(),
                 fast: FastParams = FastParams(), risk: RiskParams | None = None) -> None:
        super().__init__(spec, params, fast)
        self.risk = risk or RiskParams()

    def plan(self, state: Array, hulls: Sequence[Polytope],
             objective: Objective = Objective.MISSION_TIME, prev_control: Array | None = None,
             forecast: ForecastView | None = None) -> Plan:
        if forecast is None:
            return super().plan(state, hulls, objective, prev_control)
        t0 = time.perf_counter()
        zones = RiskMap(forecast, self.risk).step_masks(self.params.horizon, first=2)
        self._zones = zones
        try:
            plan = super().plan(state, hulls, objective, prev_control)
        finally:
            self._zones, self._mask, self._zone_rows = [], None, []
        note: dict[str, object] = {"risk_zones": len(zones)}
        if not plan.ok and zones:
            note["risk"] = f"unmet ({plan.status.value}: {plan.message[:120]})"
            plan = super().plan(state, hulls, objective, prev_control)
        else:
            note["risk"] = "met" if zones else "no zones"
        return dataclasses.replace(plan, compute_time_s=time.perf_counter() - t0,
                                   info={**plan.info, **note})


class AnytimeSystem2:
    """"fast+exact": the fast plan, then SCIP seeded with it in a killable worker.

    The worker solves (P2) exactly (:class:`dualpilot.system2.scip.SeededExactSystem2`:
    native SCIP, tight big-M, the fast plan as the starting incumbent) within
    ``exact_budget_s`` (its time limit is set a little below); the better
    verified plan is returned. A worker crash or overrun leaves the fast plan
    as the answer. Not the default: its latency is the exact budget whenever
    SCIP cannot prove optimality quickly.
    """

    system = 2
    method = "fast+exact"

    def __init__(self, spec: MissionSpec, params: System2Params = System2Params(), *,
                 exact_budget_s: float = 2.0, worker: Worker | None = None,
                 fast: FastParams = FastParams()) -> None:
        if exact_budget_s <= 0:
            raise ValueError("exact_budget_s must be positive")
        self.spec, self.params, self.dynamics = spec, params, spec.dynamics
        self.goal = spec.goal
        self.exact_budget_s = float(exact_budget_s)
        self.fast_planner = FastSystem2(spec, params, fast)
        if worker is None:
            limit = max(0.2, 0.8 * exact_budget_s)
            exact_params = dataclasses.replace(params, time_limit_s=float(limit))
            worker = Worker(PlannerFactory(SeededExactSystem2, spec, exact_params))
        self.worker = worker
        worker.start()  # imports and model set-up happen before the first request

    def plan(self, state: Array, hulls: Sequence[Polytope],
             objective: Objective = Objective.MISSION_TIME,
             prev_control: Array | None = None) -> Plan:
        t0 = time.perf_counter()
        fast = self.fast_planner.plan(state, hulls, objective, prev_control)
        if fast.status in (PlanStatus.INVALID_INPUT, PlanStatus.INFEASIBLE):
            return fast
        if fast.ok and fast.info.get("optimal"):
            # the relaxation's optimum is feasible: nothing to improve
            return dataclasses.replace(
                fast, compute_time_s=time.perf_counter() - t0,
                info={**fast.info, "source": "fast",
                      "exact_outcome": "skipped (fast plan proven optimal)"})
        request = (np.asarray(state, dtype=float), tuple(hulls), objective, prev_control,
                   fast.controls if fast.ok else None)
        left = max(0.05, self.exact_budget_s - (time.perf_counter() - t0))
        answer, why = self.worker.solve(request, left)
        exact = answer if isinstance(answer, Plan) else None
        if answer is not None and exact is None:
            why = "bad answer"
        best = fast
        if exact is not None and exact.ok and exact.cost is not None:
            spec = self.spec
            area = spec.area_size_m if self.params.keep_in_area else None
            verdict = verify_p2_plan(exact.states, exact.controls, tuple(hulls), self.dynamics,
                                     spec.clearance_m, spec.d_safe_m, area, tol=1e-3)
            if verdict.ok and (
                    not fast.ok or fast.cost is None or exact.cost < fast.cost):
                best = exact
        info = dict(best.info)
        info.update(source="exact" if best is exact else "fast", exact_outcome=why,
                    exact_status=None if exact is None else exact.status.value,
                    fast_cost=fast.cost)
        return Plan(system=2, status=best.status, states=best.states, controls=best.controls,
                    compute_time_s=time.perf_counter() - t0, objective=objective,
                    cost=best.cost, message=best.message, info=info)

    def close(self) -> None:
        self.worker.stop()
