"""Exact System 2, Problem (P2): short horizons (T = 15-20) and 1-3 hulls keep SCIP fast."""

from __future__ import annotations

import math

import cvxpy as cp
import numpy as np
import pytest

from dualpilot.model.dynamics import DynamicsParams, rollout, transition_matrices
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.plan import Objective, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2 import exact as s2mod
from dualpilot.system2.exact import ExactSystem2
from dualpilot.system2.miqp import gurobi_available
from dualpilot.system2.problem import System2Params, p2_cost
from dualpilot.system2.slots import face_inflated, outer_simplify
from dualpilot.verify import Verdict

SPEC = MissionSpec()
GOAL = SPEC.goal
DYN = DynamicsParams()
EPS = SPEC.clearance_m
T = 20


def params(**kw: object) -> System2Params:
    base: dict[str, object] = {"horizon": T, "max_hulls": 3, "max_faces": 6, "time_limit_s": 60.0}
    base.update(kw)
    return System2Params(**base)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def planner() -> ExactSystem2:
    return ExactSystem2(SPEC, params())


def hover(x: float, y: float) -> np.ndarray:
    return np.array([x, y, 0.0, 0.0])


# A 100 m square on the diagonal from (100, 100) to the goal: the straight line is blocked.
BLOCK = Rect(260.0, 260.0, 100.0, 100.0).polytope()


def assert_dynamics_and_bounds(plan, x0) -> None:
    assert plan.states.shape == (T + 1, 4) and plan.controls.shape == (T, 2)
    assert plan.states[0] == pytest.approx(x0)
    assert np.allclose(plan.states, rollout(x0, plan.controls, DYN), atol=1e-9)  # Eq. (1)
    assert np.all(np.abs(plan.controls) <= DYN.u_max_n + 1e-9)
    assert np.all(np.abs(plan.states[1:, 2:]) <= DYN.v_max_mps + 1e-4)
    assert np.all(plan.states[:, :2] >= -1e-6) and np.all(plan.states[:, :2] <= 1000 + 1e-6)


def test_blocked_line_plan_goes_around_and_keeps_the_disjunction(planner):
    x0 = hover(100.0, 100.0)
    assert BLOCK.segment_intersects(x0[:2], GOAL.center)  # the straight line is blocked
    plan = planner.plan(x0, (BLOCK,))
    assert plan.ok, plan.message
    assert plan.system == 2 and plan.objective is Objective.MISSION_TIME
    assert plan.info["solver"] == "SCIP" and plan.info["optimal"] is True
    assert plan.info["n_hulls"] == 1
    assert_dynamics_and_bounds(plan, x0)
    # Eq. (P2_3)-(P2_4) by hand: some face of the hull is at least ε away, for τ = 1..T
    pos = plan.states[1:, :2]
    margins = np.max(pos @ BLOCK.A.T - BLOCK.b, axis=1)
    assert np.all(margins >= EPS - 0.05)
    # every segment is clear of d_safe: independent dense sampling
    t = np.linspace(0.0, 1.0, 50)[:, None]
    for p0, p1 in zip(plan.states[:-1, :2], plan.states[1:, :2], strict=True):
        assert min(BLOCK.distance(p) for p in p0 + t * (p1 - p0)) >= 20.0
    # it went around: it is beside the hull (x or y in [210, 310]) on one side of it
    beside = [(px >= 335.0 - 0.05 and 210.0 <= py <= 310.0)
              or (py >= 335.0 - 0.05 and 210.0 <= px <= 310.0) for px, py in pos]
    assert any(beside)
    free = planner.plan(x0, ())
    assert free.ok and free.cost < plan.cost


def test_cost_is_eq_s2_and_matches_the_solver_objective(planner):
    x0 = np.array([100.0, 100.0, 3.0, -2.0])
    u_prev = np.array([1.0, -2.0])
    for objective in Objective:
        plan = planner.plan(x0, (BLOCK,), objective, prev_control=u_prev)
        assert plan.ok, plan.message
        kappa = System2Params().kappa(objective)
        assert plan.cost == pytest.approx(
            p2_cost(plan.states, plan.controls, GOAL.center, kappa, u_prev)
        )
        assert plan.cost == pytest.approx(plan.info["solver_objective"], rel=1e-6)


