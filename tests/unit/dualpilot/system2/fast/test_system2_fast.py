"""The fast System 2: agreement with the exact MIQP, verification, and a solver that fails."""

import dataclasses
import json
import os
import time

import numpy as np
import pytest

from dualpilot.evaluation.bench import run_system2
from dualpilot.evaluation.instances import GOAL, SPEC, make_instance
from dualpilot.model.dynamics import DynamicsParams, rollout, transition_matrices
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.planners import (
    BUILTIN,
    build_planner,
    build_planners,
    method_names,
    risk_aware_names,
)
from dualpilot.system2.anytime import AnytimeSystem2
from dualpilot.system2.fast.cfs import KeepOuts
from dualpilot.system2.fast.geometry import Inflated, homotopy_paths
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.fast.qp import P2Qp, QpParams
from dualpilot.system2.problem import System2Params, verify_p2_plan
from dualpilot.system2.worker import Worker

DYN = DynamicsParams()
SMALL = System2Params(horizon=20, time_limit_s=60.0)


# ----------------------------------------------------------- fast vs exact
@pytest.mark.timeout(240)
def test_fast_matches_exact_on_small_instances():
    """T = 20, 3 hulls: SCIP proves optimality quickly; the fast plan is within the stated gap."""
    from dualpilot.system2.exact import ExactSystem2

    fast = FastSystem2(SPEC, SMALL)
    exact = ExactSystem2(SPEC, SMALL)
    gaps, homotopies = [], []
    for index in (0, 4, 6):
        inst = make_instance(index, 5, 3)
        a = fast.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
        b = exact.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
        assert a.ok and b.ok and b.info["optimal"]
        assert a.cost is not None and b.cost is not None
        gaps.append((a.cost - b.cost) / b.cost)
        homotopies.append(a.info["homotopy"])
    # the hulls matter on these instances (the unconstrained optimum is not feasible)
    assert all(h != "relaxation" for h in homotopies)
    assert max(gaps) <= 0.03
    assert float(np.median(gaps)) <= 0.01
    # and no better than the optimum beyond the solver's tolerances
    assert min(gaps) >= -1e-4


def test_unconstrained_optimum_is_returned_as_optimal():
    fast = FastSystem2(SPEC, SMALL)
    far = (Rect(100.0, 900.0, 100.0, 100.0).polytope(),)
    plan = fast.plan(np.array([300.0, 300.0, 5.0, 5.0]), far, Objective.MISSION_TIME)
    assert plan.ok and plan.info["homotopy"] == "relaxation" and plan.info["optimal"]
    assert plan.info["bound_gap"] == pytest.approx(0.0, abs=1e-9)


# ------------------------------------------------------------ verification
def _square() -> Polytope:
    return Rect(50.0, 50.0, 100.0, 100.0).polytope()  # [0, 100]²


def test_verification_rejects_a_segment_that_clips_a_corner():
    # x0 at the origin moving at (15, 15) m/s: the segment to x1 = (15, 15) passes
    # 18 m from the corner (20.2, −5.2) of a square below it, while both
    # samples are 20.9 m from it (a check of the samples alone would pass).
    corner = np.array([7.5, 7.5]) + 18.0 * np.array([1.0, -1.0]) / np.sqrt(2.0)
    square = Rect(corner[0] + 50.0, corner[1] - 50.0, 100.0, 100.0).polytope()
    x0 = np.array([0.0, 0.0, 15.0, 15.0])
    controls = np.array([[-3.0, -3.0]])
    states = rollout(x0, controls, DYN)
    assert square.distance(states[0, :2]) > 20.0 and square.distance(states[1, :2]) > 20.0
    verdict = verify_p2_plan(states, controls, (square,), DYN, 0.0, SPEC.d_safe_m, None)
    assert not verdict.ok and "clearance" in verdict.reason


def test_verification_rejects_a_point_inside_the_epsilon_corner():
    # (120, 120) is 28 m from the square's corner, but only 20 m past each face:
    # Eq. (P2_3)-(P2_4) with ε = 25 m forbid it.
    x0 = np.array([120.0, 120.0 - 0.0, 0.0, 0.0])
    controls = np.zeros((1, 2))
    states = rollout(x0, controls, DYN)
    ok_clearance = verify_p2_plan(states, controls, (_square(),), DYN, 0.0, SPEC.d_safe_m,
                                  None)
    assert ok_clearance.ok
    verdict = verify_p2_plan(states, controls, (_square(),), DYN, 25.0, SPEC.d_safe_m, None)
    assert not verdict.ok and "disjunction" in verdict.reason


def test_a_plan_failing_verification_is_never_returned(monkeypatch):
    """If the solver's candidates were wrongly judged feasible, the final check still stops them."""
    fast = FastSystem2(SPEC, SMALL)
    monkeypatch.setattr(KeepOuts, "violations", lambda self, pos: np.zeros((0, 2), dtype=int))
    block = (Rect(450.0, 450.0, 150.0, 150.0).polytope(),)
    plan = fast.plan(np.array([300.0, 300.0, 10.0, 10.0]), block, Objective.MISSION_TIME)
    assert plan.status is PlanStatus.UNSAFE and len(plan.states) == 0
    assert "no verified candidate" in plan.message


