"""The convex-feasible-set (CFS) loop of the fast method: one run per homotopy, and the race.

A run fixes one half-plane outside each ε-inflated keep-out Q_i per planned position
(:class:`dualpilot.system2.fast.qp.P2Qp`) and re-chooses them at each QP's solution
(:mod:`dualpilot.system2.fast.geometry`), so that, once an iterate is feasible for
(P2), the Eq. (S2) cost never rises. :func:`race` advances the runs of one plan one
QP at a time until none can still win. Lengths m, forces N.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dualpilot.arrays import AnyArray, Array
from dualpilot.system2.fast.geometry import FaceStack, HullStack, Inflated
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.fast.qp import P2Qp, QpResult
from dualpilot.system2.fast.split import SplitQp


@dataclass
class Candidate:
    """A plan's positions and controls (Eq. (S2) ``cost``) found by run ``name``."""

    name: str
    positions: Array  # rows p_{t+1|t} .. p_{t+T+1|t}: p_τ is row τ − 1
    controls: Array
    cost: float
    iterations: int


class CountedSolve:
    """``P2Qp.solve`` (``SplitQp.solve`` in 3-D) of one plan (state, u_{t|t}, goal, κ),
    counting the QPs in ``n``."""

    def __init__(self, qp: P2Qp | SplitQp, x0: Array, u_prev: Array, goal: Array,
                 kappa: tuple[float, float]) -> None:
        self.qp, self.x0, self.u_prev, self.goal, self.kappa = qp, x0, u_prev, goal, kappa
        self.n = 0

    def __call__(self, tau: Array, nrm: Array, rhs: Array, z0: Array | None = None,
                 elastic: float | None = None, confirm: bool = False) -> QpResult:
        self.n += 1
        return self.qp.solve(self.x0, self.u_prev, self.goal, self.kappa, tau, nrm, rhs,
                             None, elastic, z0=z0, confirm=confirm)


@dataclass(frozen=True)
class KeepOuts:
    """The ε-inflated keep-outs of one plan and the plan steps each constrains.

    ``mask`` (keep-outs × τ = 0..T, bool) marks a keep-out's steps (a risk zone holds
    at some steps only); None: every keep-out at every step (the hulls). ``area`` is
    the area's side (m; None: no bounds).
    """

    polys: list[Inflated]
    faces: FaceStack
    stack: HullStack
    mask: AnyArray | None
    horizon: int
    area: float | None

    @staticmethod
    def of(polys: list[Inflated], horizon: int, area: float | None,
           mask: AnyArray | None = None) -> KeepOuts:
        """The keep-outs ``polys`` with their stacked faces and padded hulls."""
        return KeepOuts(polys, FaceStack.of(polys), HullStack.of(polys), mask, horizon, area)

    def steps(self) -> AnyArray | None:
        """``mask`` over the constrained positions τ = 2..T (None: every step)."""
        return None if self.mask is None else self.mask[:, 2:self.horizon + 1]

    def violations(self, pos: Array) -> NDArray[np.int64]:
        """(τ, i) pairs (τ = 2..T) where the disjunction fails for keep-out i at its steps."""
        T = self.horizon
        hull, tt = np.nonzero(self.faces.below(pos[1:T], 0.0, self.steps()))  # hull-major
        return np.column_stack([tt + 2, hull]).astype(np.int64).reshape(-1, 2)

    def below(self, pos: Array, threshold: float) -> AnyArray:
        """(keep-outs, points p_2..p_T): keep-out i's margin at the point is below
        ``threshold`` (m), at its steps."""
        return self.faces.below(pos, threshold, self.steps())

    def clip(self, pos: Array) -> Array:
        """Positions clipped to the area (unchanged without one)."""
        return pos if self.area is None else np.clip(pos, 0.0, self.area)

    def in_area(self, pos: Array) -> bool:
        """Whether p_2..p_T lie in the area (1 µm of slack)."""
        if self.area is None:
            return True
        p = pos[1:self.horizon]
        return bool(np.all(p >= -1e-6) and np.all(p <= self.area + 1e-6))

    def feasible(self, pos: Array) -> bool:
        """Positions p_1..p_{T+1} that keep every disjunction and the area."""
        return self.violations(pos).size == 0 and self.in_area(pos)


@dataclass(frozen=True)
class CfsPlan:
    """What every run of one plan shares: the method's knobs, the keep-outs, the
    relaxation's positions (the supports lean towards them) and the counted QP."""

    fast: FastParams
    keepouts: KeepOuts
    desired: Array
    solve: CountedSolve