def test_no_hulls_first_control_saturates_toward_the_goal(planner):
    plan = planner.plan(hover(50.0, 50.0), ())  # κ2 = 0.001: time dominates
    assert plan.ok
    assert plan.controls[0] == pytest.approx([DYN.u_max_n, DYN.u_max_n], abs=1e-3)
    plan = planner.plan(hover(950.0, 500.0), ())  # goal up-left
    assert plan.controls[0] == pytest.approx([-DYN.u_max_n, DYN.u_max_n], abs=1e-3)


def independent_qp(x0, objective, u_prev) -> float:
    """(P2) without hulls as a plain convex QP, solved by Clarabel."""
    phi, gamma = transition_matrices(DYN)
    k1, k2 = System2Params().kappa(objective)
    x = cp.Variable((T + 1, 4))
    u = cp.Variable((T, 2))
    cons = [x[0] == x0, cp.abs(u) <= 7.5, cp.abs(x[1:, 2:]) <= 15.0,
            x[1:, :2] >= 0.0, x[1:, :2] <= 1000.0]
    cons += [x[k + 1] == phi @ x[k] + gamma @ u[k] for k in range(T)]
    du = cp.vstack([u[0] - u_prev, u[1:] - u[:-1]])
    obj = k1 * cp.sum_squares(x[1:, :2] - np.ones((T, 1)) @ GOAL.center[None, :])
    prob = cp.Problem(cp.Minimize(obj + k2 * cp.sum_squares(du)), cons)
    prob.solve(solver=cp.CLARABEL)
    return float(prob.value)


@pytest.mark.parametrize("objective", list(Objective))
def test_no_hulls_matches_an_independent_qp(planner, objective):
    x0 = np.array([300.0, 200.0, -4.0, 6.0])
    u_prev = np.array([-3.0, 2.0])
    plan = planner.plan(x0, (), objective, prev_control=u_prev)
    assert plan.ok
    assert plan.cost == pytest.approx(independent_qp(x0, objective, u_prev), rel=1e-5)


def test_resolve_reuses_the_compiled_problem(planner):
    prob = planner.problem
    a = planner.plan(hover(100.0, 100.0), (BLOCK,))
    b = planner.plan(hover(100.0, 400.0), (Rect(300.0, 600.0, 120.0, 80.0).polytope(),))
    assert a.ok and b.ok
    assert planner.problem is prob
    assert not np.allclose(a.states, b.states)
    assert b.states[0] == pytest.approx(hover(100.0, 400.0))


def test_time_plan_gets_closer_and_energy_plan_is_smoother(planner):
    x0 = np.array([100.0, 100.0, 5.0, 0.0])
    fast = planner.plan(x0, (BLOCK,), Objective.MISSION_TIME)
    smooth = planner.plan(x0, (BLOCK,), Objective.ENERGY)
    assert fast.ok and smooth.ok and smooth.objective is Objective.ENERGY

    def energy(plan):
        return float(np.sum(np.diff(np.vstack([np.zeros(2), plan.controls]), axis=0) ** 2))

    def final_gap(plan):
        return float(np.linalg.norm(plan.states[-1, :2] - GOAL.center))

    assert final_gap(fast) < final_gap(smooth)
    assert energy(smooth) < energy(fast)


def test_default_slots_and_a_many_faced_hull_are_handled():
    planner = ExactSystem2(SPEC, System2Params(horizon=15))  # 10 hulls × 12 faces
    ang = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    disc = Polytope.from_vertices(np.column_stack([300 + 60 * np.cos(ang),
                                                   250 + 60 * np.sin(ang)]))
    assert disc.n_faces == 24
    x0 = hover(150.0, 150.0)
    plan = planner.plan(x0, (disc, BLOCK))
    assert plan.ok, plan.message
    assert plan.info["simplified_hulls"] == [0] and plan.info["n_hulls"] == 2
    # verified against the original hulls
    assert s2mod.verify_trajectory(plan.states, plan.controls, (disc, BLOCK), DYN, 20.0).ok


