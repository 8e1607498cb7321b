"""System 2 with a certificate: the fast plan, then branch and bound until its gap is proven.

Method "certified" (:class:`CertifiedSystem2`): the fast method's verified plan
(:mod:`dualpilot.system2.fast.planner`) is the incumbent; the branch and bound of
:mod:`dualpilot.system2.certify.bnb` then raises a lower bound on (P2) until the
certified gap (cost − bound) / bound is at most ``CertifyParams.tolerance`` or the budget
ends, and returns the best verified plan with its bound. It searches in two stages: the
root alone on the plain relaxation (``CertifyParams.plain_root_s``), which closes most
requests, then, if the gap is still open, the search on the relaxation with the reach sets
(:mod:`dualpilot.system2.certify.reach`), whose cheapest cell path, repaired, is offered as
an incumbent first. Every plan it returns passes
:func:`dualpilot.system2.problem.verify_p2_plan`; a relaxation that proves no trajectory
satisfies (P2) turns a failed fast plan into INFEASIBLE. Across the steps of a mission the
search is warm-started twice: the fast method starts from the previous plan (the first
incumbent), and the root convexifies at once, one step on, what the previous root did.

In 3-D (``spec.dim == 3``, prisms for hulls) a request whose prisms are all taller than the
ceiling less ε, from G_o's altitude at rest vertically, is the planar request on the
footprints, planned by this class in 2-D and lifted with its bound; any other 3-D request
gets the least over the branches "over or around" of the same search on the footprints a
branch keeps plus its altitude's bound (:mod:`dualpilot.system2.certify.planner3`).

After each plan, ``CertifiedSystem2.trace`` lists (seconds since the plan began, bound,
incumbent cost) at every node: how the run's certified gap closed over time.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from typing import cast

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.dynamics import rollout
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.certify.bnb import BranchAndBound, CertifyParams, Outcome
from dualpilot.system2.certify.model import Instance, controls, maps, positions
from dualpilot.system2.certify.planner3 import Certified3
from dualpilot.system2.certify.relaxation import NodeResult, Pair, Relaxation
from dualpilot.system2.certify.repair import repair
from dualpilot.system2.fast.geometry import Inflated
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.fast.planner3 import Fast3, planar_spec
from dualpilot.system2.fast.qp import P2Qp
from dualpilot.system2.problem import System2Params, p2_cost, verify_p2_plan


def relaxation_of(spec: MissionSpec, params: System2Params, state: Array,
                  hulls: Sequence[Polytope], objective: Objective,
                  prev_control: Array | None, reach: bool = True) -> Relaxation:
    """The relaxations of the (P2) instance of one plan request (``reach``: with the
    reach sets' bounds, :class:`Relaxation`)."""
    mp = maps(params.horizon, spec.dynamics, speed_sides=params.speed_polygon_sides)
    u_prev = np.zeros(2) if prev_control is None else np.asarray(prev_control, dtype=float)
    area = spec.area_size_m if params.keep_in_area else None
    instance = Instance(np.asarray(state, dtype=float), u_prev, spec.goal.center,
                        params.kappa(objective), tuple(hulls), spec.clearance_m, area)
    return Relaxation(mp, instance, reach)


class PlanCheck:
    """A relaxation solution as a plan: flown as it is when it keeps every disjunction, else
    repaired (:func:`dualpilot.system2.certify.repair.repair`); the controls are rolled out
    by Eq. (1) and checked by :func:`verify_p2_plan`. Returns (Eq. (S2) cost, controls)."""

    def __init__(self, spec: MissionSpec, params: System2Params, rel: Relaxation,
                 hulls: Sequence[Polytope], qp: P2Qp) -> None:
        self.spec, self.rel, self.hulls, self.qp = spec, rel, tuple(hulls), qp
        self.area = spec.area_size_m if params.keep_in_area else None
        self.polys = Inflated.make_many(self.hulls, spec.clearance_m)

    def __call__(self, res: NodeResult) -> tuple[float, Array] | None:
        mp, rel = self.rel.maps, self.rel
        assert res.z is not None
        direct = self._checked(controls(mp, res.z, rel.off))
        if direct is not None:
            return direct
        ref = positions(mp, res.z, rel.off.p1)
        best = None
        for rounding in (res.rounding(), None):
            try:
                fixed = repair(self.qp, rel.x0, rel.u_prev, self.spec.goal.center, rel.kappa,
                               self.polys, ref, area=self.area, rounding=rounding)
            except (ValueError, ArithmeticError, np.linalg.LinAlgError):
                fixed = None  # the fast QP refuses the problem (e.g. T = 2): no repair
            got = None if fixed is None else self._checked(fixed.controls)
            if got is not None and (best is None or got[0] < best[0]):
                best = got
        return best

    def from_corridor(self) -> tuple[float, Array] | None:
        """The reach sets' corridor (:meth:`ReachSets.corridor`) repaired into a plan: a
        first incumbent that goes round what the fast method's homotopy does not."""
        reach, rel = self.rel.reach, self.rel
        if reach is None:
            return None
        path = reach.corridor()
        if path is None:
            return None
        ref = np.vstack([path, path[-1:]])  # p_1..p_{T+1}
        ref[0] = rel.off.p1
        try:
            fixed = repair(self.qp, rel.x0, rel.u_prev, self.spec.goal.center, rel.kappa,
                           self.polys, ref, area=self.area)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            return None
        return None if fixed is None else self._checked(fixed.controls)

    def _checked(self, u: Array) -> tuple[float, Array] | None:
        dyn = self.spec.dynamics
        u = np.clip(u, -dyn.u_max_n, dyn.u_max_n)
        states = rollout(self.rel.x0, u, dyn)
        verdict = verify_p2_plan(states, u, self.hulls, dyn, self.spec.clearance_m,
                                 self.spec.d_safe_m, self.area, rolled_out=True)
        if not verdict.ok:
            return None
        return p2_cost(states, u, self.spec.goal.center, self.rel.kappa, self.rel.u_prev), u


class CertifiedSystem2:
    """"certified": the fast plan with a lower bound proven by branch and bound.

    Parameters
    ----------
    spec : MissionSpec
        Goal, area, ε, d_safe and Eq. (1).
    params : System2Params
        T and κ.
    certify : CertifyParams
        The tolerance on the certified gap and the budget of the search.
    fast : FastParams, optional
        The fast method that gives the first incumbent (its defaults).
    """

    system = 2
    method = "certified"

    def __init__(self, spec: MissionSpec, params: System2Params = System2Params(),
                 certify: CertifyParams = CertifyParams(),
                 fast: FastParams | None = None) -> None:
        self.spec, self.params, self.certify = spec, params, certify
        fast = fast or FastParams()
        #: the 3-D method (None in 2-D): the plane's certified planner under the reduction
        self.three: Certified3 | None = None
        self.fast_planner: FastSystem2
        if spec.dim == 3:
            flat = CertifiedSystem2(planar_spec(spec), params, certify, fast)
            fast3 = Fast3(spec, params, fast, flat.fast_planner)
            self.three = Certified3(spec, params, flat, fast3)
            self.fast_planner = flat.fast_planner
        else:
            self.fast_planner = FastSystem2(spec, params, fast)
        self.trace: list[tuple[float, float, float]] = []
        #: the previous plan's convexified (τ, hull centroid): the next root starts from them
        self._warm: list[tuple[int, Array]] = []

    def reset(self) -> None:
        """Forget the previous plan (the fast method's seed and the root's clusters)."""
        self.fast_planner.reset()
        self._warm = []
        if self.three is not None:
            self.three.reset()

    def plan(self, state: Array, hulls: Sequence[Polytope] | Sequence[Prism],
             objective: Objective = Objective.MISSION_TIME,
             prev_control: Array | None = None) -> Plan:
        """Plan from ``state`` avoiding ``hulls`` (prisms in 3-D:
        :class:`~dualpilot.system2.certify.planner3.Certified3`); ``prev_control`` is
        u_{t|t} (N)."""
        if self.three is not None:
            plan = self.three.plan(state, cast(Sequence[Prism], hulls), objective, prev_control)
            self.trace = list(self.three.trace)
            return plan
        t0 = time.perf_counter()
        fast = self.fast_planner.plan(state, hulls, objective, prev_control)
        if fast.status in (PlanStatus.INVALID_INPUT, PlanStatus.INFEASIBLE):
            return fast
        hull_t = tuple(cast(Sequence[Polytope], hulls))
        cost = fast.cost if fast.ok and fast.cost is not None else math.inf
        out = self._search(state, hull_t, objective, prev_control, cost,
                           self._warm_start(hull_t), t0, reach=False,
                           params=self._root_only(time.perf_counter() - t0))
        left = self.certify.time_budget_s - (time.perf_counter() - t0)
        if out.gap > self.certify.tolerance and out.bound < math.inf and left > 0.0:
            second = self._search(state, hull_t, objective, prev_control, out.cost,
                                  set(), t0, reach=True,
                                  params=dataclasses.replace(self.certify, time_budget_s=left))
            out = _chained(out, second)
        self._warm = [(tau, hull_t[i].vertices.mean(axis=0)) for tau, i in out.root_blocks]
        return self._answer(fast, out, np.asarray(state, dtype=float), objective, t0)

    def _root_only(self, spent_s: float) -> CertifyParams:
        """The first stage: the root alone, without the reach sets, for at most
        ``plain_root_s`` (most requests end there; the others go on with the reach sets)."""
        c = self.certify
        budget = min(c.plain_root_s, c.time_budget_s - spent_s)
        return dataclasses.replace(c, max_nodes=1, time_budget_s=max(budget, 1e-3))

    def _search(self, state: Array, hulls: tuple[Polytope, ...], objective: Objective,
                prev_control: Array | None, cost: float, blocks: set[Pair], t0: float, *,
                reach: bool, params: CertifyParams) -> Outcome:
        """One branch and bound from the incumbent ``cost``; with ``reach``, on the
        relaxation with the reach sets, its corridor offered as a plan first. Its trace is
        timed from ``t0``, the request."""
        rel = relaxation_of(self.spec, self.params, state, hulls, objective, prev_control,
                            reach=reach)
        check = PlanCheck(self.spec, self.params, rel, hulls, self.fast_planner.qp)
        search = BranchAndBound(rel, params, cost, check, blocks)
        if reach:
            search.consider(check.from_corridor())
        out = search.run()
        started = time.perf_counter() - t0 - out.time_s
        out.trace = [(started + t, b, c) for t, b, c in out.trace]
        return out

    def _warm_start(self, hulls: tuple[Polytope, ...], near_m: float = 100.0) -> set[Pair]:
        """The previous root's clusters one step on: (τ − 1, the hull whose centroid is
        nearest, within ``near_m``). Only a first guess of what to convexify: any is valid."""
        if not self._warm or not hulls:
            return set()
        centroids = np.array([h.vertices.mean(axis=0) for h in hulls])
        out: set[Pair] = set()
        for tau, c in self._warm:
            d = np.linalg.norm(centroids - c, axis=1)
            i = int(np.argmin(d))
            if tau > 2 and d[i] <= near_m:
                out.add((tau - 1, i))
        return out

    def _answer(self, fast: Plan, out: Outcome, x0: Array, objective: Objective,
                t0: float) -> Plan:
        """The better verified plan with the search's bound and statistics."""
        info = dict(fast.info)
        self.trace = list(out.trace)
        info.update(certify_nodes=out.nodes, certify_relaxations=out.relaxations,
                    certify_stop=out.stop, certify_root_bound=out.root_bound,
                    certify_time_s=out.time_s, fast_cost=fast.cost)
        elapsed = time.perf_counter() - t0
        if out.controls is not None:
            states = rollout(x0, out.controls, self.spec.dynamics)
            info["source"] = "branch and bound"
            return Plan(system=2, status=PlanStatus.OK, states=states, controls=out.controls,
                        compute_time_s=elapsed, objective=objective, cost=out.cost,
                        info=info, bound=min(out.bound, out.cost))
        if fast.ok and fast.cost is not None:
            info["source"] = "fast"
            return dataclasses.replace(fast, compute_time_s=elapsed, info=info,
                                       bound=min(out.bound, fast.cost))
        if out.bound == math.inf:
            failed = Plan.failed(2, PlanStatus.INFEASIBLE, elapsed,
                                 "(P2) is infeasible: the relaxation holds no trajectory")
            return dataclasses.replace(failed, objective=objective, info=info)
        return dataclasses.replace(fast, compute_time_s=elapsed, info=info)


def _chained(first: Outcome, second: Outcome) -> Outcome:
    """The two stages as one search: the better bound (both are valid), the second's
    incumbent (it starts from the first's), the work summed, the traces end to end."""
    trace = first.trace + [(t, max(b, first.bound), c) for t, b, c in second.trace]
    return Outcome(bound=max(first.bound, second.bound), cost=second.cost,
                   controls=second.controls if second.controls is not None else first.controls,
                   nodes=first.nodes + second.nodes,
                   relaxations=first.relaxations + second.relaxations,
                   root_bound=max(first.root_bound, second.root_bound),
                   time_s=first.time_s + second.time_s, stop=second.stop, trace=trace,
                   root_blocks=second.root_blocks)
