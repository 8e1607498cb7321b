"""System 2 with a certificate: the bound on (P2), its soundness, the exact method.

Hand values: with T = 2, ΔT = m = 1, ζ = 0 and v_t = u_{t|t} = 0, p_{t+1|t} = p_t,
u_1 = p_2 − p_1 and u_2 is free (p_3 is virtual), so u_2 = u_1 and Eq. (S2) is
κ1‖p_1 − G‖² + κ1‖p_2 − G‖² + κ2‖p_2 − p_1‖² = f* + (κ1 + κ2)‖p_2 − p*‖² with
p* = (κ1 G + κ2 p_1)/(κ1 + κ2) and f* = κ1‖p_1 − G‖² + κ1κ2/(κ1 + κ2)‖G − p_1‖². With
p* inside a hull's ε-inflation the optimum puts p_2 on the nearest face: f* + (κ1 + κ2)d².
"""

from __future__ import annotations

import math

import clarabel
import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from dualpilot.evaluation.instances import SPEC, check_plan, make_instance
from dualpilot.evaluation.soundness import check
from dualpilot.model.dynamics import DynamicsParams, rollout
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.plan import Objective, Plan, PlanStatus, certified_gap
from dualpilot.spec import MissionSpec
from dualpilot.system2.certify.bnb import CertifyParams
from dualpilot.system2.certify.duality import Cones, lagrangian_bound, proves_infeasible
from dualpilot.system2.certify.model import controls, maps, offsets, positions
from dualpilot.system2.certify.pieces import cover
from dualpilot.system2.certify.planner import CertifiedSystem2, relaxation_of
from dualpilot.system2.fast.qp import P2Qp, QpParams
from dualpilot.system2.problem import System2Params, p2_cost


def test_certified_gap_by_hand() -> None:
    assert certified_gap(110.0, 100.0) == pytest.approx(0.1)
    assert certified_gap(100.0, 100.0) == 0.0
    assert certified_gap(100.0, 100.0 + 1e-9) == 0.0  # a bound at the cost: proven optimal
    assert certified_gap(100.0, 0.0) == math.inf
    assert certified_gap(None, 1.0) == math.inf and certified_gap(1.0, None) == math.inf
    assert certified_gap(1.0, -math.inf) == math.inf
    plan = Plan(2, PlanStatus.OK, np.zeros((1, 4)), np.zeros((0, 2)), 0.0, cost=3.0)
    assert plan.certified_gap is None
    assert Plan(2, PlanStatus.OK, np.zeros((1, 4)), np.zeros((0, 2)), 0.0, cost=3.0,
                bound=2.0).certified_gap == pytest.approx(0.5)


def test_position_model_is_eq1_and_eq_s2() -> None:
    """z ↦ controls, rolled out by Eq. (1), gives back the positions; the cost is Eq. (S2)."""
    rng = np.random.default_rng(0)
    T, dyn = 12, SPEC.dynamics
    mp = maps(T, dyn)
    x0, u_prev = np.array([300.0, 400.0, 5.0, -3.0]), np.array([1.0, -2.0])
    off = offsets(mp, x0, u_prev)
    z = (x0[:2] + 15.0 * np.cumsum(rng.uniform(-1, 1, (T, 2)), axis=0)).ravel() / mp.scale
    u = controls(mp, z, off)
    states = rollout(x0, u, dyn)
    assert np.allclose(states[1:, :2], positions(mp, z, off.p1)[:T], atol=1e-9)
    goal, kappa = np.array([900.0, 900.0]), (1.0, 0.001)
    du = mp.D @ z + off.du
    by_maps = (kappa[0] * np.sum((positions(mp, z, off.p1)[:T] - goal) ** 2)
               + kappa[1] * float(du @ du))
    assert by_maps == pytest.approx(p2_cost(states, u, goal, kappa, u_prev), rel=1e-12)


@pytest.mark.parametrize("objective", list(Objective))
def test_plain_relaxation_bound_is_the_qp_optimum(objective: Objective) -> None:
    """No disjunction kept: the bound is the convex QP's optimum (the fast method's solver,
    without its safety margins), never above it and a few parts in a million below."""
    inst = make_instance(3, 1, 4)
    params = System2Params()
    rel = relaxation_of(SPEC, params, inst.state, inst.hulls, objective, inst.prev_control,
                        reach=False)
    res = rel.solve({}, {})
    qp = P2Qp(params.horizon, SPEC.dynamics, SPEC.area_size_m,
              QpParams(v_margin=0.0, u_margin=0.0, area_margin=0.0, tol=1e-10))
    free = qp.solve(inst.state, inst.prev_control, SPEC.goal.center, params.kappa(objective),
                    np.zeros(0, int), np.zeros((0, 2)), np.zeros(0), confirm=True)
    assert free.ok
    assert res.bound <= free.objective * (1 + 1e-9)
    # the certified bound pays for Clarabel's residuals over the reach boxes: a few 1e-6
    assert res.bound == pytest.approx(free.objective, rel=2e-5)