def test_outer_simplify_is_conservative():
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(200, 2)) * [80.0, 40.0] + [500.0, 500.0]
    poly = Polytope.from_vertices(pts)
    assert poly.n_faces > 8
    simple = outer_simplify(poly, 6)
    assert simple.n_faces <= 6
    assert all(simple.contains(v, margin=1e-6) for v in poly.vertices)
    assert outer_simplify(BLOCK, 6) is not None and outer_simplify(BLOCK, 6).n_faces == 4


def test_face_inflated_square_by_hand():
    big = face_inflated(Rect(0.0, 0.0, 2.0, 2.0).polytope(), 0.5)
    assert np.sort(np.abs(big.vertices).ravel()) == pytest.approx(np.full(8, 1.5))


def test_face_inflated_is_the_halfspace_intersection():
    # a 0.1 m chamfer at (2, 2): pushed out, its edge grows (outward offsets never drop faces)
    poly = Polytope.from_vertices(np.array([[0, 0], [2, 0], [2, 1.9], [1.9, 2], [0, 2]]))
    big = face_inflated(poly, 1.0)
    assert big.n_faces == 5
    pts = np.random.default_rng(0).uniform(-2.0, 4.0, size=(2000, 2))
    for p in pts:
        assert big.contains(p, margin=1e-9) == bool(np.all(poly.A @ p <= poly.b + 1.0 + 1e-9))


def test_unreachable_hulls_are_dropped_exactly(planner):
    # T = 20 at 15 m/s per axis reaches < 420 m: a hull 700 m away cannot matter
    far = Rect(800.0, 150.0, 100.0, 100.0).polytope()
    x0 = hover(50.0, 50.0)
    plan = planner.plan(x0, (far,))
    free = planner.plan(x0, ())
    assert plan.ok and plan.info["n_hulls"] == 0 and plan.info["n_hulls_input"] == 1
    assert plan.cost == pytest.approx(free.cost, rel=1e-6)


def test_too_many_reachable_hulls_is_reported():
    planner = ExactSystem2(SPEC, params(horizon=15, max_hulls=1))
    hulls = (BLOCK, Rect(150.0, 350.0, 60.0, 60.0).polytope())
    plan = planner.plan(hover(100.0, 100.0), hulls)
    assert plan.status is PlanStatus.INVALID_INPUT and "max_hulls" in plan.message


def test_infeasible_by_construction_and_by_solver(planner):
    wall = Rect(200.0, 500.0, 200.0, 1200.0).polytope()  # x in [100, 300], whole height
    # x_{t+1|t} = (80, 500) is fixed by the velocity and lies within ε of the wall
    plan = planner.plan(np.array([70.0, 500.0, 10.0, 0.0]), (wall,))
    assert plan.status is PlanStatus.INFEASIBLE and "fixed by the current velocity" in plan.message
    assert "solver" not in plan.info
    # x_{t+1|t} = (73, 500) is fine but the UAV cannot brake: x_{t+2|t} ≥ 77.9 > 100 − ε
    plan = planner.plan(np.array([58.0, 500.0, 15.0, 0.0]), (wall,))
    assert plan.status is PlanStatus.INFEASIBLE, plan.message
    assert plan.info["solver_status"] == cp.INFEASIBLE
    assert plan.states.shape == (0, 4) and not plan.ok


def test_invalid_inputs(planner):
    assert planner.plan(np.array([np.nan, 0, 0, 0]), ()).status is PlanStatus.INVALID_INPUT
    assert planner.plan(np.zeros(3), ()).status is PlanStatus.INVALID_INPUT
    bad_u = planner.plan(hover(50, 50), (), prev_control=np.array([np.inf, 0.0]))
    assert bad_u.status is PlanStatus.INVALID_INPUT
    inside = planner.plan(hover(260.0, 260.0), (BLOCK,))
    assert inside.status is PlanStatus.INVALID_INPUT and "d_safe" in inside.message
    near = planner.plan(hover(260.0, 325.0), (BLOCK,))  # 15 m from the hull
    assert near.status is PlanStatus.INVALID_INPUT


