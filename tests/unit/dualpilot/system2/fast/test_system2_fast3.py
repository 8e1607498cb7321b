"""System 2's fast method in 3-D: the split QP, plans over low fires, the reduction to 2-D."""

from __future__ import annotations

import dataclasses

import cvxpy as cp
import numpy as np
import pytest

from dualpilot.model.altitude import AltitudeBand, lift_state
from dualpilot.model.dynamics import DynamicsParams, transition_matrices
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.prism import Prism
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.plan import Objective, PlanStatus
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from dualpilot.system2.anytime import AnytimeSystem2
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.fast.qp import QpParams
from dualpilot.system2.fast.risk import RiskSystem2
from dualpilot.system2.fast.split import OVER, SplitQp
from dualpilot.system2.fast.thorough import ThoroughSystem2
from dualpilot.system2.problem import System2Params, verify_p2_plan

DYN3 = DynamicsParams(dim=3)
SPEC3 = MissionSpec(dynamics=DYN3)
SPEC2 = MissionSpec()
BAND = SPEC3.band


# ------------------------------------------------------------------ the split QP
def _whole_qp(T: int, x0: np.ndarray, u_prev: np.ndarray, goal: np.ndarray,
              kappa: tuple[float, float], rows: tuple[np.ndarray, np.ndarray, np.ndarray],
              area: float, band: AltitudeBand) -> tuple[float, np.ndarray]:
    """The 3-D restriction as one QP in the states and forces of Eq. (1), by Clarabel:
    (Eq. (S2) value, positions p_1..p_T). The bounds are the fast QP's, tightened by its
    margins (QpParams)."""
    m = QpParams()
    phi, gamma = transition_matrices(DYN3)
    X = cp.Variable((T + 1, 6))
    U = cp.Variable((T, 3))
    cons = [X[0] == x0, X[1:] == X[:-1] @ phi.T + U @ gamma.T,
            cp.abs(U) <= DYN3.u_max_n - m.u_margin,
            cp.abs(X[1:, 3:]) <= DYN3.v_max_mps - m.v_margin,
            X[2:, :2] >= m.area_margin, X[2:, :2] <= area - m.area_margin,
            X[2:, 2] >= band.floor_m + m.area_margin, X[2:, 2] <= band.ceiling_m - m.area_margin]
    tau, nrm, rhs = rows
    for t, n, r in zip(tau.tolist(), nrm, rhs.tolist(), strict=True):
        cons.append(n @ X[t, :3] >= r)
    du = cp.vstack([U[0] - u_prev, U[1:] - U[:-1]])
    cost = kappa[0] * cp.sum_squares(X[1:, :3] - goal[None, :]) + kappa[1] * cp.sum_squares(du)
    prob = cp.Problem(cp.Minimize(cost), cons)
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12,
               max_iter=400)
    assert prob.status == "optimal", prob.status
    return float(prob.value), np.asarray(X.value)[1:, :3]


def _random_restriction(rng: np.random.Generator, T: int, area: float):
    """A state, u_{t|t}, G_o, κ and rows (around and over) that a braking flight keeps."""
    x0 = np.concatenate([rng.uniform(300, 700, 2), rng.uniform(40, 100, 1),
                         rng.uniform(-10, 10, 2), rng.uniform(-3, 3, 1)])
    u_prev = rng.uniform(-5, 5, 3)
    goal = np.concatenate([rng.uniform(0, area, 2), rng.uniform(BAND.floor_m, BAND.ceiling_m, 1)])
    kappa = (float(rng.uniform(0.1, 2.0)), float(rng.uniform(0.05, 2.0)))
    # a feasible flight: brake at 0.9 of U
    phi, gamma = transition_matrices(DYN3)
    x, pos = x0.copy(), [x0[:3]]
    for _ in range(T):
        u = np.clip(-(1 - DYN3.zeta) * x[3:] * DYN3.mass_kg / DYN3.dt_s,
                    -0.9 * DYN3.u_max_n, 0.9 * DYN3.u_max_n)
        x = phi @ x + gamma @ u
        pos.append(x[:3])
    flight = np.array(pos)  # row k: p_k
    n_rows = int(rng.integers(0, 3 * T))
    tau = rng.integers(2, T + 1, n_rows)
    over = rng.random(n_rows) < 0.4
    ang = rng.uniform(0, 2 * np.pi, n_rows)
    nrm = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(n_rows)])
    nrm[over] = OVER
    rhs = np.einsum("ij,ij->i", nrm, flight[tau]) - rng.exponential(5.0, n_rows)
    return x0, u_prev, goal, kappa, (tau, nrm, rhs)


