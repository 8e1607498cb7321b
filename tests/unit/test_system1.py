"""System 1 (dualpilot.system1.planner): operator waypoints or RRT, LQR tracking, verification."""

from __future__ import annotations

import numpy as np
import pytest

import dualpilot.system1.planner as s1mod
from dualpilot.model.dynamics import DynamicsParams, hover_state, step
from dualpilot.model.geometry import Polytope, Rect, path_clearance
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system1.planner import System1, System1Params
from dualpilot.verify import Verdict, verify_trajectory

SPEC = MissionSpec()
GOAL = SPEC.goal
DYN = DynamicsParams()
BLOCK = Rect(650.0, 650.0, 200.0, 200.0).polytope()  # on the diagonal to G


def planner(seed: int = 0, **kw: object) -> System1:
    return System1(SPEC, System1Params(**kw), np.random.default_rng(seed))  # type: ignore[arg-type]


def iterations(plan: Plan) -> int:
    n = plan.info["rrt_iterations"]
    assert isinstance(n, int)
    return n


def assert_valid(plan: Plan, hulls: tuple[Polytope, ...], horizon: int = 80) -> None:
    assert plan.ok, plan.message
    assert plan.system == 1
    assert plan.states.shape == (horizon + 1, 4) and plan.controls.shape == (horizon, 2)
    assert verify_trajectory(plan.states, plan.controls, hulls, DYN, clearance_m=20.0).ok
    assert plan.path is not None and plan.compute_time_s > 0


def test_open_space_plan_reaches_the_goal_and_stops_there() -> None:
    x = hover_state(np.array([400.0, 400.0]))
    plan = planner().plan(x, ())
    assert_valid(plan, ())
    assert plan.path is not None
    np.testing.assert_array_equal(plan.path, [[400.0, 400.0], GOAL.center])
    np.testing.assert_array_equal(plan.states[0], x)
    assert GOAL.contains(plan.states[-1, :2])
    np.testing.assert_allclose(plan.states[-1], [900.0, 900.0, 0.0, 0.0], atol=1e-3)
    assert plan.info["source"] == "rrt" and plan.info["ref_speed_mps"] == 12.0


def test_rrt_plan_avoids_a_hull() -> None:
    hulls = (BLOCK,)
    plan = planner(seed=5).plan(hover_state(np.array([50.0, 50.0])), hulls)
    assert_valid(plan, hulls)
    assert plan.info["source"] == "rrt" and iterations(plan) > 0
    assert plan.path is not None
    assert path_clearance(plan.path, hulls) >= 25.0 - 1e-9
    assert GOAL.contains(plan.path[-1])


def test_same_seed_gives_the_same_plan() -> None:
    x = hover_state(np.array([50.0, 50.0]))
    a = planner(seed=9).plan(x, (BLOCK,))
    b = planner(seed=9).plan(x, (BLOCK,))
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.path, b.path)


def test_operator_waypoints_are_used_when_safe() -> None:
    s1 = planner()
    wps = np.array([[800.0, 500.0], [880.0, 880.0]])  # around BLOCK's lower right corner
    s1.set_waypoints(wps)
    x = hover_state(np.array([300.0, 300.0]))
    plan = s1.plan(x, (BLOCK,))
    assert_valid(plan, (BLOCK,))
    assert plan.info["source"] == "operator"
    np.testing.assert_array_equal(plan.path, np.vstack([x[:2], wps]))
    # as the UAV flies, passed waypoints drop out of the reference
    for _ in range(55):  # ~540 m to the first waypoint at up to 12 m/s
        x = step(x, plan.controls[0], DYN)
        plan = s1.plan(x, (BLOCK,))
    assert plan.ok and plan.info["source"] == "operator"
    assert plan.path is not None
    np.testing.assert_array_equal(plan.path[-1], wps[-1])
    assert len(plan.path) <= 3 and not np.any(np.all(plan.path == wps[0], axis=1))


def test_unsafe_operator_waypoints_are_replaced_by_the_rrt() -> None:
    s1 = planner(seed=2)
    s1.set_waypoints(np.array([[650.0, 650.0], [900.0, 900.0]]))  # straight through BLOCK
    plan = s1.plan(hover_state(np.array([300.0, 300.0])), (BLOCK,))
    assert_valid(plan, (BLOCK,))
    assert plan.info["source"] == "rrt" and "operator_rejected" in plan.info
    assert plan.path is not None and path_clearance(plan.path, (BLOCK,)) >= 25.0 - 1e-9


def test_a_waypoint_segment_that_clips_a_corner_is_rejected() -> None:
    # Every waypoint and every 10 m sample keeps 25 m from the tip, the segment does not.
    tip = np.array([500.0, 524.0])
    needle = Polytope.from_vertices(np.array([tip, tip + [-40.0, 300.0], tip + [40.0, 300.0]]))
    pts = np.linspace([300.0, 500.0], [700.0, 500.0], 41)
    assert min(needle.distance(p) for p in pts if abs(p[0] - 500.0) > 5) > 25.0
    s1 = planner(seed=1)
    s1.set_waypoints(np.array([[700.0, 500.0], [880.0, 880.0]]))
    plan = s1.plan(hover_state(np.array([300.0, 500.0])), (needle,))
    assert plan.ok and plan.info["source"] == "rrt" and "operator_rejected" in plan.info