def test_statuses_match_the_exact_solver():
    fast = FastSystem2(SPEC, SMALL)
    assert fast.plan(np.zeros(3), ()).status is PlanStatus.INVALID_INPUT
    sq = (_square(),)
    # x_(t+1|t) = (110, 50) lies 10 m past a face: (P2) is infeasible whatever the control
    assert fast.plan(np.array([95.0 + 30.0, 50.0, -15.0, 0.0]), sq).status \
        is PlanStatus.INFEASIBLE
    assert fast.plan(np.array([110.0, 50.0, 5.0, 0.0]), sq).status is PlanStatus.INVALID_INPUT


# ------------------------------------------------------------- components
def test_interior_point_qp_matches_clarabel():
    x0 = np.array([200.0, 150.0, 3.0, -2.0])
    u_prev = np.array([1.0, -1.0])
    tau = np.arange(5, 20)
    normals = np.tile([[-1.0, 0.0]], (len(tau), 1))  # p_x ≤ 300 for τ = 5..19
    rhs = np.full(len(tau), -300.0)
    for kappa in ((1.0, 0.001), (0.001, 1.0)):
        ipm = P2Qp(20, DYN, 1000.0, QpParams(backend="ipm"))
        clarabel = P2Qp(20, DYN, 1000.0, QpParams(backend="clarabel"))
        a = ipm.solve(x0, u_prev, GOAL.center, kappa, tau, normals, rhs)
        b = clarabel.solve(x0, u_prev, GOAL.center, kappa, tau, normals, rhs)
        assert a.ok and b.ok
        assert a.objective == pytest.approx(b.objective, rel=1e-6)
        assert np.max(a.positions[4:19, 0]) <= 300.0 + 1e-6
        # positions follow Eq. (1) under the controls
        states = rollout(x0, a.controls, DYN)
        assert states[1:, :2] == pytest.approx(a.positions[:20], abs=1e-6)


def test_homotopies_pass_a_blocking_hull_on_both_sides():
    poly = Inflated.make(Rect(500.0, 500.0, 200.0, 200.0).polytope(), 25.0)
    paths = homotopy_paths(np.array([300.0, 300.0]), np.array([700.0, 700.0]), [poly])
    assert len(paths) == 2
    turn = [float(np.sign(d[0] * 1.0 - d[1] * 1.0)) for d in (p[1] - p[0] for p in paths)]
    assert sorted(turn) == [-1.0, 1.0]  # one path passes left of the hull, one right
    lengths = [float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for p in paths]
    assert lengths[0] == pytest.approx(lengths[1], rel=0.01)
    assert min(lengths) > np.hypot(400.0, 400.0)
    for p in paths:
        for a, b in zip(p[:-1], p[1:], strict=True):
            assert poly.margin(0.5 * (a + b))[0] >= -1e-6


def test_transition_matrices_reading():
    # the QP's position-only elimination relies on Eq. (1): p_τ = p_{τ-1} + ΔT v_{τ-1}
    phi, gamma = transition_matrices(DYN)
    assert phi[0, 2] == DYN.dt_s and gamma[0, 0] == 0.0