def _check_split(n: int, seed: int) -> None:
    """The split solved tightly (Clarabel, 1e-12) equals the whole QP to 1e-9 (relative);
    the fast method's own solver (the banded interior point, 1e-9 in its scaled units) to
    1e-5."""
    rng = np.random.default_rng(seed)
    T, area = 30, 1000.0
    tight = SplitQp(T, DYN3, area, BAND, QpParams(backend="clarabel", tol=1e-12))
    fast = SplitQp(T, DYN3, area, BAND)
    for _ in range(n):
        x0, u_prev, goal, kappa, rows = _random_restriction(rng, T, area)
        whole, pos = _whole_qp(T, x0, u_prev, goal, kappa, rows, area, BAND)
        res = tight.solve(x0, u_prev, goal, kappa, *rows, confirm=True)
        assert res.ok, res.status
        assert res.objective == pytest.approx(whole, rel=1e-9, abs=1e-9)
        np.testing.assert_allclose(res.positions[:T], pos, rtol=0, atol=1e-3)
        quick = fast.solve(x0, u_prev, goal, kappa, *rows, confirm=True)
        assert quick.ok, quick.status
        assert quick.objective == pytest.approx(whole, rel=1e-5)


def test_split_qp_equals_the_whole_qp():
    """The planar QP plus the altitude's QP is the 3-D QP (Clarabel on the whole)."""
    _check_split(20, 0)


@pytest.mark.slow
def test_split_qp_equals_the_whole_qp_200():
    _check_split(200, 1)


def test_altitude_at_rest_is_written_down_exactly():
    """No over-row, at G_o's altitude at rest: z ≡ G_z and u_z ≡ 0 without a solve, and a
    solve of the same QP (a small climb asked, then none) agrees."""
    T = 40
    qp = SplitQp(T, DYN3, 1000.0, BAND)
    x0 = np.array([100.0, 200.0, 50.0, 3.0, -2.0, 0.0])
    u0 = np.array([1.0, -1.0, 0.0])
    goal = np.array([900.0, 900.0, 50.0])
    none = (np.zeros(0, int), np.zeros((0, 3)), np.zeros(0))
    rest = qp.solve(x0, u0, goal, (1.0, 0.1), *none)
    assert "at rest" in rest.status
    assert np.all(rest.positions[:, 2] == 50.0) and np.all(rest.controls[:, 2] == 0.0)
    # the same altitude QP solved (by the interior point): the same optimum, z ≡ 50
    solved = qp.vertical.solve(np.array([50.0, 0.0]), np.zeros(1), np.array([50.0]),
                               (1.0, 0.1), np.zeros(0, int), np.zeros((0, 1)), np.zeros(0),
                               confirm=True)
    assert solved.ok
    np.testing.assert_allclose(solved.positions[:, 0], 50.0, atol=1e-6)
    assert solved.objective < 1e-6
    # the plane's part is the 2-D QP's, bit for bit
    flat = qp.plane.solve(np.array([100.0, 200.0, 3.0, -2.0]), u0[:2], goal[:2], (1.0, 0.1),
                          none[0], none[1][:, :2], none[2], confirm=True)
    assert np.array_equal(rest.positions[:, :2], flat.positions)
    assert rest.objective == flat.objective


