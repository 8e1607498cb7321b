"""The fast method in 3-D (docs/three_d.md, "6. System 2", Fast): prisms passed around or over.

The reduction first: with every prism one that cannot be passed over within the band (a
cuboid taller than the ceiling, as in the top-down evaluation), the UAV at G_o's altitude,
v_z = 0 and u_{t|t,z} = 0, the 3-D request is the 2-D request plus an altitude that stays
put; the plane's :class:`dualpilot.system2.fast.planner.FastSystem2` plans it on the
footprints and its plan is lifted (the 2-D plan bit for bit). Otherwise the relaxation,
the references (:mod:`dualpilot.system2.fast.references3`) and their CFS runs
(:mod:`dualpilot.system2.fast.cfs3`) over the split QP (:mod:`dualpilot.system2.fast.split`),
and the cheapest candidate that passes :func:`verify_p2_plan` with the band and the prisms.
Risk zones (:class:`dualpilot.system2.fast.risk.RiskSystem2`'s) are kept out at their
steps: a footprint (the default ``risk_zone_height = "band"``) or a zone prism that cannot
be passed over within the band as a prism taller than the band (around only, its
footprint checked in the plane: the stricter test); a lower zone prism (``"fire"``) is
passed around or over like a front's, and checked by its six faces. The run-time
monitor's ``check_risk`` reads the same zones.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.altitude import lift_controls, lift_state
from dualpilot.model.dynamics import reach_radius, rollout
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.cfs import Candidate, CfsPlan, CountedSolve, race
from dualpilot.system2.fast.cfs3 import Cfs3, KeepOuts3
from dualpilot.system2.fast.geometry import FaceStack
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.fast.qp import QpParams
from dualpilot.system2.fast.references3 import References3
from dualpilot.system2.fast.split import SplitQp, planar_dynamics
from dualpilot.system2.problem import (
    System2Params,
    check_request,
    disjunction_margin,
    p2_cost,
    verify_p2_plan,
)

Zone = tuple[Polytope | Prism, AnyArray]
"""A keep-out of some plan steps only: (footprint or prism, bool mask over τ = 0..T)."""


class PlanarFast(Protocol):
    """The plane's fast planner, as :class:`Fast3` uses it."""

    def plan(self, state: Array, hulls: Sequence[Polytope], objective: Objective,
             prev_control: Array | None) -> Plan: ...

    def plan_with_zones(self, state: Array, hulls: Sequence[Polytope], objective: Objective,
                        prev_control: Array | None, zones: Sequence[Zone]) -> Plan: ...

    def seed_previous(self, plan: Plan | None) -> None: ...