def _small_qp() -> tuple[sp.csc_matrix, np.ndarray, sp.csc_matrix, np.ndarray, Cones]:
    """min ½‖x‖² − x₁ − 2x₂ s.t. x₁ + x₂ ≤ 1, x ≥ 0: optimum at (0, 1), value −1.5."""
    P = sp.csc_matrix(np.eye(2))
    q = np.array([-1.0, -2.0])
    A = sp.csc_matrix(np.array([[1.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]))
    b = np.array([1.0, 0.0, 0.0])
    return P, q, A, b, Cones(0, 3, ())


def test_lagrangian_bound_holds_for_any_dual() -> None:
    P, q, A, b, cones = _small_qp()
    lo, hi = np.full(2, -10.0), np.full(2, 10.0)
    settings_ = clarabel.DefaultSettings()
    settings_.verbose = False
    sol = clarabel.DefaultSolver(sp.triu(P).tocsc(), q, A, b, [clarabel.NonnegativeConeT(3)],
                                 settings_).solve()
    x, y = np.array(sol.x), np.array(sol.z)
    exact = lagrangian_bound(P, q, 0.0, A, b, cones, x, y, lo, hi)
    assert -1.5 - 1e-6 <= exact <= -1.5
    rng = np.random.default_rng(1)
    for _ in range(200):  # any x̄, any y (negative entries are projected away): still below
        xb, yb = rng.normal(0, 3, 2), rng.normal(0, 3, 3)
        assert lagrangian_bound(P, q, 0.0, A, b, cones, xb, yb, lo, hi) <= -1.5 + 1e-12


def test_infeasibility_needs_a_certificate() -> None:
    """x ≥ 1 and x ≤ 0 in the box [−5, 5]: y = (1, 1) proves it, y = 0 does not."""
    A = sp.csc_matrix(np.array([[-1.0], [1.0]]))
    b = np.array([-1.0, 0.0])
    cones = Cones(0, 2, ())
    lo, hi = np.array([-5.0]), np.array([5.0])
    assert proves_infeasible(A, b, cones, np.array([1.0, 1.0]), lo, hi)
    assert not proves_infeasible(A, b, cones, np.zeros(2), lo, hi)
    # feasible rows (x ≥ 1, x ≤ 2) are never proved infeasible, whatever y
    b2 = np.array([-1.0, 2.0])
    rng = np.random.default_rng(2)
    assert not any(proves_infeasible(A, b2, cones, rng.normal(0, 5, 2), lo, hi)
                   for _ in range(200))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6))
def test_pieces_cover_exactly_the_free_positions(seed: int) -> None:
    """Every free point of the box lies in a piece; every point of a piece is free."""
    rng = np.random.default_rng(seed)
    lo = rng.uniform(0, 300, 2)
    hi = lo + rng.uniform(50, 400, 2)
    hulls = [Rect(*rng.uniform(0, 600, 2), *rng.uniform(30, 200, 2)).polytope()
             for _ in range(int(rng.integers(1, 4)))]
    eps = 25.0
    fixed = np.zeros((0, 3))
    if rng.random() < 0.5:  # a fixed face: one hull's face, as a node of the search fixes
        h = hulls[0]
        k = int(rng.integers(h.n_faces))
        fixed = np.array([[*h.A[k], h.b[k] + eps]])
    pieces = cover(lo, hi, fixed, hulls, eps, 10**6)
    assert pieces is not None
    pts = rng.uniform(lo, hi, (400, 2))

    def free(p: np.ndarray) -> bool:
        ok_fixed = all(row[:2] @ p >= row[2] for row in fixed)
        return ok_fixed and all(np.max(h.A @ p - h.b) >= eps for h in hulls)

    def in_piece(p: np.ndarray, piece: np.ndarray) -> bool:
        return bool(np.all(piece[:, :2] @ p - piece[:, 2] >= -1e-6))

    for p in pts:
        inside_any = any(in_piece(p, pc) for pc in pieces)
        if free(p):
            assert inside_any
        if inside_any:
            assert all(np.max(h.A @ p - h.b) >= eps - 1e-6 for h in hulls)


# --------------------------------------------------------------- hand values
HAND_SPEC = MissionSpec(start=(100.0, 100.0), goal=Rect(150.0, 100.0, 10.0, 10.0),
                        area_size_m=1000.0, d_safe_m=1.0, clearance_m=2.0,
                        dynamics=DynamicsParams(dt_s=1.0, zeta=0.0, mass_kg=1.0,
                                                u_max_n=100.0, v_max_mps=100.0))
HAND_PARAMS = System2Params(horizon=2)
P1 = np.array([100.0, 100.0])
G = np.array([150.0, 100.0])


def _hand_optimum(d: float) -> float:
    """f* + (κ1 + κ2) d² of the module docstring (mission time: κ = (1, 0.001))."""
    k1, k2 = HAND_PARAMS.kappa(Objective.MISSION_TIME)
    g2 = float((G - P1) @ (G - P1))
    return k1 * g2 + k1 * k2 / (k1 + k2) * g2 + (k1 + k2) * d * d