class Cfs:
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

    def __init__(self, plan: CfsPlan, name: str, ref: Array,
                 retime: Callable[[float], Array] | None = None, max_elastic: int = 0) -> None:
        self.plan, self.name, self.ref = plan, name, ref
        self.keepouts = plan.keepouts
        self.retime, self.max_elastic = retime, max_elastic
        self.slowdowns = [0.6, 0.35] if retime is not None else []
        T = plan.keepouts.horizon
        self.T = T
        self.taus = np.arange(2, T + 1)
        self.active = np.zeros((len(plan.keepouts.polys), T + 1), dtype=bool)
        self._activate(ref)
        self.cur = ref.copy()
        self.best: Candidate | None = None
        self.last_cost = math.inf  # the latest QP's cost, feasible for (P2) or not
        kappa = plan.solve.kappa
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

    @property
    def cost(self) -> float:
        return self.best.cost if self.best is not None else math.inf

    def _activate(self, pos: Array) -> None:
        T = self.T
        self.active[:, 2:T + 1] |= self.keepouts.below(pos[1:T], self.plan.fast.near_m)

    def _rows(self) -> tuple[Array, Array, Array]:
        """Half-planes (τ, normal, rhs) of the active (τ, i) pairs, hull-major, vectorised."""
        f, T = self.plan.fast, self.T
        hid, col = np.nonzero(self.active[:, 2:T + 1])  # row-major: hull-major, τ ascending
        if not len(hid):
            self.last_hull_ids = np.zeros(0, dtype=np.int64)
            return np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros(0)
        tt = self.taus[col]
        hs = self.keepouts.stack
        if self.feasible_seen:
            nrm, off, _ = hs.support_toward(hid, self.cur[tt - 1], self.plan.desired[tt - 1],
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
        ks = np.flatnonzero((slack < 1e-3) & self._around(nrm))
        if not len(ks):
            return None
        hs, eps_m = self.keepouts.stack, self.plan.fast.eps_margin_m
        margins = hs._face_margins(hid[ks], pts[ks])
        face = np.argmax(margins, axis=1)
        best = margins[np.arange(len(ks)), face]
        a_face = hs.A[hid[ks], face]
        swap = ~np.all(np.abs(a_face - nrm[ks, :2]) < 1e-9, axis=1) & ~(best < 0.25 * eps_m)
        if not np.any(swap):
            return None
        nrm, rhs = nrm.copy(), rhs.copy()
        k = ks[swap]
        nrm[k, :2] = a_face[swap]
        # keep the current position feasible (it may sit a hair inside the margin)
        rhs[k] = hs.b[hid[k], face[swap]] + np.minimum(eps_m, best[swap])
        return tau, nrm, rhs

    def _around(self, nrm: Array) -> AnyArray:
        """Which rows pass a keep-out around (a half-plane of its footprint): all in 2-D."""
        return np.ones(len(nrm), dtype=bool)

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
        f = self.plan.fast
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
        res = self.plan.solve(*rows, warm, self.penalty if self.elastic else None,
                              self.feasible_seen)
        if self.elastic:
            self.n_elastic += 1
        if not res.ok:
            self._failed_qp()
            return
        self._take(res, rows)
        if self.iterations >= f.max_iterations:
            self.done = True

    def _failed_qp(self) -> None:
        """After a QP without a solution: re-time the reference slower, go elastic or stop."""
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

    def _take(self, res: QpResult, rows: tuple[Array, Array, Array]) -> None:
        """Keep a QP's solution: the best feasible iterate, the next point and pairs."""
        pos = res.positions
        self.last_cost = res.objective
        feasible = self.keepouts.feasible(pos)
        self.last_rows = rows
        if feasible:
            self.elastic = False
            self.feasible_seen = True
            prev = self.cost
            if res.objective < prev:
                self.best = Candidate(self.name, pos, res.controls, res.objective,
                                      self.iterations)
            if prev - res.objective <= self.plan.fast.rel_tol * abs(res.objective):
                self.converged = True
        elif self.elastic and self.n_elastic >= self.max_elastic:
            self.done = True
        self._activate(pos)
        if feasible or not self.feasible_seen:
            self.cur = self.keepouts.clip(pos)
        # else: the solution broke a (τ, i) pair that was not in the QP; keep the last
        # feasible iterate, whose supports of the newly added pairs keep the QP feasible


def race(runs: Sequence[Cfs], plan: CfsPlan, lower_bound: float, t0: float,
         info: dict[str, object]) -> None:
    """Advance the runs, one QP at a time, until none can still win.

    Screening: one QP each; then always the run with the lowest cost (its
    feasible cost, or its last QP's while it is not feasible yet) while it
    can still win, the relaxation's cost ``lower_bound`` is not reached and
    the QP and time budgets allow (``t0``: when the plan began, perf_counter s).
    """
    f = plan.fast
    for run in runs:
        run.step()

    def key(r: Cfs) -> float:
        return r.cost if r.best is not None else r.last_cost

    while True:
        best_cost = min(r.cost for r in runs)  # inf while nothing is feasible
        cands = [r for r in runs if not r.done and (
            r.best is not None or r.iterations < f.max_prefeasible)]
        if not cands or best_cost <= lower_bound * (1.0 + 1e-6) + 1e-9:
            break  # done, or as good as the relaxation (optimal)
        if math.isfinite(best_cost) and (plan.solve.n >= f.max_qp or (
                f.time_budget_s is not None and time.perf_counter() - t0 > f.time_budget_s)):
            info["budget_hit"] = True
            break  # anytime: keep the best verified plan found so far
        run = min(cands, key=key)
        if math.isfinite(best_cost) and key(run) > (1.0 + f.screen_slack) * best_cost:
            break  # no homotopy left that can still win
        run.step()