def test_bad_construction():
    with pytest.raises(ValueError, match="goal .* outside"):
        ExactSystem2(MissionSpec(goal=Rect(990.0, 500.0, 100.0, 100.0)), params())
    with pytest.raises(ValueError, match="horizon"):
        ExactSystem2(SPEC, System2Params(horizon=0))
    with pytest.raises(ValueError, match="solver"):
        ExactSystem2(SPEC, params(), solver="CPLEX")
    with pytest.raises(ValueError, match="3-D under speed_limit = 'axis' only"):
        ExactSystem2(MissionSpec(dynamics=DynamicsParams(dim=3, speed_limit="norm")), params())
    with pytest.raises(ValueError, match="max_faces"):
        outer_simplify(BLOCK, 3)
    if not gurobi_available():
        with pytest.raises(ValueError, match="gurobipy"):
            ExactSystem2(SPEC, params(), solver="GUROBI")


def test_solver_crash_is_an_error_plan(monkeypatch):
    planner = ExactSystem2(SPEC, params(horizon=15))

    def boom(*args, **kwargs):
        raise RuntimeError("simulated crash")

    monkeypatch.setattr(planner.problem, "get_problem_data", boom)
    plan = planner.plan(hover(100.0, 100.0), (BLOCK,))
    assert plan.status is PlanStatus.ERROR and "simulated crash" in plan.message


def test_a_plan_failing_verification_is_unsafe_never_ok(planner, monkeypatch):
    monkeypatch.setattr(s2mod, "verify_trajectory",
                        lambda *a, **k: Verdict(False, "clearance 3.00 m < 20.0 m", 3.0))
    plan = planner.plan(hover(100.0, 100.0), (BLOCK,))
    assert plan.status is PlanStatus.UNSAFE and "failed verification" in plan.message
    assert plan.states.shape == (0, 4)


def test_time_limit_gives_timeout_or_a_verified_incumbent():
    planner = ExactSystem2(SPEC, params(horizon=20, time_limit_s=1e-3))
    plan = planner.plan(hover(100.0, 100.0), (BLOCK,))
    assert plan.status in (PlanStatus.TIMEOUT, PlanStatus.OK)
    if plan.ok:  # an incumbent is kept only because it verified
        assert plan.info["native_status"] == "timelimit" and plan.info["optimal"] is False
    assert math.isfinite(plan.compute_time_s)


@pytest.mark.slow  # a process of its own (make test-fast leaves it out)
def test_isolated_worker_matches_in_process_and_survives_a_kill():
    x0 = hover(100.0, 100.0)
    inproc = ExactSystem2(SPEC, params(horizon=15)).plan(x0, (BLOCK,))
    with ExactSystem2(SPEC, params(horizon=15), isolate=True) as planner:
        plan = planner.plan(x0, (BLOCK,))
        assert plan.ok, plan.message
        assert plan.cost == pytest.approx(inproc.cost, rel=1e-6)
        worker = planner._worker
        assert worker is not None and worker._proc is not None
        worker._proc.kill()  # a crashed solver process is restarted on the next plan
        worker._proc.join()
        again = planner.plan(x0, (BLOCK,), Objective.ENERGY)
        assert again.ok, again.message


def test_isolated_worker_hard_deadline_gives_timeout():
    with ExactSystem2(SPEC, params(horizon=15), isolate=True, hard_timeout_s=0.01) as planner:
        plan = planner.plan(hover(100.0, 100.0), (BLOCK,))
        assert plan.status is PlanStatus.TIMEOUT and "hard deadline" in plan.message
        assert planner._worker is not None and planner._worker.pid is None  # killed