# ------------------------------------------------------------------ plans in 3-D
def _random_instance(rng: np.random.Generator, low: bool):
    """A 3-D start, u_{t|t} and 1-4 fire cuboids between it and G (some low when ``low``)."""
    g = SPEC3.goal_center
    start = rng.uniform(30, 500, 2)
    z = float(rng.uniform(30, 100)) if low else BAND.goal_z_m
    v = np.concatenate([rng.uniform(-6, 6, 2), rng.uniform(-2, 2, 1) if low else [0.0]])
    x0 = np.concatenate([start, [z], v])
    prisms = []
    for _ in range(int(rng.integers(1, 5))):
        c = start + rng.uniform(0.2, 0.8) * (g[:2] - start) + rng.normal(0, 60, 2)
        rect = Rect(float(c[0]), float(c[1]), float(rng.uniform(100, 250)),
                    float(rng.uniform(100, 250)))
        top = (float(rng.choice([10.7, 30.8, 50.0, 80.0, SPEC3.above_ceiling_m])) if low
               else SPEC3.above_ceiling_m)
        prism = Prism.cuboid(rect, 0.0, top)
        if prism.distance(x0[:3]) > 60.0:
            prisms.append(prism)
    u_prev = np.concatenate([rng.uniform(-3, 3, 2), rng.uniform(-1, 1, 1) if low else [0.0]])
    return x0, tuple(prisms), u_prev


def _check_plans(n: int, seed: int) -> int:
    """Every OK 3-D plan passes verify_p2_plan with the band and the prisms; the count of OK."""
    rng = np.random.default_rng(seed)
    planner = FastSystem2(SPEC3)
    ok = 0
    for _ in range(n):
        x0, prisms, u_prev = _random_instance(rng, low=True)
        planner.reset()
        plan = planner.plan(x0, prisms, Objective.MISSION_TIME, u_prev)
        assert plan.status in (PlanStatus.OK, PlanStatus.UNSAFE, PlanStatus.INFEASIBLE), \
            plan.message
        if not plan.ok:
            continue
        ok += 1
        verdict = verify_p2_plan(plan.states, plan.controls, prisms, DYN3, SPEC3.clearance_m,
                                 SPEC3.d_safe_m, SPEC3.area_size_m, band=BAND)
        assert verdict.ok, verdict.reason
        assert np.array_equal(plan.states[0], x0)
        if prisms:  # the clearance by the exact 3-D distances, independently
            pts = plan.states[:, :3]
            gaps = SegmentChecker3(prisms).distances(pts[:-1], pts[1:])
            assert float(np.min(gaps)) >= SPEC3.d_safe_m - 1e-6
    return ok


def test_random_3d_plans_verify():
    assert _check_plans(12, 3) >= 8


@pytest.mark.slow
def test_random_3d_plans_verify_many():
    assert _check_plans(150, 4) >= 100


def test_plan_passes_over_a_low_wall():
    """A grass fire's wall across the whole area between start and G (top 30.8 m): no way
    around it; the plan climbs over it, ε above its top, and descends again."""
    wall = Prism.cuboid(Rect(500.0, 450.0, 1000.0, 120.0), 0.0, 30.8)
    x0 = np.array([200.0, 200.0, 50.0, 0.0, 6.0, 0.0])
    plan = FastSystem2(SPEC3).plan(x0, (wall,))
    assert plan.ok, plan.message
    pos = plan.states[1:, :3]
    inside = np.abs(pos[:, 1] - 450.0) <= 60.0 + SPEC3.clearance_m
    assert np.any(inside)
    assert np.all(pos[inside, 2] >= 30.8 + SPEC3.clearance_m - 1e-6)
    assert pos[:, 1].max() > 600.0  # it crossed
    verdict = verify_p2_plan(plan.states, plan.controls, (wall,), DYN3, SPEC3.clearance_m,
                             SPEC3.d_safe_m, SPEC3.area_size_m, band=BAND)
    assert verdict.ok, verdict.reason
    assert np.all(plan.states[:, 2] <= BAND.ceiling_m) and np.all(plan.states[:, 2] >= 20.0)
    homotopies = plan.info["homotopies"]
    assert isinstance(homotopies, list) and "over0" in homotopies
    # the method built on it, every homotopy to convergence: no dearer
    built = build_planner(2, SPEC3, "thorough")
    assert isinstance(built, ThoroughSystem2)
    thorough = built.plan(x0, (wall,))
    assert thorough.ok and thorough.cost is not None and plan.cost is not None
    assert thorough.cost <= plan.cost * (1 + 1e-9)
    assert verify_p2_plan(thorough.states, thorough.controls, (wall,), DYN3, SPEC3.clearance_m,
                          SPEC3.d_safe_m, SPEC3.area_size_m, band=BAND).ok
    # a wall whose top + ε (125 m) is above the ceiling: no plan crosses it
    tall = Prism.cuboid(Rect(500.0, 450.0, 1000.0, 120.0), 0.0, 100.0)
    blocked = FastSystem2(SPEC3).plan(x0, (tall,))
    if blocked.ok:
        assert blocked.states[:, 1].max() < 450.0 - 60.0 - SPEC3.d_safe_m


