"""The certified method in 3-D over fronts taller than the band (docs/three_d.md, "6. System 2").

**The reduction, and why its bound holds.** When no prism can be kept out of by its top or
bottom within the band (:meth:`Prism.escape_faces` lists its base's faces only: z_hi + ε
above the ceiling, z_lo − ε below the floor), Eq. (P2_3)-(P2_4) can hold only by a face of
a footprint, which constrains (x, y) alone. Eq. (1) and U and X (``speed_limit = "axis"``)
are per axis, the area bounds x and y, and Eq. (S2) is a sum over the axes. So the (x, y)
part of every feasible 3-D trajectory is a feasible trajectory of the planar (P2) on the
footprints, at no more than its cost: the planar optimum, and so the planar method's
certified bound, is a lower bound on the 3-D optimum. With the UAV at G_o's altitude,
v_z = 0 and u_{t|t,z} = 0 the planar plan lifted to that altitude (z constant, u_z ≡ 0) is
a 3-D plan of the same cost, and it keeps d_safe by the planar distances (its altitude lies
within every prism's altitudes). Then the 3-D answer is the planar
:class:`~dualpilot.system2.certify.planner.CertifiedSystem2`'s on the footprints, lifted:
its plan bit for bit, its cost, bound and certified gap.

**Otherwise** (a front that can be passed over, or the UAV off G_o's altitude or climbing)
the designed 2.5-D reach sets (docs/three_d.md) are not built. The request gets the better
verified plan of the fast method's 3-D plan (:class:`~dualpilot.system2.fast.planner3.Fast3`)
and the planar certified plans of the branches' searches, lifted to the UAV's altitude
where they keep every prism in 3-D; and the bound of "over or around"
(:mod:`~dualpilot.system2.certify.branches`): a prism is kept at every τ by a base face
(around), or at some τ by its top or bottom, whose altitude costs at least its bound of
:mod:`~dualpilot.system2.certify.over`; the bound is the least over the branches of the
planar certified bound on the footprints a branch keeps plus its altitude's bound. The
reduction's argument (the z terms of Eq. (S2) apart, Eq. (1), U and X per axis) makes
each branch's sum a lower bound on every 3-D trajectory in it. It is weak where the
optimum stays high for long (the climb is counted at one step and the steps X ties to
it) or the plans found go round a
front the optimum passes over (measured in docs/three_d.md). A mission whose fronts may be
lower than the ceiling less ε is refused up front (:func:`certifies_3d`, read by
:mod:`dualpilot.mission.dimension`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.altitude import lift_controls, lift_state
from dualpilot.model.dynamics import rollout
from dualpilot.model.fire_height import FireHeightParams
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan
from dualpilot.spec import MissionSpec
from dualpilot.system2.certify.bnb import CertifyParams
from dualpilot.system2.certify.branches import Branches
from dualpilot.system2.certify.over import altitude_costs
from dualpilot.system2.fast.planner3 import Fast3
from dualpilot.system2.problem import System2Params, check_request, p2_cost, verify_p2_plan


def certifies_3d(spec: MissionSpec, heights: FireHeightParams, scenario: str) -> str:
    """"" when every request of a 3-D mission on ``scenario`` under ``heights`` starts in
    the reduction (module docstring) as long as the UAV keeps G_o's altitude: every front's
    top + ε above the ceiling (``"above-ceiling"``: the ceiling + ε; ``"uniform"``: from
    ``fire_height_min_m``; a scenario's plume: not known before it burns) and the start at
    G_o's altitude; else why not, for the refusal."""
    band, eps = spec.band, spec.clearance_m
    reading = heights.resolved(scenario)
    tall = (reading == "above-ceiling"
            or (reading == "uniform" and heights.fire_height_min_m + eps > band.ceiling_m))
    level = band.ceiling_m - eps
    scope = (f"plans dim=3 only where every front's top is above the ceiling less ε "
             f"({level:g} m) and the start is at G_o's altitude (fire_height=above-ceiling, "
             f"or uniform with fire_height_min_m above {level:g} m)")
    if not tall:
        here = (f"fire_height=uniform from {heights.fire_height_min_m:g} m"
                if reading == "uniform" else f"fire_height={reading}, its fronts' tops "
                "following their fire")
        return f"{scope}; here {here}"
    if band.start_altitude_m != band.goal_z_m:
        return (f"{scope}; here the start at {band.start_altitude_m:g} m and G_o at "
                f"{band.goal_z_m:g} m")
    return ""


class PlanarCertified(Protocol):
    """The plane's certified planner, as :class:`Certified3` uses it."""

    trace: list[tuple[float, float, float]]
    certify: CertifyParams

    def plan(self, state: Array, hulls: Sequence[Polytope], objective: Objective,
             prev_control: Array | None) -> Plan: ...

    def reset(self) -> None: ...


class Certified3:
    """The 3-D half of :class:`~dualpilot.system2.certify.planner.CertifiedSystem2` (module
    docstring): ``flat`` is the plane's certified planner, ``fast3`` the fast method in 3-D
    for the requests outside the reduction (it seeds ``flat``'s fast planner, as the fast
    method's 3-D half seeds its plane's)."""

    def __init__(self, spec: MissionSpec, params: System2Params, flat: PlanarCertified,
                 fast3: Fast3) -> None:
        self.spec, self.params, self.flat, self.fast3 = spec, params, flat, fast3
        self.trace: list[tuple[float, float, float]] = []

    def reset(self) -> None:
        """Forget the previous plans (the plane's and the fast method's in 3-D)."""
        self.flat.reset()
        self.fast3.reset()
        self.trace = []

    def reduces(self, x0: Array, u_prev: Array, prisms: Sequence[Prism]) -> bool:
        """No prism kept out of by its top or bottom within the band, and the UAV at G_o's
        altitude with v_z = 0 and u_{t|t,z} = 0 (module docstring)."""
        band, eps = self.spec.band, self.spec.clearance_m
        at_rest = bool(x0[2] == self.spec.goal_center[2] and x0[5] == 0.0 and u_prev[2] == 0.0)
        return at_rest and all(len(p.escape_faces(band, eps)) == p.base.n_faces
                               for p in prisms)

    def plan(self, state: Array, hulls: Sequence[Prism], objective: Objective,
             prev_control: Array | None) -> Plan:
        """The plane's certified plan lifted under the reduction, else the better of the
        fast 3-D plan and the relaxation's lifted plan, with the relaxation's bound."""
        t0 = time.perf_counter()
        checked = check_request(state, hulls, objective, prev_control, dim=3)
        if isinstance(checked, str):
            plan = self.fast3.plan(state, tuple(hulls), objective, prev_control)
            self.trace = []
            return dataclasses.replace(plan, bound=None,
                                       info={**plan.info, "certify": "the request is invalid"})
        x0, u_prev, prisms = checked
        if not self.reduces(x0, u_prev, prisms):
            return self._dropped(x0, u_prev, prisms, objective, t0)
        flat = self.flat.plan(_planar(x0), [p.base for p in prisms], objective, u_prev[:2])
        self.trace = list(self.flat.trace)
        info = {**flat.info, "reduction": True}
        if not flat.ok:
            failed = Plan.failed(2, flat.status, time.perf_counter() - t0, flat.message, dim=3)
            plan = dataclasses.replace(failed, objective=flat.objective, info=info)
        else:
            plan = dataclasses.replace(flat, states=_lifted(flat, float(x0[2])),
                                       controls=lift_controls(flat.controls),
                                       compute_time_s=time.perf_counter() - t0, info=info)
        self.fast3.last = plan if plan.ok else None
        return plan

    def _dropped(self, x0: Array, u_prev: Array, prisms: tuple[Prism, ...],
                 objective: Objective, t0: float) -> Plan:
        """Off the reduction (module docstring, "Otherwise"): the fast 3-D plan; the plane's
        certified searches on the branches' footprints (:class:`Branches`), the least
        branch's set first, while the budget lasts and the gap is open; each search's plan
        lifted, and climbed over the prisms it crosses, are candidates where they keep
        every prism in 3-D (:meth:`_candidates`). The cheapest verified plan, with the
        least branch's bound."""
        fast = self.fast3.plan(x0, prisms, objective, u_prev)
        z0, per = altitude_costs(self.spec, x0, float(u_prev[2]), prisms,
                                 self.params.kappa(objective), self.params.horizon)
        branches = Branches(z0, per.min(axis=1))
        cost = fast.cost if fast.ok and fast.cost is not None else math.inf
        best = fast if math.isfinite(cost) else None
        certify = self.flat.certify
        deadline = t0 + certify.time_budget_s
        self.trace, stop = [], None
        while (hulls := branches.next_set(cost, certify.tolerance)) is not None:
            left = deadline - time.perf_counter()
            if branches.known and left <= 0.0:
                break
            first = not branches.known and hulls != branches.every
            flat = self._search(x0, u_prev, [prisms[i].base for i in sorted(hulls)],
                                objective, left / 2.0 if first else left)
            branches.add(hulls, 0.0 if flat.bound is None else flat.bound)
            stop = flat.info.get("certify_stop")
            for lifted in self._candidates(flat, x0, u_prev, prisms, objective):
                if lifted.cost is not None and lifted.cost < cost:
                    best, cost = lifted, lifted.cost
            if best is not None:
                self.trace.append((time.perf_counter() - t0, min(branches.bound(), cost), cost))
        if best is None or best.cost is None:
            self.trace = []
            return dataclasses.replace(fast, bound=None, info={
                **fast.info, "certify": "no bound: no verified plan"})
        info = {**best.info, "certify": "over or around: the least branch's bound",
                "certify_n_kept": len(branches.kept), "certify_searches": len(branches.known),
                "fast_cost": fast.cost, "certify_stop": stop}
        plan = dataclasses.replace(best, bound=min(branches.bound(), best.cost), info=info,
                                   compute_time_s=time.perf_counter() - t0)
        self.fast3.last = plan
        return plan

    def _search(self, x0: Array, u_prev: Array, hulls: list[Polytope], objective: Objective,
                budget_s: float) -> Plan:
        """The plane's certified plan on ``hulls`` within ``budget_s`` (s)."""
        certify = self.flat.certify
        self.flat.certify = dataclasses.replace(certify, time_budget_s=max(budget_s, 1e-3))
        try:
            return self.flat.plan(_planar(x0), hulls, objective, u_prev[:2])
        finally:
            self.flat.certify = certify

    def _candidates(self, flat: Plan, x0: Array, u_prev: Array, prisms: tuple[Prism, ...],
                    objective: Objective) -> list[Plan]:
        """A planar plan as 3-D plans that pass :func:`verify_p2_plan` with the band and
        every prism: at x0's altitude (v_z = 0 and no vertical force only), and over the
        prisms its ground track crosses (the altitude's QP of the split QP with rows
        z_τ ≥ top + ε where the track is within ε of a footprint, and the steps beside)."""
        if not flat.ok:
            return []
        out: list[Plan] = []
        xy = flat.states[:, :2]
        if x0[5] == 0.0 and u_prev[2] == 0.0:
            lifted = self._checked(_lifted(flat, float(x0[2])), lift_controls(flat.controls),
                                   flat, u_prev, prisms, objective, "relaxation, lifted")
            if lifted is not None:
                out.append(lifted)
        band, eps, T = self.spec.band, self.spec.clearance_m, self.params.horizon
        need = np.full(T + 1, -np.inf)
        for p in prisms:
            near = np.all(xy @ p.base.A.T <= p.base.b + eps + 1.0, axis=1)
            if not np.any(near[1:]):
                continue
            if p.z_hi + eps > band.ceiling_m:
                return out  # the track crosses a prism that cannot be passed over
            near = near | np.r_[near[1:], False] | np.r_[False, near[:-1]]
            need[near] = np.maximum(need[near], p.z_hi + eps + 0.5)
        tau = np.flatnonzero(np.isfinite(need[2:])) + 2
        if not len(tau) or (np.isfinite(need[1]) and x0[2] < need[1]):
            return out
        res = self.fast3.qp.vertical.solve(np.array([x0[2], x0[5]]), u_prev[2:],
                                           np.array([self.spec.goal_center[2]]),
                                           self.params.kappa(objective), tau,
                                           np.ones((len(tau), 1)), need[tau], None, None,
                                           confirm=True)
        if not res.ok:
            return out
        controls = np.column_stack([flat.controls, res.controls[:, 0]])
        dyn = self.spec.dynamics
        controls = np.clip(controls, -dyn.u_max_n, dyn.u_max_n)
        climbed = self._checked(rollout(x0, controls, dyn), controls, flat, u_prev, prisms,
                                objective, "relaxation, climbed over")
        return out if climbed is None else [*out, climbed]

    def _checked(self, states: Array, controls: Array, flat: Plan, u_prev: Array,
                 prisms: tuple[Prism, ...], objective: Objective, source: str) -> Plan | None:
        """The 3-D plan (``states``, ``controls``) from the plane's plan ``flat``, with its
        3-D Eq. (S2) cost, if it passes :func:`verify_p2_plan` with the band and every
        prism; else None."""
        spec = self.spec
        area = spec.area_size_m if self.params.keep_in_area else None
        verdict = verify_p2_plan(states, controls, prisms, spec.dynamics, spec.clearance_m,
                                 spec.d_safe_m, area, rolled_out=False, band=spec.band)
        if not verdict.ok:
            return None
        cost = p2_cost(states, controls, spec.goal_center, self.params.kappa(objective), u_prev)
        return dataclasses.replace(flat, states=states, controls=controls, cost=cost,
                                   info={**flat.info, "source": source})


def _planar(x0: Array) -> Array:
    """The planar state [p_x, p_y, v_x, v_y] of a 3-D one."""
    return np.array([x0[0], x0[1], x0[3], x0[4]])


def _lifted(flat: Plan, z: float) -> Array:
    """A planar plan's states at altitude ``z``, climbing at 0."""
    return np.array([lift_state(s, z) for s in flat.states])