def _certified(hull: Polytope) -> Plan:
    planner = CertifiedSystem2(HAND_SPEC, HAND_PARAMS, CertifyParams(tolerance=0.0))
    return planner.plan(np.array([*P1, 0.0, 0.0]), (hull,), Objective.MISSION_TIME,
                        np.zeros(2))


def test_one_hull_bound_and_cost_are_the_hand_value() -> None:
    k1, k2 = HAND_PARAMS.kappa(Objective.MISSION_TIME)
    p_star = (k1 * G + k2 * P1) / (k1 + k2)
    hull = Rect(157.5, 105.0, 25.0, 50.0).polytope()  # x 145..170, y 80..130
    d = p_star[0] - (145.0 - 2.0)  # the west face (ε = 2 m) is the nearest
    plan = _certified(hull)
    assert plan.ok and plan.bound is not None
    assert plan.cost == pytest.approx(_hand_optimum(d), rel=1e-7)
    assert plan.bound == pytest.approx(_hand_optimum(d), rel=1e-6)
    assert plan.cost is not None and plan.bound <= plan.cost
    assert plan.states[2, :2] == pytest.approx([143.0, p_star[1]], abs=1e-2)


def test_symmetric_detour_bound_and_cost_are_the_hand_value() -> None:
    """p* at the centre of a square: four mirror-image optima, all at d = half side + ε."""
    k1, k2 = HAND_PARAMS.kappa(Objective.MISSION_TIME)
    p_star = (k1 * G + k2 * P1) / (k1 + k2)
    hull = Rect(float(p_star[0]), float(p_star[1]), 20.0, 20.0).polytope()
    plan = _certified(hull)
    assert plan.ok and plan.bound is not None
    assert plan.cost == pytest.approx(_hand_optimum(12.0), rel=1e-7)
    assert plan.bound == pytest.approx(_hand_optimum(12.0), rel=1e-6)
    assert isinstance(plan.info["certify_nodes"], int) and plan.info["certify_nodes"] >= 1


# --------------------------------------------------------------- soundness
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10**7))
def test_bound_never_exceeds_scips_optimum(seed: int) -> None:
    """Random small instances (T = 3–8, one or two rectangles) against SCIP: the bound is
    at most SCIP's verified cost, and where SCIP proves the optimum the certified gap is
    at least the true gap. ``benchmarks/certify_soundness.py`` runs thousands."""
    c = check(seed, scip_time_limit_s=5.0)
    assert c.sound, c


# --------------------------------------------------------------- the method
def test_certified_plan_on_a_paper_instance() -> None:
    inst = make_instance(12, 1, 3)  # G inside a hull: the plain relaxation is 60 % low
    # ~0.2 s of CPU on an idle machine; the budget is wall time, generous for a starved test
    planner = CertifiedSystem2(SPEC, System2Params(), CertifyParams(time_budget_s=30.0))
    plan = planner.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
    ok, why = check_plan(plan, inst)
    assert ok, why
    assert plan.bound is not None and plan.cost is not None and plan.bound <= plan.cost
    assert plan.certified_gap is not None and plan.certified_gap <= 0.01
    root = plan.info["certify_root_bound"]
    assert isinstance(root, float) and root <= plan.bound


@pytest.mark.parametrize("budget_s", [1e-3, 1.0])
def test_the_search_trace_never_overstates_the_bound(budget_s: float) -> None:
    """The bound at every node of the trace is at most the final one and never falls: the
    bench reads the gap at shorter budgets from it. Also when the budget stops the first
    relaxation early, whose bound (its last iterate's) may be negative."""
    inst = make_instance(8, 1, 9)  # a search that branches
    planner = CertifiedSystem2(SPEC, System2Params(), CertifyParams(time_budget_s=budget_s))
    plan = planner.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
    bounds = [b for _, b, _ in planner.trace]
    assert plan.bound is not None and bounds
    assert len(bounds) >= 2 or budget_s < 1.0
    slack = 1e-12 * abs(plan.bound) + 1e-9
    assert all(b <= plan.bound + slack for b in bounds)
    assert all(b2 >= b1 - 1e-9 * abs(b1) for b1, b2 in zip(bounds[:-1], bounds[1:], strict=True))
    times = [t for t, _, _ in planner.trace]
    assert times == sorted(times)


def test_proven_infeasible_when_no_trajectory_can_stop() -> None:
    """At 15 m/s towards a wall whose ε-band starts 2 m past p_{t+1|t}: braking as hard as
    U allows still moves 4.86 m in the next step, so (P2) has no solution."""
    wall = Rect(600.0, 500.0, 200.0, 600.0).polytope()  # west face x = 500
    x0 = np.array([500.0 - 25.0 - 2.0 - 15.0, 500.0, 15.0, 0.0])
    planner = CertifiedSystem2(SPEC, System2Params())
    plan = planner.plan(x0, (wall,), Objective.MISSION_TIME, np.zeros(2))
    assert plan.status is PlanStatus.INFEASIBLE, plan.message
