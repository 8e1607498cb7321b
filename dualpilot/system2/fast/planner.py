"""System 2 in real time: the "fast" method, a verified, near-optimal solver for Problem (P2).

One half-plane outside each ε-inflated hull per planned position makes (P2) a
convex QP (:class:`dualpilot.system2.fast.qp.P2Qp`, solved by
:mod:`dualpilot.system2.fast.ipm`), started from the relaxation, the homotopy
paths and the previous plan (:mod:`dualpilot.system2.fast.references`), and
improved by convex-feasible-set iteration (:mod:`dualpilot.system2.fast.cfs`);
the cheapest candidate that passes :func:`verify_p2_plan` is returned, else
UNSAFE. Keep-outs of some plan steps only (``zones``: the risk zones of
:class:`dualpilot.system2.fast.risk.RiskSystem2`) are avoided at their steps. In 3-D
(``spec.dim == 3``, prisms for hulls) each prism is passed around or over
(:mod:`dualpilot.system2.fast.planner3`).

The other methods built on it: "thorough" (:mod:`dualpilot.system2.fast.thorough`),
"fast+risk" (:mod:`dualpilot.system2.fast.risk`), "fast+exact"
(:mod:`dualpilot.system2.anytime`) and "certified"
(:mod:`dualpilot.system2.certify.planner`). ε, d_safe, G and the area come from
the :class:`dualpilot.spec.MissionSpec`; :mod:`dualpilot.planners` builds each by name.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import cast

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.dynamics import DynamicsParams, reach_radius, rollout
from dualpilot.model.geometry import Polytope, SegmentChecker, hull_boxes
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.cfs import Candidate, Cfs, CfsPlan, CountedSolve, KeepOuts, race
from dualpilot.system2.fast.geometry import FaceStack, Inflated
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.fast.planner3 import Fast3, Zone, planar_spec
from dualpilot.system2.fast.qp import P2Qp, QpResult
from dualpilot.system2.fast.references import References, braking
from dualpilot.system2.problem import (
    System2Params,
    check_request,
    disjunction_margin,
    p2_cost,
    verify_p2_plan,
)

#: A planar keep-out of some plan steps only: (polygon, bool mask over τ = 0..T).
PlanarZone = tuple[Polytope, AnyArray]


def _planar_zones(zones: Sequence[Zone]) -> list[PlanarZone]:
    """The zones of a 2-D plan (ValueError for a prism: a 2-D plan has no altitude)."""
    out: list[PlanarZone] = []
    for z, m in zones:
        if not isinstance(z, Polytope):
            raise ValueError("a 2-D plan keeps out planar risk zones, not prisms")
        out.append((z, m))
    return out


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
        if params.horizon < 2:
            raise ValueError("FastSystem2 needs a horizon of at least 2 steps")
        #: the 3-D method (None in 2-D); it plans a request that reduces to the plane with
        #: this planner's 2-D sibling
        self.three: Fast3 | None = None
        flat = spec
        if dynamics.dim == 3:
            flat = planar_spec(spec)
            self.three = Fast3(spec, params, fast, FastSystem2(flat, params, fast))
        self.spec = spec
        self.goal = spec.goal
        self.params = params
        self.dynamics = dynamics
        self.fast = fast
        self.clearance_m = spec.d_safe_m  # every returned plan keeps d_safe
        self.epsilon_m = spec.clearance_m  # ε of Eq. (P2_3)
        self.area = spec.area_size_m if params.keep_in_area else None
        self.qp = P2Qp(params.horizon, flat.dynamics, self.area,
                       speed_sides=params.speed_polygon_sides)
        self.references = References(fast, params, flat.dynamics, spec.goal, self.area)
        self._last: Plan | None = None

    # ---------------------------------------------------------------- public
    def reset(self) -> None:
        """Forget the previous plan (its shifted copy seeds the next call)."""
        self._last = None
        if self.three is not None:
            self.three.reset()

    def seed_previous(self, plan: Plan | None) -> None:
        """Start the next plan from ``plan`` (2-D) as if this planner had made it."""
        self._last = plan if plan is not None and plan.ok else None

    def plan(
        self,
        state: Array,
        hulls: Sequence[Polytope] | Sequence[Prism],
        objective: Objective = Objective.MISSION_TIME,
        prev_control: Array | None = None,
    ) -> Plan:
        """Plan from ``state`` avoiding ``hulls`` (prisms in 3-D); ``prev_control`` is
        u_{t|t} (N)."""
        return self.plan_with_zones(state, hulls, objective, prev_control, ())

    def plan_with_zones(self, state: Array, hulls: Sequence[Polytope] | Sequence[Prism],
                        objective: Objective,
                        prev_control: Array | None, zones: Sequence[Zone]) -> Plan:
        """:meth:`plan`, each of ``zones`` also kept out (by ε, as the hulls) at its steps."""
        if self.three is not None:
            return self.three.plan(state, cast(tuple[Prism, ...], tuple(hulls)), objective,
                                   prev_control, zones)
        t0 = time.perf_counter()
        checked = check_request(state, cast(Sequence[Polytope], hulls), objective, prev_control)
        if isinstance(checked, str):
            return _failed(PlanStatus.INVALID_INPUT, checked, t0, objective)
        x0, u_prev, hull_t = checked
        early = _start_checks(x0, hull_t, self.dynamics, self.clearance_m, self.epsilon_m,
                              self.area)
        if early is not None:
            return _failed(early[0], early[1], t0, objective)
        try:
            plan = self._plan(x0, hull_t, objective, u_prev, t0, _planar_zones(zones))
        except Exception as exc:  # noqa: BLE001 - a crash becomes an ERROR plan, never a raise
            plan = _failed(PlanStatus.ERROR, f"{type(exc).__name__}: {exc}", t0, objective)
        self._last = plan if plan.ok else None
        return plan

    # --------------------------------------------------------------- method
    def _plan(self, x0: Array, hulls: tuple[Polytope, ...], objective: Objective,
              u_prev: Array, t0: float, zones: Sequence[PlanarZone]) -> Plan:
        kappa = self.params.kappa(objective)
        keepouts, static, zone_rows, info = self._keepouts(x0, hulls, zones)
        solve = CountedSolve(self.qp, x0, u_prev, self.goal.center, kappa)
        # 1. the relaxation: no hulls
        free = solve(np.zeros(0, int), np.zeros((0, 2)), np.zeros(0), confirm=True)
        if not free.ok:
            return _failed(PlanStatus.ERROR, f"relaxed QP failed: {free.status}", t0, objective,
                           info)
        info["lower_bound"] = free.objective
        candidates: list[Candidate] = []
        if keepouts.feasible(free.positions):
            candidates.append(Candidate("relaxation", free.positions, free.controls,
                                        free.objective, 0))
        else:
            shared = CfsPlan(self.fast, keepouts, free.positions, solve)
            candidates.extend(self._homotopy_candidates(x0, free, static, shared, kappa, t0,
                                                        info))
        info["n_qp"] = solve.n
        candidates.sort(key=lambda c: c.cost)
        reasons: list[str] = []
        for cand in candidates:
            plan = self._finish(cand, x0, hulls, objective, kappa, u_prev, t0, info, reasons,
                                zone_rows)
            if plan is not None:
                return plan
        msg = "no verified candidate" + (f": {'; '.join(reasons[:3])}" if reasons else "")
        return _failed(PlanStatus.UNSAFE, msg, t0, objective, info)

    def _keepouts(self, x0: Array, hulls: tuple[Polytope, ...], zones: Sequence[PlanarZone]
                  ) -> tuple[KeepOuts, KeepOuts, list[PlanarZone], dict[str, object]]:
        """The ε-inflated hulls within reach of this plan, with the zones within reach.

        Returns (keep-outs, the hulls alone, the zones kept, the plan's info): the
        homotopies and the target avoid the hulls alone.
        """
        T = self.params.horizon
        reach = reach_radius(x0[2:], T, self.dynamics)
        polys = Inflated.make_many(hulls, self.epsilon_m)
        polys = [q for q, m in zip(polys, FaceStack.of(polys).margins(x0[:2])[0], strict=True)
                 if m <= reach]
        # per-plan geometry, shared by every homotopy run: stacked faces, padded hulls
        static = KeepOuts.of(polys, T, self.area)
        info: dict[str, object] = {"n_hulls": len(polys), "n_hulls_input": len(hulls)}
        if not zones:
            return static, static, [], info
        inflated = Inflated.make_many([z for z, _ in zones], self.epsilon_m)
        margins = FaceStack.of(inflated).margins(x0[:2])[0]
        kept = [(q, z) for q, z, m in zip(inflated, zones, margins, strict=True)
                if m <= reach]
        info["n_zones"] = len(kept)
        if not kept:
            return static, static, [], info
        both = polys + [q for q, _ in kept]
        mask = np.vstack([np.ones((len(polys), T + 1), dtype=bool)]
                         + [z[1][None, : T + 1] for _, z in kept])
        return KeepOuts.of(both, T, self.area, mask), static, [z for _, z in kept], info

    def _homotopy_candidates(self, x0: Array, free: QpResult, static: KeepOuts,
                             shared: CfsPlan, kappa: tuple[float, float], t0: float,
                             info: dict[str, object]) -> list[Candidate]:
        """The best feasible iterate of each homotopy's CFS run (:func:`race`), or of
        braking to a hover when no run found one; ``free`` is the relaxation, ``static``
        the hulls alone (what the homotopies avoid)."""
        refs = self.references(x0, free.positions, static, kappa, self._last)
        info["homotopies"] = [name for name, _, _ in refs]
        runs = [Cfs(shared, name, ref, retime) for name, ref, retime in refs]
        race(runs, shared, free.objective, t0, info)
        if not any(r.best is not None for r in runs):
            # fallback seed: braking to a hover is feasible whenever its path is clear
            brake = Cfs(shared, "brake", braking(x0, self.params.horizon, self.dynamics),
                        max_elastic=2)
            while not brake.done:
                brake.step()
            runs.append(brake)
        return [r.best for r in runs if r.best is not None]

    def _finish(self, cand: Candidate, x0: Array, hulls: tuple[Polytope, ...],
                objective: Objective, kappa: tuple[float, float], u_prev: Array, t0: float,
                info: dict[str, object], reasons: list[str],
                zones: Sequence[PlanarZone] = ()) -> Plan | None:
        """Roll out, verify and package one candidate; None (with a reason) if it fails."""
        d = self.dynamics
        controls = np.clip(cand.controls, -d.u_max_n, d.u_max_n)
        states = rollout(x0, controls, d)
        verdict = verify_p2_plan(states, controls, hulls, d, self.epsilon_m, self.clearance_m,
                                 self.area, rolled_out=True)
        if not verdict.ok:
            reasons.append(f"{cand.name}: {verdict.reason}")
            return None
        if zones:  # each zone at its own steps, ε as for the hulls
            faces = FaceStack.of([z for z, _ in zones]).margins(states[:, :2])  # (T+1, zones)
            steps = np.stack([m for _, m in zones], axis=1)
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


# ------------------------------------------------------------------ helpers
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