class Fast3:
    """The 3-D half of :class:`FastSystem2` (module docstring); ``planar`` is the plane's
    planner (the reduction's), ``spec`` the 3-D mission's."""

    def __init__(self, spec: MissionSpec, params: System2Params, fast: FastParams,
                 planar: PlanarFast) -> None:
        self.spec, self.params, self.fast, self.planar = spec, params, fast, planar
        self.dynamics, self.band = spec.dynamics, spec.band
        self.goal = spec.goal_center  # G_o ∈ ℝ³
        self.epsilon_m, self.clearance_m = spec.clearance_m, spec.d_safe_m
        self.area = spec.area_size_m if params.keep_in_area else None
        self.qp = SplitQp(params.horizon, spec.dynamics, self.area, spec.band)
        qpp = QpParams()
        #: an over-row's level needs this much room below the ceiling (the row's and the
        #: band's margins)
        self.level_margin = fast.eps_margin_m + qpp.area_margin + 1e-6
        self.references = References3(fast, params, spec.dynamics, spec.goal, self.area,
                                      spec.band)
        self.last: Plan | None = None

    # ---------------------------------------------------------------- public
    def plan(self, state: Array, hulls: tuple[Prism, ...], objective: Objective,
             prev_control: Array | None, zones: Sequence[Zone] = ()) -> Plan:
        """A plan from the 3-D ``state`` around or over ``hulls`` (prisms), ``zones`` kept
        out at their steps (module docstring)."""
        t0 = time.perf_counter()
        checked = check_request(state, hulls, objective, prev_control, dim=3)
        if isinstance(checked, str):
            return _failed(PlanStatus.INVALID_INPUT, checked, t0, objective)
        x0, u_prev, prisms = checked
        zones = self._footprints(zones)
        if self._reduces(x0, u_prev, prisms) and all(isinstance(z, Polytope) for z, _ in zones):
            plan = self._planar_plan(x0, u_prev, prisms, objective, t0, zones)
        else:
            early = self._start_checks(x0, prisms)
            if early is not None:
                plan = _failed(early[0], early[1], t0, objective)
            else:
                try:
                    plan = self._plan(x0, prisms, objective, u_prev, t0, zones)
                except Exception as exc:  # noqa: BLE001 - a crash is an ERROR plan, never a raise
                    plan = _failed(PlanStatus.ERROR, f"{type(exc).__name__}: {exc}", t0,
                                   objective)
            # the plane's planner starts its next plan from this one, in the plane
            self.planar.seed_previous(_flat_plan(plan) if plan.ok else None)
        self.last = plan if plan.ok else None
        return plan

    def reset(self) -> None:
        """Forget the previous plans (3-D and the plane's)."""
        self.last = None
        self.planar.seed_previous(None)

    def over_level(self, prism: Prism) -> float:
        """The altitude an over-row keeps above ``prism`` (z_hi + ε), +inf when the band has
        no room above it (m)."""
        top = prism.z_hi + self.epsilon_m
        return top if top + self.level_margin <= self.band.ceiling_m else float("inf")

    def _footprints(self, zones: Sequence[Zone]) -> list[Zone]:
        """``zones`` with each prism that cannot be passed over within the band as its
        footprint (a zone as tall as every altitude: the ``"band"`` reading's)."""
        return [(z.base if isinstance(z, Prism) and self.over_level(z) == float("inf") else z,
                 m) for z, m in zones]

    # ------------------------------------------------------------- reduction
    def _reduces(self, x0: Array, u_prev: Array, prisms: tuple[Prism, ...]) -> bool:
        """Every prism passed around only, and the UAV at G_o's altitude at rest vertically."""
        return (self.qp.at_rest(x0, u_prev, float(self.goal[2]))
                and all(self.over_level(p) == float("inf") for p in prisms))

    def _planar_plan(self, x0: Array, u_prev: Array, prisms: tuple[Prism, ...],
                     objective: Objective, t0: float, zones: Sequence[Zone]) -> Plan:
        """The plane's plan on the footprints, lifted to the UAV's altitude."""
        xy0 = np.array([x0[0], x0[1], x0[3], x0[4]])
        bases = [p.base for p in prisms]
        flat = (self.planar.plan_with_zones(xy0, bases, objective, u_prev[:2], zones)
                if zones
                else self.planar.plan(xy0, bases, objective, u_prev[:2]))
        if not flat.ok:
            failed = Plan.failed(2, flat.status, time.perf_counter() - t0, flat.message, dim=3)
            return dataclasses.replace(failed, objective=objective,
                                       info={**flat.info, "reduction": True})
        z = float(x0[2])
        states = np.array([lift_state(s, z) for s in flat.states])
        return dataclasses.replace(flat, states=states, controls=lift_controls(flat.controls),
                                   compute_time_s=time.perf_counter() - t0,
                                   info={**flat.info, "reduction": True})

    # ---------------------------------------------------------------- method
    def _start_checks(self, x0: Array, prisms: tuple[Prism, ...]
                      ) -> tuple[PlanStatus, str] | None:
        """The statuses before solving (as the plane's ``_start_checks``), with the band."""
        d_safe, eps = self.clearance_m, self.epsilon_m
        p0 = x0[:3]
        p1 = p0 + self.dynamics.dt_s * x0[3:]
        checker = SegmentChecker3(prisms)
        if prisms and checker.point_distance(p0) < d_safe:
            for i, prism in enumerate(prisms):
                dist = prism.distance(p0)
                if dist < d_safe:
                    return (PlanStatus.INVALID_INPUT,
                            f"start {p0} is {dist:.2f} m from prism {i} (< d_safe {d_safe} m): "
                            "no safe plan can start here")
        for i, prism in enumerate(prisms):
            if float(prism.margins(p1)[0]) < eps:
                return (PlanStatus.INFEASIBLE,
                        f"x_(t+1|t) position {p1} is fixed by the current velocity and lies "
                        f"within ε={eps} m of prism {i}: (P2) is infeasible")
        if self.area is not None and not (np.all(p1[:2] >= 0.0) and np.all(p1[:2] <= self.area)):
            return (PlanStatus.INFEASIBLE,
                    f"x_(t+1|t) position {p1} is fixed by the current velocity and lies outside "
                    "the area: (P2) is infeasible")
        if not self.band.contains(float(p1[2])):
            return (PlanStatus.INFEASIBLE,
                    f"x_(t+1|t) position {p1} is fixed by the current velocity and lies outside "
                    f"the band [{self.band.floor_m}, {self.band.ceiling_m}] m: (P2) is infeasible")
        if prisms:
            gap = float(checker.distances(p0[None], p1[None])[0])
            if gap < d_safe:
                return (PlanStatus.UNSAFE,
                        f"the first segment, fixed by the current velocity, passes {gap:.2f} m "
                        f"from a prism (< {d_safe} m)")
        return None

    def _keepouts(self, x0: Array, prisms: tuple[Prism, ...], zones: Sequence[Zone]
                  ) -> tuple[KeepOuts3, KeepOuts3, list[Zone]]:
        """The prisms within reach of this plan as keep-outs, with the zones within reach
        (as prisms taller than the band, at their steps); the prisms' alone (what the
        references avoid); the zones kept."""
        T = self.params.horizon
        reach = reach_radius(x0[3:], T, self.dynamics)
        near = [p for p in prisms if float(p.margins(x0[:3])[0]) - self.epsilon_m <= reach]
        keep = KeepOuts3.of_prisms(near, self.epsilon_m, T, self.area, self.band,
                                   self.level_margin)
        kept = [(z, m) for z, m in zones if _footprint(z).distance(x0[:2]) - self.epsilon_m
                <= reach]
        if not kept:
            return keep, keep, []
        tall = self.band.above_ceiling_m(self.epsilon_m + self.level_margin)
        walls = [z if isinstance(z, Prism) else Prism(z, -tall, tall) for z, _ in kept]
        mask = np.vstack([np.ones((len(near), T + 1), dtype=bool)]
                         + [m[None, : T + 1] for _, m in kept])
        both = KeepOuts3.of_prisms(near + walls, self.epsilon_m, T, self.area, self.band,
                                   self.level_margin)
        return dataclasses.replace(both, mask=mask), keep, kept

    def _plan(self, x0: Array, prisms: tuple[Prism, ...], objective: Objective, u_prev: Array,
              t0: float, zones: Sequence[Zone]) -> Plan:
        kappa = self.params.kappa(objective)
        both, keep, kept = self._keepouts(x0, prisms, zones)
        info: dict[str, object] = {"n_hulls": len(keep.polys), "n_hulls_input": len(prisms),
                                   "n_over": int(np.isfinite(keep.level).sum())}
        if zones:
            info["n_zones"] = len(kept)
        solve = CountedSolve(self.qp, x0, u_prev, self.goal, kappa)
        free = solve(np.zeros(0, int), np.zeros((0, 3)), np.zeros(0), confirm=True)
        if not free.ok:
            return _failed(PlanStatus.ERROR, f"relaxed QP failed: {free.status}", t0, objective,
                           info)
        info["lower_bound"] = free.objective
        candidates: list[Candidate] = []
        if both.feasible(free.positions):
            candidates.append(Candidate("relaxation", free.positions, free.controls,
                                        free.objective, 0))
        else:
            shared = CfsPlan(self.fast, both, free.positions, solve)
            refs = self.references(x0, free.positions, keep, kappa, self.last)
            info["homotopies"] = [name for name, _, _ in refs]
            runs = [Cfs3(shared, name, ref, retime) for name, ref, retime in refs]
            race(runs, shared, free.objective, t0, info)
            if not any(r.best is not None for r in runs):
                brake = Cfs3(shared, "brake", self.references.braking(x0), max_elastic=2)
                while not brake.done:
                    brake.step()
                runs.append(brake)
            candidates.extend(r.best for r in runs if r.best is not None)
        info["n_qp"] = solve.n
        candidates.sort(key=lambda c: c.cost)
        reasons: list[str] = []
        for cand in candidates:
            plan = self._finish(cand, x0, prisms, objective, kappa, u_prev, t0, info, reasons,
                                kept)
            if plan is not None:
                return plan
        msg = "no verified candidate" + (f": {'; '.join(reasons[:3])}" if reasons else "")
        return _failed(PlanStatus.UNSAFE, msg, t0, objective, info)

    def _finish(self, cand: Candidate, x0: Array, prisms: tuple[Prism, ...],
                objective: Objective, kappa: tuple[float, float], u_prev: Array, t0: float,
                info: dict[str, object], reasons: list[str], zones: Sequence[Zone] = ()
                ) -> Plan | None:
        """Roll out, verify (band and prisms; each zone at its steps, in the plane) and
        package one candidate; None if it fails."""
        d = self.dynamics
        controls = np.clip(cand.controls, -d.u_max_n, d.u_max_n)
        states = rollout(x0, controls, d)
        verdict = verify_p2_plan(states, controls, prisms, d, self.epsilon_m, self.clearance_m,
                                 self.area, rolled_out=True, band=self.band)
        if not verdict.ok:
            reasons.append(f"{cand.name}: {verdict.reason}")
            return None
        worst = _zone_margin(states, zones) - self.epsilon_m
        if worst < -1e-6:
            reasons.append(f"{cand.name}: {-worst:.3g} m inside a risk zone's ε")
            return None
        margin = disjunction_margin(states[1:, :3], prisms, self.epsilon_m)
        cost = p2_cost(states, controls, self.goal, kappa, u_prev)
        out = dict(info)
        out.update(homotopy=cand.name, cfs_iterations=cand.iterations,
                   clearance_m=verdict.clearance_m, disjunction_margin_m=margin,
                   optimal=cand.name == "relaxation", climb_m=float(np.max(states[:, 2]) - x0[2]))
        lb = out.get("lower_bound")
        if isinstance(lb, float) and cost > 0:
            out["bound_gap"] = max(0.0, (cost - lb) / cost)
        return Plan(system=2, status=PlanStatus.OK, states=states, controls=controls,
                    compute_time_s=time.perf_counter() - t0, objective=objective, cost=cost,
                    info=out)