def test_planners_by_name_from_the_registry():
    # the built-ins, each system's default first (an installed package may add more after)
    def builtin(names: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(n for n in names if n in BUILTIN)

    assert {s: builtin(method_names(s)) for s in (1, 2)} == {
        1: ("rrt", "rrt+du"), 2: ("fast", "exact", "fast+exact", "thorough", "certified")}
    assert {s: builtin(risk_aware_names(s)) for s in (1, 2)} == {1: ("rrt", "rrt+du"),
                                                                 2: ("fast",)}
    assert method_names(1)[:2] == ("rrt", "rrt+du") and method_names(2)[0] == "fast"
    with pytest.raises(ValueError, match="'exact' has no risk-aware variant"):
        build_planner(2, SPEC, "exact", risk=True)
    fast = build_planner(2, SPEC, "fast", SMALL)
    assert isinstance(fast, FastSystem2) and (fast.system, fast.method) == (2, "fast")
    thorough = build_planner(2, SPEC, "thorough")
    assert (thorough.system, thorough.method) == (2, "thorough")
    both = build_planners(SPEC)
    assert [(k, p.system, p.method) for k, p in both.items()] == [(1, 1, "rrt"), (2, 2, "fast")]
    with pytest.raises(ValueError, match="unknown System 2 method"):
        build_planner(2, SPEC, "magic")
    with pytest.raises(ValueError, match="'rrt' is a System 1 method, not System 2's"):
        build_planner(2, SPEC, "rrt")
    with pytest.raises(ValueError, match="unknown system"):
        build_planner(3, SPEC, "fast")
    with pytest.raises(TypeError, match="System2Params"):
        build_planner(1, SPEC, "rrt", SMALL)


@pytest.mark.timeout(120)
def test_exact_from_the_registry_solves_in_a_worker_process():
    exact = build_planner(2, SPEC, "exact", SMALL)
    try:
        assert exact.method == "exact"
        inst = make_instance(4, 5, 3)
        plan = exact.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
        assert plan.ok, plan.message
        worker = exact._worker  # type: ignore[attr-defined]
        assert worker is not None and worker.pid is not None and worker.pid != os.getpid()
    finally:
        exact.close()  # type: ignore[attr-defined]


# ------------------------------------------------- a solver that misbehaves
class _CrashPlanner:
    def plan(self, *args):
        os._exit(3)  # like glibc aborting on "double free"


class _HangPlanner:
    def plan(self, *args):
        time.sleep(60.0)


class _BetterPlanner:
    """Answers with a given (verified) plan: stands in for an exact solve that wins."""

    def __init__(self, plan: Plan):
        self.answer = plan

    def plan(self, *args):
        return self.answer


def _query():
    inst = make_instance(4, 5, 3)
    return inst.state, inst.hulls, inst.objective, inst.prev_control


@pytest.mark.timeout(60)
@pytest.mark.parametrize("planner, outcome", [(_CrashPlanner, "crashed"), (_HangPlanner, "killed")])
def test_worker_failure_leaves_the_best_verified_plan(planner, outcome):
    worker = Worker(lambda: planner().plan, context="fork")
    anytime = AnytimeSystem2(SPEC, SMALL, exact_budget_s=1.0, worker=worker)
    try:
        query = _query()
        fast = FastSystem2(SPEC, SMALL).plan(*query)
        plan = anytime.plan(*query)
        assert plan.ok and plan.info["source"] == "fast"
        assert str(plan.info["exact_outcome"]).startswith(outcome)
        assert plan.states == pytest.approx(fast.states)
        assert verify_p2_plan(plan.states, plan.controls, query[1], DYN, SPEC.clearance_m,
                              SPEC.d_safe_m, SPEC.area_size_m).ok
        assert not worker.alive()
        # the next request starts a fresh worker (and fails the same way)
        again = anytime.plan(*query)
        assert again.ok and worker.restarts == 2
    finally:
        anytime.close()


@pytest.mark.timeout(60)
def test_better_exact_plan_is_taken_and_a_bad_one_is_not():
    query = _query()
    fast = FastSystem2(SPEC, SMALL).plan(*query)
    assert fast.ok and fast.cost is not None
    # a "better" plan that fails verification (a position inside a hull) must be refused
    states = fast.states.copy()
    states[5, :2] = query[1][0].vertices.mean(axis=0)
    bogus = dataclasses.replace(fast, states=states, cost=0.0)
    anytime = AnytimeSystem2(SPEC, SMALL, exact_budget_s=5.0,
                             worker=Worker(lambda: _BetterPlanner(bogus).plan, context="fork"))
    try:
        plan = anytime.plan(*query)
        assert plan.info["source"] == "fast" and plan.cost == pytest.approx(fast.cost)
    finally:
        anytime.close()
    # a verified, cheaper plan is taken
    cheaper = dataclasses.replace(fast, cost=fast.cost * 0.5)
    anytime = AnytimeSystem2(SPEC, SMALL, exact_budget_s=5.0,
                             worker=Worker(lambda: _BetterPlanner(cheaper).plan, context="fork"))
    try:
        plan = anytime.plan(*query)
        assert plan.info["source"] == "exact" and plan.cost == pytest.approx(0.5 * fast.cost)
    finally:
        anytime.close()


# ------------------------------------------------------------------ bench
@pytest.mark.slow  # a process of its own (make test-fast leaves it out)
@pytest.mark.timeout(300)
def test_bench_system2_writes_the_issue_fields(tmp_path):
    result = run_system2(2, 3, tmp_path, reference_timeout=30.0, methods=["fast", "exact"],
                         horizon=10, log=lambda *_: None)
    data = json.loads((tmp_path / "system2.json").read_text())
    assert data["default"] == "fast"
    for method in ("fast", "exact"):
        assert set(data["summary"][method]) == {
            "time_s_median", "time_s_p95", "gap_median", "gap_p95", "verified_fraction"}
    row = data["instances"][0]
    assert {"time_s", "cost", "gap", "verified"} <= set(row["methods"]["fast"])
    assert result["summary"]["fast"]["verified_fraction"] == 1.0


def test_seeded_scip_proves_the_fast_plan_optimal_on_a_small_instance():
    from dualpilot.system2.scip import SeededExactSystem2

    inst = make_instance(4, 5, 3)
    fast = FastSystem2(SPEC, SMALL).plan(inst.state, inst.hulls, inst.objective,
                                              inst.prev_control)
    seeded = SeededExactSystem2(SPEC, SMALL).plan(inst.state, inst.hulls, inst.objective,
                                                       inst.prev_control, fast.controls)
    assert seeded.ok and seeded.info["optimal"]
    assert fast.cost is not None and seeded.cost is not None
    assert seeded.cost <= fast.cost * (1 + 1e-9)
    assert (fast.cost - seeded.cost) / seeded.cost < 1e-3
    dual = seeded.info["dual_bound"]
    assert isinstance(dual, float) and dual <= seeded.cost * (1 + 1e-6)
