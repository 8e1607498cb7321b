"""The certified method in 3-D (docs/three_d.md, 6. System 2, Certified;
dualpilot/system2/certify/planner3.py).

With every front taller than the ceiling less ε and the UAV at G_o's altitude at rest
vertically, the 3-D plan is the 2-D certified plan on the footprints, lifted, bit for bit,
with the same cost, bound and certified gap; that bound is below the proven optimum of the
exact 3-D (P2) (SCIP, T = 20). Outside that case the bound is the least over the branches
"over or around" (dualpilot/system2/certify/branches.py), below SCIP's proven optimum too
and never below the relaxation that drops the fronts that can be passed over, and the plan
the cheapest verified of the fast 3-D plan and the searches' plans lifted or climbed over.
A mission is refused up front where its fronts may be lower (``certifies_3d``).

The searches here stop by node count, not by the wall clock (``DETERMINISTIC``), so that
two runs on the same instance do the same work whatever the machine's load.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dualpilot.mission.monitor import check
from dualpilot.model.altitude import AltitudeBand, lift_state
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire_height import FireHeightParams
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from dualpilot.system2.certify.bnb import CertifyParams
from dualpilot.system2.certify.planner import CertifiedSystem2
from dualpilot.system2.certify.planner3 import certifies_3d
from dualpilot.system2.exact import ExactSystem2
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params, p2_cost, verify_p2_plan

DYN3 = DynamicsParams(dim=3)
SPEC3 = MissionSpec(dynamics=DYN3)
SPEC2 = MissionSpec()
BAND = SPEC3.band  # [20, 120] m, start and G_o at 50 m
EPS = SPEC3.clearance_m  # 25 m
TALL = SPEC3.above_ceiling_m  # 145 m
#: a search stopped by its node count only (the wall clock never decides)
DETERMINISTIC = CertifyParams(time_budget_s=1e6, plain_root_s=1e6, max_nodes=6)


def _instance(rng: np.random.Generator, top: float = TALL
              ) -> tuple[np.ndarray, tuple[Prism, ...], np.ndarray]:
    """A 3-D start at G_o's altitude at rest vertically, u_{t|t} with no vertical force and
    1-4 cuboids ``top`` tall between it and G."""
    g = SPEC3.goal_center
    start = rng.uniform(30, 500, 2)
    x0 = np.concatenate([start, [BAND.goal_z_m], rng.uniform(-6, 6, 2), [0.0]])
    prisms = []
    for _ in range(int(rng.integers(1, 5))):
        c = start + rng.uniform(0.2, 0.8) * (g[:2] - start) + rng.normal(0, 60, 2)
        rect = Rect(float(c[0]), float(c[1]), float(rng.uniform(100, 250)),
                    float(rng.uniform(100, 250)))
        prism = Prism.cuboid(rect, 0.0, top)
        if prism.distance(x0[:3]) > 60.0:
            prisms.append(prism)
    u_prev = np.concatenate([rng.uniform(-3, 3, 2), [0.0]])
    return x0, tuple(prisms), u_prev


def _assert_flies(plan: Plan, x0: np.ndarray, prisms: tuple[Prism, ...],
                  spec: MissionSpec = SPEC3) -> None:
    """The plan passes verify_p2_plan in 3-D (band and prisms) and the run-time monitor."""
    verdict = verify_p2_plan(plan.states, plan.controls, prisms, spec.dynamics, EPS,
                             spec.d_safe_m, spec.area_size_m, band=spec.band)
    assert verdict.ok, verdict.reason
    assert check(plan, x0, prisms, spec).ok


def _check_tall(n: int, seed: int, steps: int) -> int:
    """Fronts taller than the ceiling: each 3-D plan of a few consecutive requests is the
    2-D plan lifted, bit for bit, with the same cost, bound and gap; the count of OK plans."""
    rng = np.random.default_rng(seed)
    p3 = CertifiedSystem2(SPEC3, certify=DETERMINISTIC)
    p2 = CertifiedSystem2(SPEC2, certify=DETERMINISTIC)
    ok = 0
    for k in range(n):
        x0, prisms, u_prev = _instance(rng)
        p3.reset()
        p2.reset()
        x2, u2 = x0[[0, 1, 3, 4]], u_prev[:2]
        objective = list(Objective)[k % 2]
        for _ in range(steps):
            a = p3.plan(x0, prisms, objective, u_prev)
            b = p2.plan(x2, [p.base for p in prisms], objective, u2)
            assert a.status == b.status and a.message == b.message
            if not b.ok:
                break
            ok += 1
            assert a.info["reduction"] is True and a.info["source"] == b.info["source"]
            assert np.array_equal(a.states, np.array([lift_state(s, BAND.goal_z_m)
                                                      for s in b.states]))
            assert np.array_equal(a.controls[:, :2], b.controls)
            assert np.all(a.controls[:, 2] == 0.0)
            assert a.cost == b.cost and a.bound == b.bound and b.bound is not None
            assert a.certified_gap == b.certified_gap
            assert [t[1:] for t in p3.trace] == [t[1:] for t in p2.trace]  # (bound, cost)
            _assert_flies(a, x0, prisms)
            # the lifted plan's 3-D Eq. (S2) is the 2-D cost (the z terms are 0)
            kappa = System2Params().kappa(objective)
            assert p2_cost(a.states, a.controls, SPEC3.goal_center, kappa, u_prev) == \
                pytest.approx(b.cost, rel=1e-12)
            x2, u2 = b.states[1], b.controls[0]
            x0, u_prev = a.states[1], a.controls[0]
    return ok


def test_tall_fronts_give_the_2d_certified_plans() -> None:
    assert _check_tall(6, 11, steps=2) >= 8


@pytest.mark.slow
def test_tall_fronts_give_the_2d_certified_plans_60() -> None:
    assert _check_tall(60, 12, steps=1) >= 45
    assert _check_tall(10, 13, steps=3) >= 20


# ------------------------------------------------------------------ soundness against SCIP
def _low_instance(rng: np.random.Generator
                  ) -> tuple[np.ndarray, tuple[Prism, ...], np.ndarray]:
    """As :func:`_instance`, each cuboid's top one of 10.7, 30.8, 50, 80, 95 m (the ceiling
    less ε) or taller than the ceiling, and on every other instance the UAV off G_o's
    altitude, climbing, with a vertical force."""
    x0, prisms, u_prev = _instance(rng)
    tops = (10.7, 30.8, 50.0, 80.0, BAND.ceiling_m - EPS, TALL)
    prisms = tuple(Prism(p.base, 0.0, float(rng.choice(tops))) for p in prisms)
    if rng.random() < 0.5:
        x0[2], x0[5], u_prev[2] = rng.uniform(40.0, 90.0), rng.uniform(-2, 2), rng.uniform(-1, 1)
    return x0, prisms, u_prev


def _check_against_scip(n: int, seed: int, low: bool = False) -> int:
    """At T = 20, where SCIP proves the exact 3-D (P2) optimal: the certified bound is at
    most that optimum (1e-5 relative: SCIP's tolerances, docs/certify.md), and the certified
    plan costs no less than it. The count of instances SCIP proved."""
    rng = np.random.default_rng(seed)
    params = System2Params(horizon=20, max_hulls=4, max_faces=4, time_limit_s=60.0)
    certified = CertifiedSystem2(SPEC3, params, certify=DETERMINISTIC)
    exact = ExactSystem2(SPEC3, params)
    proved = 0
    for k in range(n):
        x0, prisms, u_prev = _low_instance(rng) if low else _instance(rng)
        # bring the start near enough for the fronts to matter within 20 steps
        x0[:2] = SPEC3.goal_center[:2] - rng.uniform(150, 400, 2)
        prisms = tuple(p for p in prisms if p.distance(x0[:3]) > 60.0)
        objective = list(Objective)[k % 2]
        certified.reset()
        plan = certified.plan(x0, prisms, objective, u_prev)
        best = exact.plan(x0, prisms, objective, u_prev)
        if not (best.ok and best.info.get("optimal") is True):
            continue
        proved += 1
        assert best.cost is not None
        if plan.ok:
            assert plan.bound is not None and plan.cost is not None
            assert plan.bound <= best.cost * (1 + 1e-5)
            assert plan.cost >= best.cost * (1 - 1e-5)
            _assert_flies(plan, x0, prisms)
        else:  # the certified method may fail to plan; it never calls (P2) infeasible here
            assert plan.status is not PlanStatus.INFEASIBLE
    return proved


def test_the_bound_is_below_scips_3d_optimum() -> None:
    assert _check_against_scip(2, 21) >= 1


@pytest.mark.slow
def test_the_bound_is_below_scips_3d_optimum_many() -> None:
    assert _check_against_scip(16, 22) >= 12


def test_over_low_fronts_the_bound_is_below_scips_3d_optimum() -> None:
    """Off the reduction (fronts that can be passed over, a UAV off G_o's altitude): the
    relaxation's bound, against SCIP's proven optimum."""
    assert _check_against_scip(3, 23, low=True) >= 2


@pytest.mark.slow
def test_over_low_fronts_the_bound_is_below_scips_3d_optimum_many() -> None:
    assert _check_against_scip(40, 24, low=True) >= 30


def _check_heights(n: int, seed: int) -> int:
    """Fronts of drawn heights, U[5, 40] m (the mission's reading) or taller than the
    ceiling, the UAV at G_o's altitude or off it climbing, at T = 20: the bound of "over or
    around" is at most SCIP's proven optimum of the exact 3-D (P2) (1e-5 relative) and at
    least the relaxation that drops the passable fronts (the plane's search on the others'
    footprints, the same node-count budget), the plan costs no less than the optimum and
    flies. The count of instances SCIP proved."""
    rng = np.random.default_rng(seed)
    params = System2Params(horizon=20, max_hulls=4, max_faces=4, time_limit_s=60.0)
    certified = CertifiedSystem2(SPEC3, params, certify=DETERMINISTIC)
    flat = CertifiedSystem2(SPEC2, params, certify=DETERMINISTIC)
    exact = ExactSystem2(SPEC3, params)
    proved = 0
    for k in range(n):
        x0, prisms, u_prev = _instance(rng)
        prisms = tuple(Prism(p.base, 0.0, TALL if rng.random() < 0.3
                             else float(rng.uniform(5.0, 40.0))) for p in prisms)
        if (k // 2) % 2:
            x0[2], x0[5], u_prev[2] = rng.uniform(30.0, 90.0), rng.uniform(-3, 3), \
                rng.uniform(-1, 1)
        x0[:2] = SPEC3.goal_center[:2] - rng.uniform(150, 400, 2)
        prisms = tuple(p for p in prisms if p.distance(x0[:3]) > 60.0)
        objective = list(Objective)[k % 2]
        certified.reset()
        flat.reset()
        plan = certified.plan(x0, prisms, objective, u_prev)
        tall = [p.base for p in prisms if p.z_hi + EPS > BAND.ceiling_m]
        dropped = flat.plan(x0[[0, 1, 3, 4]], tall, objective, u_prev[:2])
        best = exact.plan(x0, prisms, objective, u_prev)
        if not (best.ok and best.info.get("optimal") is True):
            continue
        proved += 1
        assert best.cost is not None
        if plan.ok:
            assert plan.bound is not None and plan.cost is not None
            assert plan.bound <= best.cost * (1 + 1e-5)
            assert plan.cost >= best.cost * (1 - 1e-5)
            if dropped.bound is not None and "reduction" not in plan.info:
                assert plan.bound >= min(dropped.bound, plan.cost) * (1 - 1e-12)
            _assert_flies(plan, x0, prisms)
        else:
            assert plan.status is not PlanStatus.INFEASIBLE
    return proved


def test_over_fronts_of_drawn_heights_the_bound_is_below_scips_3d_optimum() -> None:
    assert _check_heights(3, 31) >= 2


@pytest.mark.slow
def test_over_fronts_of_drawn_heights_the_bound_is_below_scips_3d_optimum_many() -> None:
    assert _check_heights(60, 32) >= 45


# ------------------------------------------------------------------ outside the reduction
#: the least Σ (z_σ − 50)² of a climb from 50 m to z at the horizon's last step, X's
#: 15 m/s a step the fastest descent back in time: 10 m: none; 30.8 m: 55.8 − 50 = 5.8 m
#: at τ = T alone; 95 m: 120 − 50 = 70, 55, 40, 25, 10 m at T, T−1, …, T−4
HAND_CLIMB = {10.0: 0.0, 30.8: 5.8**2, BAND.ceiling_m - EPS: 70.0**2 + 55.0**2 + 40.0**2
              + 25.0**2 + 10.0**2}


@pytest.mark.parametrize("top", [10.0, 30.8, BAND.ceiling_m - EPS])
def test_a_front_that_can_be_passed_over_gets_the_least_of_around_and_over(top: float
                                                                           ) -> None:
    """A cuboid 10 m, 30.8 m tall, or exactly the ceiling less ε (95 m: z = 120 m keeps ε
    above it, so (P2) may pass over it; the fast method's own reduction does not try): the
    bound is the least of "around" (the planar search on the footprint) and "over" (the
    planar search with no hull plus the climb to top + ε at some step, by hand above), so
    at most the free planar optimum (an independent QP, Clarabel) plus that climb, and
    above the free optimum by nearly the climb where going round costs more (95 m); the
    plan is the better of the fast 3-D plan and the planar plans lifted where they keep the
    cuboid (top + ε ≤ 50 m: the 10 m one, whose gap then closes), and flies."""
    rect = Rect(450.0, 450.0, 250.0, 250.0)
    x0 = np.array([150.0, 150.0, 50.0, 5.0, 5.0, 0.0])
    prisms = (Prism.cuboid(rect, 0.0, top),)
    plan = CertifiedSystem2(SPEC3, certify=DETERMINISTIC).plan(x0, prisms)
    fast = FastSystem2(SPEC3).plan(x0, prisms)
    assert plan.ok and fast.ok and plan.cost is not None and fast.cost is not None
    assert plan.bound is not None and plan.bound <= plan.cost
    free = _free_planar_optimum(x0)
    assert plan.bound <= free * (1 + 1e-6) + HAND_CLIMB[top]
    assert plan.info["certify_n_kept"] == 0 and plan.cost <= fast.cost
    if top + EPS <= 50.0:  # passed over at 50 m: the free optimum flies, the gap closes
        assert plan.certified_gap is not None and plan.certified_gap <= 0.01
    if top == BAND.ceiling_m - EPS:  # the climb counted (the planar bound within 0.1 %)
        assert plan.bound > free
    _assert_flies(plan, x0, prisms)


def _free_planar_optimum(x0: np.ndarray) -> float:
    """(P2) with no hull in the plane (Eq. (1), U, X and the area), by Clarabel: the planar
    relaxation's optimum, which the planar certified bound never exceeds."""
    import cvxpy as cp

    from dualpilot.model.dynamics import transition_matrices

    T, dyn = System2Params().horizon, SPEC2.dynamics
    phi, gamma = transition_matrices(dyn)
    k1, k2 = System2Params().kappa(Objective.MISSION_TIME)
    x = cp.Variable((T + 1, 4))
    u = cp.Variable((T, 2))
    cons = [x[0] == x0[[0, 1, 3, 4]], cp.abs(u) <= dyn.u_max_n, cp.abs(x[1:, 2:]) <= dyn.v_max_mps,
            x[1:, :2] >= 0.0, x[1:, :2] <= SPEC2.area_size_m]
    cons += [x[k + 1] == phi @ x[k] + gamma @ u[k] for k in range(T)]
    du = cp.vstack([u[0], u[1:] - u[:-1]])
    goal = np.ones((T, 1)) @ SPEC2.goal.center[None, :]
    prob = cp.Problem(cp.Minimize(k1 * cp.sum_squares(x[1:, :2] - goal)
                                  + k2 * cp.sum_squares(du)), cons)
    prob.solve(solver=cp.CLARABEL)
    assert prob.status == "optimal"
    return float(prob.value)


def test_a_climbing_uav_gets_the_relaxations_bound() -> None:
    """Tall fronts, but the UAV climbing (v_z = 1 m/s): not the reduction; the fast 3-D
    plan (the planar one cannot be lifted) with the planar search's bound on the footprint."""
    rect = Rect(450.0, 450.0, 250.0, 250.0)
    x0 = np.array([150.0, 150.0, 50.0, 5.0, 5.0, 1.0])
    prisms = (Prism.cuboid(rect, 0.0, TALL),)
    plan = CertifiedSystem2(SPEC3, certify=DETERMINISTIC).plan(x0, prisms)
    assert plan.ok and plan.cost is not None and plan.bound is not None
    assert plan.bound <= plan.cost and "reduction" not in plan.info
    assert plan.info["certify_n_kept"] == 1
    _assert_flies(plan, x0, prisms)


def test_invalid_3d_requests() -> None:
    planner = CertifiedSystem2(SPEC3, certify=DETERMINISTIC)
    bad = planner.plan(np.zeros(4), ())
    assert bad.status is PlanStatus.INVALID_INPUT and "6 finite numbers" in bad.message
    assert bad.bound is None
    flat = planner.plan(np.array([150.0, 150.0, 50.0, 0.0, 0.0, 0.0]),
                        (Rect(450.0, 450.0, 250.0, 250.0).polytope(),))
    assert flat.status is PlanStatus.INVALID_INPUT and "Prism" in flat.message


# ------------------------------------------------------------------ the mission's scope
def test_which_missions_the_method_certifies_in_3d() -> None:
    """Decided from the reading before a mission: every front's top + ε above the ceiling
    (120 m, ε = 25 m) and the start at G_o's altitude."""
    paper = "paper"
    assert certifies_3d(SPEC3, FireHeightParams(), paper) == ""  # auto: above-ceiling
    assert certifies_3d(SPEC3, FireHeightParams("above-ceiling"), "grass-5") == ""
    # uniform from 100 m: 100 + 25 > 120; from 95 m: 95 + 25 = 120, not above
    assert certifies_3d(SPEC3, FireHeightParams("uniform"), paper) == ""
    low = certifies_3d(SPEC3, FireHeightParams("uniform", 95.0, 250.0), paper)
    assert low.endswith("here fire_height=uniform from 95 m") and "(95 m)" in low
    assert "fire_height=plume" in certifies_3d(SPEC3, FireHeightParams(), "grass-15")
    off = dataclasses.replace(SPEC3, band=AltitudeBand(goal_altitude_m=60.0))
    assert "the start at 50 m and G_o at 60 m" in certifies_3d(off, FireHeightParams(), paper)


def test_the_registry_builds_it_in_3d() -> None:
    assert isinstance(build_planner(2, SPEC3, "certified"), CertifiedSystem2)


def test_an_s2_mission_over_tall_fronts_flies_with_a_bound_on_every_plan() -> None:
    """``--controller s2 --s2-method certified --seed 26 --timing paper --set dim=3 --set
    fire_height=uniform`` (fronts U[100, 250] m: 100 + ε above the ceiling): it reaches G at
    G_o's altitude, and every flown plan carries a bound no more than its cost."""
    from dualpilot.mission.config import MissionConfig
    from dualpilot.mission.local import local_mission
    from dualpilot.mission.params import Timing

    config = MissionConfig.named("s2", seed=26, timing=Timing.PAPER, profile="today-3d",
                                 system2_method="certified",
                                 settings={"fire_height": "uniform"})
    result = local_mission(config).run()
    assert result.success
    flown = [r for r in result.records if r.system == 2]
    assert len(flown) == len(result.records) > 40
    for r in flown:
        assert r.cost is not None and r.bound is not None and r.bound <= r.cost
        assert r.certified_gap is not None and r.certified_gap >= 0.0
    assert all(float(r.state[2]) == BAND.goal_z_m for r in result.records)