def test_over_a_low_fire_is_cheaper_than_around():
    """A low fire on the straight line: passing over costs less than passing around, which
    is what the same fire taller than the band leaves."""
    rect = Rect(450.0, 450.0, 250.0, 250.0)
    x0 = np.array([150.0, 150.0, 50.0, 5.0, 5.0, 0.0])
    low = FastSystem2(SPEC3).plan(x0, (Prism.cuboid(rect, 0.0, 30.8),))
    tall = FastSystem2(SPEC3).plan(x0, (Prism.cuboid(rect, 0.0, SPEC3.above_ceiling_m),))
    assert low.ok and tall.ok
    assert tall.info.get("reduction") is True and "reduction" not in low.info
    assert low.cost is not None and tall.cost is not None and low.cost < tall.cost
    assert low.states[:, 2].max() >= 30.8 + SPEC3.clearance_m - 1e-6


# ------------------------------------------------------------------ the reduction
def _check_tall(n: int, seed: int, steps: int = 3) -> None:
    """Fires taller than the band, the UAV at G_o's altitude at rest vertically: every 3-D
    plan is the 2-D plan, bit for bit (a few consecutive plans: the previous one seeds the
    next)."""
    rng = np.random.default_rng(seed)
    p3, p2 = FastSystem2(SPEC3), FastSystem2(SPEC2)
    for _ in range(n):
        x0, prisms, u_prev = _random_instance(rng, low=False)
        p3.reset()
        p2.reset()
        x2 = np.array([x0[0], x0[1], x0[3], x0[4]])
        u2 = u_prev[:2]
        for _ in range(steps):
            a = p3.plan(x0, prisms, Objective.MISSION_TIME, u_prev)
            b = p2.plan(x2, [p.base for p in prisms], Objective.MISSION_TIME, u2)
            assert a.status == b.status and a.message == b.message
            if not b.ok:
                break
            assert np.array_equal(a.states, np.array([lift_state(s, 50.0) for s in b.states]))
            assert np.array_equal(a.controls[:, :2], b.controls)
            assert np.all(a.controls[:, 2] == 0.0) and a.cost == b.cost
            x2, u2 = b.states[1], b.controls[0]
            x0, u_prev = a.states[1], a.controls[0]


def test_tall_fires_give_the_2d_plans():
    _check_tall(12, 5)


@pytest.mark.slow
def test_tall_fires_give_the_2d_plans_200():
    _check_tall(200, 6, steps=1)
    _check_tall(40, 7, steps=4)


# ------------------------------------------------------------------ refusals and registry
def test_registry_and_refusals_by_name():
    assert isinstance(build_planner(2, SPEC3, "fast"), FastSystem2)
    assert build_planner(2, SPEC3, "thorough").method == "thorough"
    assert isinstance(build_planner(2, SPEC3, "fast", risk=True), RiskSystem2)
    assert build_planner(2, SPEC3, "certified").method == "certified"  # test_certify3.py
    norm = dataclasses.replace(SPEC3, dynamics=DynamicsParams(dim=3, speed_limit="norm"))
    with pytest.raises(ValueError, match="speed_limit = 'axis' only"):
        FastSystem2(norm)
    with pytest.raises(ValueError, match="'fast\\+exact' plans in 3-D under speed_limit = "
                                         "'axis' only"):
        AnytimeSystem2(norm)  # before its worker starts