def _footprint(zone: Polytope | Prism) -> Polytope:
    """A zone's footprint."""
    return zone.base if isinstance(zone, Prism) else zone


def _zone_margin(states: Array, zones: Sequence[Zone]) -> float:
    """The least margin (m) of the positions of ``states`` from each zone at its steps: a
    footprint's in the plane (at every altitude), a prism's by its six faces (+inf: none)."""
    worst = float("inf")
    flat = [(z, m) for z, m in zones if isinstance(z, Polytope)]
    if flat:
        faces = FaceStack.of([z for z, _ in flat]).margins(states[:, :2])
        steps = np.stack([m for _, m in flat], axis=1)
        worst = float(np.min(np.where(steps, faces, np.inf)))
    for z, m in zones:
        if isinstance(z, Prism):
            worst = min(worst, float(np.min(np.where(m[: len(states)], z.margins(
                states[:, :3]), np.inf))))
    return worst


def planar_spec(spec: MissionSpec) -> MissionSpec:
    """The 2-D mission of a 3-D one (its plane: the same area, goal, ε, d_safe and Eq. (1))."""
    return dataclasses.replace(spec, dynamics=planar_dynamics(spec.dynamics))


def _flat_plan(plan: Plan) -> Plan:
    """A 3-D plan in the plane (its altitude dropped), for the plane's next reference."""
    return dataclasses.replace(plan, states=plan.states[:, [0, 1, 3, 4]],
                               controls=plan.controls[:, :2])


def _failed(status: PlanStatus, msg: str, t0: float, objective: Objective | None,
            info: dict[str, object] | None = None) -> Plan:
    plan = Plan.failed(2, status, time.perf_counter() - t0, msg, dim=3)
    return dataclasses.replace(plan, objective=objective, info=dict(info or {}))