def test_the_previous_rrt_path_is_reused_while_free() -> None:
    s1 = planner(seed=3)
    x = hover_state(np.array([50.0, 50.0]))
    first = s1.plan(x, (BLOCK,))
    assert first.ok and iterations(first) > 0
    x = step(x, first.controls[0], DYN)
    again = s1.plan(x, (BLOCK,))
    assert again.ok and again.info["reused"] is True and again.info["rrt_iterations"] == 0
    assert first.path is not None and again.path is not None
    np.testing.assert_array_equal(again.path[-1], first.path[-1])
    fresh = planner(seed=3, reuse_path=False)
    fresh.plan(hover_state(np.array([50.0, 50.0])), (BLOCK,))
    assert fresh.plan(x, (BLOCK,)).info["reused"] is False
    # a new hull across the stored path forces a fresh RRT
    mid = (first.path[1] + first.path[0]) / 2
    blocker = Rect(float(mid[0]), float(mid[1]), 60.0, 60.0).polytope()
    replanned = s1.plan(x, (BLOCK, blocker))
    assert replanned.ok and replanned.info["reused"] is False


def test_no_path_is_a_status_not_an_exception() -> None:
    covering = Rect(900.0, 900.0, 200.0, 200.0).polytope()
    plan = planner(max_iterations=200).plan(hover_state(np.array([50.0, 50.0])), (covering,))
    assert plan.status is PlanStatus.NO_PATH and not plan.ok
    assert plan.states.shape == (0, 4) and plan.controls.shape == (0, 2)
    assert plan.info["rrt_status"] == "unreachable" and plan.info["rrt_iterations"] == 0
    assert plan.compute_time_s > 0
    capped = planner(max_iterations=200, reach_check=False).plan(
        hover_state(np.array([50.0, 50.0])), (covering,))
    assert capped.status is PlanStatus.NO_PATH and capped.info["rrt_iterations"] == 200


def test_an_unverified_trajectory_is_never_ok(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(s1mod, "verify_trajectory",
                        lambda *a, **k: Verdict(False, "forced failure", 0.0))
    plan = planner().plan(hover_state(np.array([400.0, 400.0])), ())
    assert plan.status is PlanStatus.UNSAFE and plan.states.shape == (0, 4)
    attempts = plan.info["attempts"]
    assert isinstance(attempts, list) and len(attempts) == 3  # 12, 6 and 3 m/s
    assert "forced failure" in plan.message


def test_a_failed_verification_is_retried_slower(monkeypatch: pytest.MonkeyPatch) -> None:
    def fussy(states: np.ndarray, controls: np.ndarray, *a: object, **k: object) -> Verdict:
        fast = np.max(np.linalg.norm(states[:, 2:], axis=1)) > 7.0
        return Verdict(not fast, "too fast" if fast else "ok", 99.0)

    monkeypatch.setattr(s1mod, "verify_trajectory", fussy)
    plan = planner().plan(hover_state(np.array([400.0, 400.0])), ())
    assert plan.ok and plan.info["ref_speed_mps"] == 6.0


def test_escape_from_within_the_clearance() -> None:
    hull = Rect(400.0, 500.0, 100.0, 100.0).polytope()  # bottom face at y = 450
    x = hover_state(np.array([400.0, 428.0]))  # 22 m away: inside 25 m, outside d_safe
    plan = planner().plan(x, (hull,))
    assert_valid(plan, (hull,))


def test_bad_input_raises() -> None:
    s1 = planner()
    with pytest.raises(ValueError, match="finite"):
        s1.plan(np.array([np.nan, 50.0, 0.0, 0.0]), ())
    with pytest.raises(ValueError, match="shape"):
        s1.plan(np.array([50.0, 50.0]), ())
    with pytest.raises(ValueError, match="fire hull"):
        s1.plan(hover_state(np.array([650.0, 650.0])), (BLOCK,))
    with pytest.raises(ValueError, match="fire hull"):
        s1.plan(hover_state(np.array([650.0, 535.0])), (BLOCK,))  # 15 m from it
    with pytest.raises(ValueError, match="outside"):
        s1.plan(hover_state(np.array([1200.0, 50.0])), ())
    with pytest.raises(ValueError, match="goal .* outside"):
        System1(MissionSpec(goal=Rect(980.0, 900.0, 100.0, 100.0)))
    with pytest.raises(ValueError, match="shape"):
        s1.set_waypoints(np.empty((0, 2)))
    with pytest.raises(ValueError, match="finite"):
        s1.set_waypoints(np.array([[100.0, np.inf]]))
    with pytest.raises(ValueError, match="inside the"):
        s1.set_waypoints(np.array([[100.0, 100.0], [1500.0, 100.0]]))
    with pytest.raises(ValueError, match="horizon"):
        System1Params(horizon=0)
    s1.set_waypoints(np.array([[100.0, 100.0]]))
    s1.set_waypoints(None)
    assert s1.waypoints is None


def test_short_horizon_and_objective_are_accepted() -> None:
    plan = planner(horizon=1).plan(hover_state(np.array([400.0, 400.0])), (), Objective.ENERGY,
                                   np.zeros(2))
    assert_valid(plan, (), horizon=1)