def test_3d_request_checks():
    """Shapes, the band at p_(t+1|t), a start within d_safe of a prism."""
    planner = FastSystem2(SPEC3, System2Params(horizon=20))
    bad = planner.plan(np.zeros(4), ())
    assert bad.status is PlanStatus.INVALID_INPUT and "6 finite numbers" in bad.message
    up = planner.plan(np.array([100.0, 100.0, 119.0, 0.0, 0.0, 12.0]), ())
    assert up.status is PlanStatus.INFEASIBLE and "band" in up.message
    fire = Prism.cuboid(Rect(100.0, 100.0, 50.0, 50.0), 0.0, 30.0)
    near = planner.plan(np.array([100.0, 100.0, 45.0, 0.0, 0.0, 0.0]), (fire,))
    assert near.status is PlanStatus.INVALID_INPUT and "prism 0" in near.message
    above = planner.plan(np.array([100.0, 100.0, 80.0, 0.0, 0.0, 0.0]), (fire,))
    assert above.ok and above.states.shape == (21, 6)


# ------------------------------------------------------------------ risk zones in 3-D
def _zones(T: int) -> list[tuple[Polytope, np.ndarray]]:
    """Two zones of the ground, each at some plan steps (bool masks over τ = 0..T)."""
    out = []
    for rect, steps in ((Rect(330.0, 300.0, 120.0, 120.0), range(5, 40)),
                        (Rect(520.0, 560.0, 150.0, 90.0), range(20, T + 1))):
        mask = np.zeros(T + 1, dtype=bool)
        mask[list(steps)] = True
        out.append((rect.polytope(), mask))
    return out


def _zone_margin(plan_states: np.ndarray, zones: list[tuple[Polytope, np.ndarray]]) -> float:
    """The least planar margin max_l(α·p − β) of a plan's positions at each zone's steps (m)."""
    worst = np.inf
    for poly, mask in zones:
        pts = plan_states[:, :2][mask[: len(plan_states)]]
        if len(pts):
            worst = min(worst, float(np.min(np.max(pts @ poly.A.T - poly.b, axis=1))))
    return float(worst)


def test_zones_under_the_reduction_give_the_2d_plan():
    """Zones with fires taller than the band, at G_o's altitude at rest: the 2-D plan of
    ``plan_with_zones``, bit for bit."""
    T = System2Params().horizon
    zones = _zones(T)
    rect = Rect(450.0, 420.0, 200.0, 160.0)
    x3 = np.array([200.0, 180.0, 50.0, 6.0, 5.0, 0.0])
    a = FastSystem2(SPEC3).plan_with_zones(
        x3, (Prism.cuboid(rect, 0.0, SPEC3.above_ceiling_m),), Objective.MISSION_TIME, None,
        zones)
    b = FastSystem2(SPEC2).plan_with_zones(np.array([200.0, 180.0, 6.0, 5.0]),
                                           [rect.polytope()], Objective.MISSION_TIME, None,
                                           zones)
    assert a.status == b.status and b.ok
    assert np.array_equal(a.states, np.array([lift_state(s, 50.0) for s in b.states]))
    assert a.info.get("reduction") is True and a.info.get("n_zones") == b.info.get("n_zones")


def test_zones_are_kept_out_at_every_altitude_over_a_low_fire():
    """A low fire on the way and two zones: the plan (3-D method) passes verify_p2_plan and
    keeps ε from each zone in the plane at the zone's steps, whatever its altitude."""
    T = System2Params().horizon
    zones = _zones(T)
    fire = Prism.cuboid(Rect(450.0, 420.0, 200.0, 160.0), 0.0, 30.8)
    x3 = np.array([200.0, 180.0, 50.0, 6.0, 5.0, 0.0])
    plan = FastSystem2(SPEC3).plan_with_zones(x3, (fire,), Objective.MISSION_TIME, None, zones)
    assert plan.ok, plan.message
    assert "reduction" not in plan.info and plan.info.get("n_zones") == 2
    assert verify_p2_plan(plan.states, plan.controls, (fire,), DYN3, SPEC3.clearance_m,
                          SPEC3.d_safe_m, SPEC3.area_size_m, band=BAND).ok
    assert _zone_margin(plan.states, zones) >= SPEC3.clearance_m - 1e-6
    free = FastSystem2(SPEC3).plan(x3, (fire,))
    assert free.ok and _zone_margin(free.states, zones) < SPEC3.clearance_m  # they bite
